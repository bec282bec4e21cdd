//! The 3DM-GX1's data replies as device readings: its GainScales (read at start-up, or the
//! configured fallbacks) and the counts of a reply, with saturation and the scaling to SI.

use imu_model::Measured;
use imu_model::nalgebra::Vector3;
use imu_proto::reply::Reply;
use imu_proto::scale;

const G0: f64 = imu_model::units::STANDARD_GRAVITY_M_S2;

/// Which GainScales are the configured fallbacks (the device's read failed).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GainFallback {
    /// The accelerometer GainScale is the fallback.
    pub accel: bool,
    /// The gyro GainScale is the fallback.
    pub gyro: bool,
    /// The magnetometer GainScale is the fallback.
    pub mag: bool,
}

impl GainFallback {
    /// All three are fallbacks (before the device answered).
    pub const ALL: Self = Self {
        accel: true,
        gyro: true,
        mag: true,
    };
    /// None is: all three were read from the device.
    pub const NONE: Self = Self {
        accel: false,
        gyro: false,
        mag: false,
    };

    /// True if any GainScale is a fallback.
    pub fn any(self) -> bool {
        self.accel || self.gyro || self.mag
    }

    /// Bit mask for the status: 1 accel, 2 gyro, 4 mag.
    pub fn mask(self) -> u8 {
        u8::from(self.accel) | u8::from(self.gyro) << 1 | u8::from(self.mag) << 2
    }
}

/// The device's GainScales and which of them are fallbacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Gains {
    /// Accelerometer GainScale.
    pub accel: u16,
    /// Gyro GainScale.
    pub gyro: u16,
    /// Magnetometer GainScale.
    pub mag: u16,
    /// Which of them are the configured fallbacks.
    pub fallback: GainFallback,
}

impl Gains {
    /// A device without GainScales (MIP: it sends SI values): all zero, none a fallback.
    pub const NOT_APPLICABLE: Self = Self {
        accel: 0,
        gyro: 0,
        mag: 0,
        fallback: GainFallback::NONE,
    };

    /// The recording metadata that states the gains in force and where each came from.
    pub fn metadata(&self) -> [(String, String); 7] {
        let source = |fallback: bool| if fallback { "fallback" } else { "device" };
        [
            ("gain-scale-accel".into(), self.accel.to_string()),
            ("gain-scale-gyro".into(), self.gyro.to_string()),
            ("gain-scale-mag".into(), self.mag.to_string()),
            (
                "gain-scale-accel-source".into(),
                source(self.fallback.accel).into(),
            ),
            (
                "gain-scale-gyro-source".into(),
                source(self.fallback.gyro).into(),
            ),
            (
                "gain-scale-mag-source".into(),
                source(self.fallback.mag).into(),
            ),
            ("gains-are-fallback".into(), self.fallback.any().to_string()),
        ]
    }
}

/// The counts of one data reply, widened to i32 (raw bits are unsigned, scaled ones signed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Counts {
    /// Accelerometer counts.
    pub accel: [i32; 3],
    /// Gyro counts.
    pub gyro: [i32; 3],
    /// Magnetometer counts.
    pub mag: [i32; 3],
    /// Signed scaled counts (0x02/0x03/0x0C) rather than raw ADC bits (0x01).
    pub scaled: bool,
}

impl Counts {
    /// The counts of a data reply; `None` for other replies.
    pub fn of(reply: &Reply) -> Option<Self> {
        let (mag, accel, rate, scaled) = match *reply {
            Reply::RawSensorBits {
                mag, accel, rate, ..
            } => (
                mag.map(i32::from),
                accel.map(i32::from),
                rate.map(i32::from),
                false,
            ),
            Reply::Vectors {
                mag, accel, rate, ..
            }
            | Reply::QuaternionVectors {
                mag, accel, rate, ..
            } => (
                mag.map(i32::from),
                accel.map(i32::from),
                rate.map(i32::from),
                true,
            ),
            _ => return None,
        };
        Some(Self {
            accel,
            gyro: rate,
            mag,
            scaled,
        })
    }

    /// True if any channel sits at the end of its range.
    pub fn saturated(&self) -> bool {
        let at_limit = |v: i32| {
            if self.scaled {
                v == i32::from(i16::MAX) || v == i32::from(i16::MIN)
            } else {
                v == 0 || v == i32::from(u16::MAX)
            }
        };
        [self.accel, self.gyro, self.mag]
            .iter()
            .flatten()
            .any(|&v| at_limit(v))
    }

    /// Physical units with the GainScales in force.
    pub fn to_units(self, g: Gains) -> Measured {
        let unit = |c: i32, gain: u16| {
            if self.scaled {
                scale::scaled_to_units(c as i16, gain)
            } else {
                scale::raw_bits_to_units(c as u16, gain)
            }
        };
        Measured {
            accel_m_s2: Vector3::from_fn(|i, _| unit(self.accel[i], g.accel) * G0),
            gyro_rad_s: Vector3::from_fn(|i, _| unit(self.gyro[i], g.gyro)),
            mag_gauss: Vector3::from_fn(|i, _| unit(self.mag[i], g.mag)),
        }
    }
}
