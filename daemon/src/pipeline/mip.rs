//! A MIP unit's IMU data packet as a device reading: the scaled fields are the device's own
//! SI reading (no counts, no GainScales), the sample clock is the timestamp field the session
//! configured, and a temperature field updates the temperature in force.

use imu_bus::recording::LogRecord;
use imu_model::Measured;
use imu_model::nalgebra::Vector3;
use imu_proto::mip::data::INTERNAL_TICK_HZ;
use imu_proto::mip::descriptor_set::IMU_DATA;
use imu_proto::mip::{ImuData, MipEvent, Packet};
use tracing::warn;

use super::{DeviceReading, Pipeline, Sinks, Timebase, log_rejected};

const G0: f64 = imu_model::units::STANDARD_GRAVITY_M_S2;
/// Host time between two recorded temperatures of a MIP stream, ns.
const TEMPERATURE_LOG_INTERVAL_NS: u64 = 1_000_000_000;

/// Which of a MIP unit's timestamps is the sample clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MipTimebase {
    /// Shared reference time (0xD5), ns since the device started: what new units send.
    ReferenceTime,
    /// Internal timestamp (0x80 0x0E), u32 counts at 62.5 kHz: older units (3DM-GX3).
    InternalTimestamp,
}

impl MipTimebase {
    /// The pipeline's timebase for this clock.
    pub fn timebase(self) -> Timebase {
        Timebase::Mip(self)
    }

    /// One tick, ns.
    pub fn tick_ns(self) -> u64 {
        match self {
            MipTimebase::ReferenceTime => 1,
            // 16 us.
            MipTimebase::InternalTimestamp => (1e9 / INTERNAL_TICK_HZ) as u64,
        }
    }

    /// The field descriptor carrying it.
    pub fn field(self) -> u8 {
        match self {
            MipTimebase::ReferenceTime => imu_proto::mip::data::field::REFERENCE_TIME,
            MipTimebase::InternalTimestamp => imu_proto::mip::data::field::INTERNAL_TIMESTAMP,
        }
    }

    /// Its name in logs and metadata.
    pub fn name(self) -> &'static str {
        match self {
            MipTimebase::ReferenceTime => "reference time (0xD5, ns)",
            MipTimebase::InternalTimestamp => "internal timestamp (0x80 0x0E, 62.5 kHz)",
        }
    }
}

impl Pipeline {
    /// Handles one MIP decoder event received at the given host times: every packet is logged
    /// as a frame; an IMU data packet becomes a sample, other packets (replies) are only logged.
    pub fn on_mip_event(
        &mut self,
        ev: MipEvent,
        t_mono_ns: u64,
        t_wall_ns: u64,
        sinks: &mut Sinks,
    ) {
        match ev {
            MipEvent::Packet { packet, offset } => {
                self.hold_frame(packet.as_bytes(), offset);
                if packet.descriptor_set() == IMU_DATA {
                    self.on_mip_data_packet(&packet, t_mono_ns, t_wall_ns, sinks);
                }
                // A packet that made no sample is logged on its own.
                self.flush_frame(t_mono_ns, t_wall_ns, sinks);
            }
            MipEvent::Rejected {
                bytes,
                offset,
                reason,
            } => log_rejected(bytes, offset, reason, t_mono_ns, t_wall_ns, sinks),
        }
    }

    /// An IMU data packet: decoded into a sample, or counted as unusable.
    fn on_mip_data_packet(
        &mut self,
        packet: &Packet,
        t_mono_ns: u64,
        t_wall_ns: u64,
        sinks: &mut Sinks,
    ) {
        match ImuData::decode_packet(packet) {
            Ok(data) => self.on_mip_data(&data, t_mono_ns, t_wall_ns, sinks),
            Err(e) => {
                self.counters.undecodable += 1;
                if self.counters.undecodable == 1 {
                    warn!("an IMU data packet could not be decoded: {e} (counted, skipped)");
                }
            }
        }
    }

    /// Logs one MIP event without making a sample of it (the start-up's bytes, before the
    /// session's clock is set): a packet as a frame, handed back; rejected bytes as such.
    pub fn log_mip_event(
        &mut self,
        ev: MipEvent,
        t_mono_ns: u64,
        t_wall_ns: u64,
        sinks: &Sinks,
    ) -> Option<Packet> {
        match ev {
            MipEvent::Packet { packet, offset } => {
                self.log_frame(packet.as_bytes(), offset, t_mono_ns, t_wall_ns, sinks);
                Some(packet)
            }
            MipEvent::Rejected {
                bytes,
                offset,
                reason,
            } => {
                log_rejected(bytes, offset, reason, t_mono_ns, t_wall_ns, sinks);
                None
            }
        }
    }

    /// One IMU data packet: its temperature kept, its sample through the shared steps.
    pub fn on_mip_data(
        &mut self,
        data: &ImuData,
        t_mono_ns: u64,
        t_wall_ns: u64,
        sinks: &mut Sinks,
    ) {
        self.counters.fields_skipped += u64::from(data.skipped_fields);
        if let Some(t) = data.temperature {
            self.temp_c = f64::from(t.mean_c);
            // The field comes with every sample: recorded once a second, as the GX1's polls.
            if self
                .temp_logged_ns
                .is_none_or(|last| t_mono_ns >= last + TEMPERATURE_LOG_INTERVAL_NS)
            {
                self.temp_logged_ns = Some(t_mono_ns);
                self.counters.temperatures += 1;
                // The packet's frame goes into the log before the temperature taken from it.
                self.flush_frame(t_mono_ns, t_wall_ns, sinks);
                sinks.log(LogRecord::Temperature {
                    t_wall_ns,
                    temp_c: self.temp_c,
                });
            }
        }
        let ticks = match self.timebase {
            Timebase::Mip(MipTimebase::ReferenceTime) => data.reference_time_ns,
            Timebase::Mip(MipTimebase::InternalTimestamp) => data.internal_ticks.map(u64::from),
            // A MIP packet on a session set up for another device's clock is not a sample.
            Timebase::Gx1 { .. } => None,
        };
        let (Some(ticks), Some(accel_g), Some(gyro)) = (ticks, data.accel_g, data.gyro_rad_s)
        else {
            // A packet without the configured clock, accel or gyro is not a sample.
            self.counters.undecodable += 1;
            if self.counters.undecodable == 1 {
                warn!(
                    "an IMU data packet lacks the configured timestamp, accel or gyro field \
                     (counted, skipped)"
                );
            }
            return;
        };
        let vector = |v: [f32; 3], unit: f64| Vector3::from_fn(|i, _| f64::from(v[i]) * unit);
        let reading = DeviceReading {
            ticks_unwrapped: self.unwrapper.unwrap_wide(ticks),
            ticks: ticks as u16,
            counts: None,
            measured: Measured {
                accel_m_s2: vector(accel_g, G0),
                gyro_rad_s: vector(gyro, 1.0),
                // A unit without a magnetometer: NaN, never a zero field.
                mag_gauss: data
                    .mag_gauss
                    .map_or(Vector3::repeat(f64::NAN), |m| vector(m, 1.0)),
            },
            saturated: false,
            command: IMU_DATA,
        };
        self.on_reading(&reading, t_mono_ns, t_wall_ns, sinks);
    }
}
