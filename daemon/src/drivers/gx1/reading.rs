//! The 3DM-GX1's data replies as device readings: the counts of a reply, with saturation and
//! the scaling to SI with the GainScales in force (read at start-up, or the configured
//! fallbacks).

use imu_model::Measured;
use imu_model::nalgebra::Vector3;
use imu_proto::reply::Reply;
use imu_proto::scale;

use crate::pipeline::{Counts, DeviceReading, Gains};

const G0: f64 = imu_model::units::STANDARD_GRAVITY_M_S2;

/// The counts of a data reply; `None` for other replies.
pub fn counts_of(reply: &Reply) -> Option<Counts> {
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
    Some(Counts {
        accel,
        gyro: rate,
        mag,
        scaled,
    })
}

/// True if any channel sits at the end of its range.
pub fn saturated(c: &Counts) -> bool {
    let at_limit = |v: i32| {
        if c.scaled {
            v == i32::from(i16::MAX) || v == i32::from(i16::MIN)
        } else {
            v == 0 || v == i32::from(u16::MAX)
        }
    };
    [c.accel, c.gyro, c.mag]
        .iter()
        .flatten()
        .any(|&v| at_limit(v))
}

/// Physical units with the GainScales in force.
#[inline]
pub fn to_units(c: &Counts, g: Gains) -> Measured {
    let unit = |v: i32, gain: u16| {
        if c.scaled {
            scale::scaled_to_units(v as i16, gain)
        } else {
            scale::raw_bits_to_units(v as u16, gain)
        }
    };
    Measured {
        accel_m_s2: Vector3::from_fn(|i, _| unit(c.accel[i], g.accel) * G0),
        gyro_rad_s: Vector3::from_fn(|i, _| unit(c.gyro[i], g.gyro)),
        mag_gauss: Vector3::from_fn(|i, _| unit(c.mag[i], g.mag)),
    }
}

/// The reading of a data reply whose 16-bit timer unwrapped to `ticks_unwrapped`.
#[inline]
pub fn reading(reply: &Reply, counts: Counts, ticks_unwrapped: u64, gains: Gains) -> DeviceReading {
    DeviceReading {
        ticks_unwrapped,
        ticks: reply.ticks().unwrap_or(0),
        counts: Some(counts),
        measured: to_units(&counts, gains),
        saturated: saturated(&counts),
        command: reply.code(),
        compensated: None,
        gnss: None,
    }
}
