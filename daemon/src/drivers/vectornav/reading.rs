//! A VectorNav binary message as a device reading: the uncompensated accel, gyro and mag are
//! the raw reading imud's calibration corrects, the unit's compensated ones are recorded
//! beside it, the startup time (ns on the unit's oscillator) is the sample clock, GPS time
//! with its time status is the GNSS time, and the temperature updates the one in force.

use imu_model::Measured;
use imu_model::nalgebra::Vector3;
use imu_proto::gnss_time::{GnssTime, gps_ns_to_unix_ns};
use imu_proto::ticks::TickUnwrapper;
use imu_proto::vectornav::{BinaryMessage, SYNC};
use tracing::warn;

use crate::pipeline::{
    DeviceReading, FrameContent, TemperatureCadence, TickKind, TickLength, Timebase,
};

/// The startup time as the pipeline's timebase: fine (many ticks a sample), 1 ns a tick.
pub fn timebase() -> Timebase {
    Timebase {
        tick: TickLength::WholeNs(1),
        kind: TickKind::Fine,
    }
}

/// Turns binary messages into frame contents.
#[derive(Debug)]
pub struct Readings {
    unwrapper: TickUnwrapper,
    /// Messages that made no sample so far (the first is said in the log).
    unusable: u64,
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
            unwrapper: TickUnwrapper::with_bits(64),
            unusable: 0,
        }
    }

    /// A new session (the count of unusable messages runs on).
    pub fn restart(&mut self) {
        self.unwrapper = TickUnwrapper::with_bits(64);
    }

    /// Messages that made no sample so far.
    pub fn unusable_count(&self) -> u64 {
        self.unusable
    }

    #[cold]
    fn unusable(&mut self) -> FrameContent {
        self.unusable += 1;
        if self.unusable == 1 {
            warn!(
                "a VectorNav binary message lacks the startup time, uncompensated accel or \
                 uncompensated gyro (counted, skipped)"
            );
        }
        FrameContent {
            unusable: true,
            ..FrameContent::default()
        }
    }

    /// What `message` carries: its temperature and its sample, or an unusable message.
    #[inline(always)]
    pub fn content(&mut self, message: &BinaryMessage) -> FrameContent {
        let d = message.data();
        let temperature = d
            .temp_c
            .map(|t| (f64::from(t), TemperatureCadence::WithSamples));
        let (Some(ticks), Some(accel), Some(gyro)) =
            (d.startup_ns, d.uncomp_accel_m_s2, d.uncomp_gyro_rad_s)
        else {
            return FrameContent {
                temperature,
                ..self.unusable()
            };
        };
        let vector = |v: [f32; 3]| Vector3::from_fn(|i, _| f64::from(v[i]));
        // A unit sending no magnetometer field: NaN, never a zero field.
        let mag = |m: Option<[f32; 3]>| m.map_or(Vector3::repeat(f64::NAN), vector);
        let compensated = match (d.accel_m_s2, d.angular_rate_rad_s) {
            (Some(a), Some(w)) => Some(Measured {
                accel_m_s2: vector(a),
                gyro_rad_s: vector(w),
                mag_gauss: mag(d.mag_gauss),
            }),
            _ => None,
        };
        FrameContent {
            reading: Some(DeviceReading {
                ticks_unwrapped: self.unwrapper.unwrap_wide(ticks),
                ticks: ticks as u16,
                counts: None,
                measured: Measured {
                    accel_m_s2: vector(accel),
                    gyro_rad_s: vector(gyro),
                    mag_gauss: mag(d.uncomp_mag_gauss),
                },
                saturated: false,
                command: SYNC,
                compensated,
                gnss: d.gps_ns.map(|gps_ns| GnssTime {
                    utc_ns: gps_ns_to_unix_ns(gps_ns),
                    // Valid when the unit says its time of week and its week are; a message
                    // without the time status carries GPS time no one vouched for.
                    valid: d.time_status.is_some_and(|s| s.gps_valid()),
                }),
            }),
            temperature,
            unusable: false,
            fields_skipped: 0,
        }
    }
}
