//! The units a person reads characterisation results in: accelerometers in mg, gyros in deg/h,
//! the same in the tables, the text summaries and the charts (the JSON stays in SI).

use crate::render::number::number;

const G0: f64 = imu_model::units::STANDARD_GRAVITY_M_S2;

/// The display unit of a sensor's output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DisplayUnit {
    /// Milli-g, for specific force given in m/s^2.
    Mg,
    /// Degrees per hour, for angular rate given in rad/s.
    DegPerHour,
}

impl DisplayUnit {
    /// The unit of `sensor` (`accel` -> mg, anything else -> deg/h).
    pub fn of_sensor(sensor: &str) -> Self {
        if sensor == "accel" {
            Self::Mg
        } else {
            Self::DegPerHour
        }
    }

    /// Display units per SI unit (m/s^2 or rad/s).
    pub fn per_si(self) -> f64 {
        match self {
            Self::Mg => 1e3 / G0,
            Self::DegPerHour => 3600.0_f64.to_degrees(),
        }
    }

    /// The unit's label, `mg` or `deg/h`.
    pub fn label(self) -> &'static str {
        match self {
            Self::Mg => "mg",
            Self::DegPerHour => "deg/h",
        }
    }

    /// An SI value converted and formatted (the one number format).
    pub fn format(self, si: f64) -> String {
        number(si * self.per_si())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions() {
        assert!((DisplayUnit::Mg.per_si() * G0 - 1e3).abs() < 1e-9);
        // 1 deg/s = 3600 deg/h.
        let one_deg_s = 1f64.to_radians();
        assert!((DisplayUnit::DegPerHour.per_si() * one_deg_s - 3600.0).abs() < 1e-9);
        assert_eq!(DisplayUnit::of_sensor("gyro").label(), "deg/h");
        assert_eq!(DisplayUnit::Mg.format(G0 * 2e-3), "2.0000");
    }
}
