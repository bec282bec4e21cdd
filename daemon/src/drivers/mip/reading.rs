//! A MIP unit's IMU data packet as a device reading: the scaled fields are the device's own
//! SI reading (no counts, no GainScales), the sample clock is the timestamp field the session
//! configured, and a temperature field updates the temperature in force.

use imu_model::Measured;
use imu_model::nalgebra::Vector3;
use imu_proto::gnss_time::{GnssTime, gps_week_tow_to_unix_ns};
use imu_proto::mip::data::INTERNAL_TICK_HZ;
use imu_proto::mip::descriptor_set::IMU_DATA;
use imu_proto::mip::{ImuData, Packet};
use imu_proto::ticks::TickUnwrapper;
use tracing::{info, warn};

use crate::pipeline::{
    DeviceReading, FrameContent, TemperatureCadence, TickKind, TickLength, Timebase,
};

const G0: f64 = imu_model::units::STANDARD_GRAVITY_M_S2;

/// Which of a MIP unit's timestamps is the sample clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MipTimebase {
    /// Shared reference time (0xD5), ns since the device started: what new units send.
    ReferenceTime,
    /// Internal timestamp (0x80 0x0E), u32 counts at 62.5 kHz: older units (3DM-GX3).
    InternalTimestamp,
}

impl MipTimebase {
    /// The pipeline's timebase for this clock: fine (many ticks a sample), whole ns a tick.
    pub fn timebase(self) -> Timebase {
        Timebase {
            tick: TickLength::WholeNs(self.tick_ns()),
            kind: TickKind::Fine,
        }
    }

    /// One tick, ns.
    pub fn tick_ns(self) -> u64 {
        match self {
            MipTimebase::ReferenceTime => 1,
            // 16 us.
            MipTimebase::InternalTimestamp => (1e9 / INTERNAL_TICK_HZ) as u64,
        }
    }

    /// Counter width, bits.
    pub fn tick_bits(self) -> u32 {
        match self {
            MipTimebase::InternalTimestamp => 32,
            MipTimebase::ReferenceTime => 64,
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

/// Turns IMU data packets into frame contents on one clock.
#[derive(Debug)]
pub struct Readings {
    timebase: MipTimebase,
    unwrapper: TickUnwrapper,
    /// Data packets that made no sample so far (the first is said in the log).
    unusable: u64,
    /// Packets of data sets other than the IMU's (estimation filter, system, GNSS) so far, by
    /// descriptor set; each set's first is said in the log.
    other_sets: std::collections::BTreeMap<u8, u64>,
}

impl Readings {
    /// Readings on `timebase`'s clock.
    pub fn new(timebase: MipTimebase) -> Self {
        Self {
            timebase,
            unwrapper: TickUnwrapper::with_bits(timebase.tick_bits()),
            unusable: 0,
            other_sets: std::collections::BTreeMap::new(),
        }
    }

    /// A new session on `timebase`'s clock (the count of unusable packets runs on, so the
    /// first is said once in the daemon's life).
    pub fn restart(&mut self, timebase: MipTimebase) {
        self.timebase = timebase;
        self.unwrapper = TickUnwrapper::with_bits(timebase.tick_bits());
    }

    #[cold]
    fn unusable(&mut self, why: impl FnOnce() -> String) -> FrameContent {
        self.unusable += 1;
        if self.unusable == 1 {
            warn!("{} (counted, skipped)", why());
        }
        FrameContent {
            unusable: true,
            ..FrameContent::default()
        }
    }

    /// Counts a packet of another data set (the map grows by one entry per set seen, at most
    /// a handful: not on the per-frame path after the first of each).
    fn count_other_set(&mut self, set: u8) {
        let n = self.other_sets.entry(set).or_insert(0);
        *n += 1;
        if *n == 1 {
            info!(
                "MIP data set 0x{set:02X} ({}) is logged as frames, not decoded into samples",
                data_set_name(set)
            );
        }
    }

    /// Packets of data sets other than the IMU's, by descriptor set.
    pub fn other_sets(&self) -> &std::collections::BTreeMap<u8, u64> {
        &self.other_sets
    }

    /// What `packet` carries: nothing for a packet of another descriptor set (a reply), else
    /// its temperature and its sample, or an unusable packet. Inlined into the driver's
    /// `poll_event`, so the content is built where it goes, in the caller's slot, rather than
    /// on the stack and copied there.
    #[inline(always)]
    pub fn content(&mut self, packet: &Packet) -> FrameContent {
        let set = packet.descriptor_set();
        if set != IMU_DATA {
            if is_data_set(set) {
                self.count_other_set(set);
            }
            return FrameContent::default();
        }
        // Read where it was decoded (by reference): moving the decoded packet out of its
        // result copied it on every sample.
        let decoded = ImuData::decode_packet(packet);
        let data = match &decoded {
            Ok(data) => data,
            Err(e) => {
                return self.unusable(|| format!("an IMU data packet could not be decoded: {e}"));
            }
        };
        let temperature = data
            .temperature
            .map(|t| (f64::from(t.mean_c), TemperatureCadence::WithSamples));
        let ticks = match self.timebase {
            MipTimebase::ReferenceTime => data.reference_time_ns,
            MipTimebase::InternalTimestamp => data.internal_ticks.map(u64::from),
        };
        let (Some(ticks), Some(accel_g), Some(gyro)) = (ticks, data.accel_g, data.gyro_rad_s)
        else {
            // A packet without the configured clock, accel or gyro is not a sample.
            return FrameContent {
                temperature,
                fields_skipped: u32::from(data.skipped_fields),
                ..self.unusable(|| {
                    "an IMU data packet lacks the configured timestamp, accel or gyro field"
                        .to_string()
                })
            };
        };
        let vector = |v: [f32; 3], unit: f64| Vector3::from_fn(|i, _| f64::from(v[i]) * unit);
        FrameContent {
            reading: Some(DeviceReading {
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
                compensated: None,
                gnss: data.gps_time.and_then(|g| {
                    // Valid when the unit says both its time of week and its week are.
                    const TOW_AND_WEEK_VALID: u16 = 8 | 16;
                    gps_week_tow_to_unix_ns(u32::from(g.week), g.tow_s).map(|utc_ns| GnssTime {
                        utc_ns,
                        valid: g.valid_flags & TOW_AND_WEEK_VALID == TOW_AND_WEEK_VALID,
                    })
                }),
            }),
            temperature,
            unusable: false,
            fields_skipped: u32::from(data.skipped_fields),
        }
    }
}

/// True for a data descriptor set (0x80 and up; commands are below).
fn is_data_set(set: u8) -> bool {
    set >= 0x80
}

/// A data set's name (mip_sdk `mip_descriptors.h`, `data_filter.h`, `data_system.h`,
/// `data_gnss.h`).
pub fn data_set_name(set: u8) -> &'static str {
    match set {
        0x80 => "IMU",
        0x81 => "GNSS",
        0x82 => "estimation filter",
        0x91..=0x95 => "GNSS receiver",
        0xA0 => "system",
        _ => "unknown",
    }
}
