//! An Xsens MTData2 message as a device reading: the HR outputs (factory calibration only)
//! are the reading imud calibrates, the compensated outputs go beside it, `SampleTimeFine` is
//! the sample clock, `UtcTime` the GNSS time, the status word's clipping bits the sample's
//! saturation, and a temperature item updates the temperature in force.

use imu_model::Measured;
use imu_model::nalgebra::Vector3;
use imu_proto::gnss_time::GnssTime;
use imu_proto::ticks::TickUnwrapper;
use imu_proto::xsens::data::status as xsens_status;
use imu_proto::xsens::{Message, MtData2, SAMPLE_TIME_FINE_HZ, mid};
use tracing::{info, warn};

use crate::pipeline::{
    DeviceReading, FrameContent, TemperatureCadence, TickKind, TickLength, Timebase,
};

/// The sample clock: `SampleTimeFine`, 10 kHz counts in a u32.
pub fn timebase() -> Timebase {
    Timebase {
        tick: TickLength::WholeNs(1_000_000_000 / u64::from(SAMPLE_TIME_FINE_HZ)),
        kind: TickKind::Fine,
    }
}

/// The clock's name in logs and metadata.
pub const CLOCK_NAME: &str = "SampleTimeFine (0x1060, 10 kHz)";

/// Which outputs are the raw reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RawSource {
    /// `AccelerationHR`/`RateOfTurnHR`: factory calibration only (preferred).
    HighRate,
    /// `Acceleration`/`RateOfTurn`: the unit's compensated outputs, for a unit that gives no
    /// HR outputs (then nothing is recorded as compensated beside them).
    Compensated,
}

impl RawSource {
    /// The source `data` offers, HR first.
    pub fn of(data: &MtData2) -> Option<Self> {
        if data.acceleration_hr_m_s2.is_some() && data.rate_of_turn_hr_rad_s.is_some() {
            Some(RawSource::HighRate)
        } else if data.acceleration_m_s2.is_some() && data.rate_of_turn_rad_s.is_some() {
            Some(RawSource::Compensated)
        } else {
            None
        }
    }

    /// Its name in logs and metadata.
    pub fn name(self) -> &'static str {
        match self {
            RawSource::HighRate => "AccelerationHR/RateOfTurnHR (0x4040/0x8040)",
            RawSource::Compensated => "Acceleration/RateOfTurn (0x4020/0x8020, compensated)",
        }
    }
}

/// Turns MTData2 messages into frame contents on the `SampleTimeFine` clock.
#[derive(Debug)]
pub struct Readings {
    unwrapper: TickUnwrapper,
    /// Data messages that made no sample so far (the first is said in the log).
    unusable: u64,
    /// Messages of other ids while streaming (replies, legacy MTData), the first said.
    other: u64,
}

impl Default for Readings {
    fn default() -> Self {
        Self::new()
    }
}

impl Readings {
    /// Readings of a new session.
    pub fn new() -> Self {
        Self {
            unwrapper: TickUnwrapper::with_bits(32),
            unusable: 0,
            other: 0,
        }
    }

    /// A new session (the count of unusable messages runs on, so the first is said once in
    /// the daemon's life).
    pub fn restart(&mut self) {
        self.unwrapper = TickUnwrapper::with_bits(32);
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

    #[cold]
    fn other(&mut self, mid: u8) -> FrameContent {
        self.other += 1;
        if self.other == 1 {
            info!("Xsens message 0x{mid:02X} while streaming is logged as a frame, not a sample");
        }
        FrameContent::default()
    }

    /// What `msg` carries: nothing for a message other than MTData2, else its temperature
    /// and its sample, or an unusable message.
    #[inline(always)]
    pub fn content(&mut self, msg: &Message) -> FrameContent {
        if msg.mid() != mid::MT_DATA2 {
            return self.other(msg.mid());
        }
        let decoded = MtData2::decode(msg);
        let data = match &decoded {
            Ok(data) => data,
            Err(e) => {
                return self.unusable(|| format!("an MTData2 message could not be decoded: {e}"));
            }
        };
        let temperature = data
            .temperature_c
            .map(|t| (t, TemperatureCadence::WithSamples));
        let fields_skipped = u32::from(data.unknown_items) + u32::from(data.bad_items);
        let (Some(ticks), Some(source)) = (data.sample_time_fine, RawSource::of(data)) else {
            return FrameContent {
                temperature,
                fields_skipped,
                ..self.unusable(|| {
                    "an MTData2 message lacks SampleTimeFine or an acceleration and rate of turn"
                        .to_string()
                })
            };
        };
        let v = |a: [f64; 3]| Vector3::from(a);
        // A unit without a magnetometer: NaN, never a zero field. The field is a ratio to the
        // field where the unit was calibrated, carried as it is in the gauss slot (the
        // identity's `magnetometer-unit` says so in the recording).
        let mag = data
            .magnetic_field_normalised
            .map_or(Vector3::repeat(f64::NAN), v);
        let (measured, compensated) = match source {
            RawSource::HighRate => (
                Measured {
                    accel_m_s2: data.acceleration_hr_m_s2.map_or_else(Vector3::zeros, v),
                    gyro_rad_s: data.rate_of_turn_hr_rad_s.map_or_else(Vector3::zeros, v),
                    mag_gauss: mag,
                },
                match (data.acceleration_m_s2, data.rate_of_turn_rad_s) {
                    (Some(a), Some(w)) => Some(Measured {
                        accel_m_s2: v(a),
                        gyro_rad_s: v(w),
                        mag_gauss: mag,
                    }),
                    _ => None,
                },
            ),
            RawSource::Compensated => (
                Measured {
                    accel_m_s2: data.acceleration_m_s2.map_or_else(Vector3::zeros, v),
                    gyro_rad_s: data.rate_of_turn_rad_s.map_or_else(Vector3::zeros, v),
                    mag_gauss: mag,
                },
                None,
            ),
        };
        FrameContent {
            reading: Some(DeviceReading {
                ticks_unwrapped: self.unwrapper.unwrap_wide(u64::from(ticks)),
                ticks: ticks as u16,
                counts: None,
                measured,
                // The unit says which axes clipped (the GX1's counts at a rail say the same);
                // a unit not sending its status word is taken as not clipping.
                saturated: data
                    .status_word
                    .is_some_and(|w| w & xsens_status::CLIPPING != 0),
                command: mid::MT_DATA2,
                compensated,
                gnss: data.utc.and_then(|u| {
                    u.unix_ns().map(|utc_ns| GnssTime {
                        utc_ns,
                        valid: u.valid(),
                    })
                }),
            }),
            temperature,
            unusable: false,
            fields_skipped,
        }
    }
}
