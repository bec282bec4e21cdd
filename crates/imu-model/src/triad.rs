//! The three sensor triads of an IMU and their physical units.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// One of the three sensor triads; each has its own error model and unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Triad {
    /// Accelerometers: specific force in m/s^2.
    Accel,
    /// Gyroscopes: angular rate in rad/s.
    Gyro,
    /// Magnetometers: magnetic flux density in gauss.
    Mag,
}

impl Triad {
    /// All triads, in file order.
    pub const ALL: [Triad; 3] = [Triad::Accel, Triad::Gyro, Triad::Mag];

    /// The unit of this triad's input and output ("U" in the effect docs).
    pub fn unit(&self) -> &'static str {
        match self {
            Triad::Accel => "m/s^2",
            Triad::Gyro => "rad/s",
            Triad::Mag => "gauss",
        }
    }

    /// The name used in files and on the command line: "accel", "gyro" or "mag".
    pub fn name(&self) -> &'static str {
        match self {
            Triad::Accel => "accel",
            Triad::Gyro => "gyro",
            Triad::Mag => "mag",
        }
    }

    /// Half-width of the input range over which the error model must be invertible
    /// (checked by validation, e.g. scale-nonlinearity monotonicity): accel +/-20 g,
    /// gyro +/-35 rad/s (~2000 deg/s), mag +/-8 gauss. These cover every MEMS part
    /// imud is meant for with margin (the 3DM-GX1 is +/-5 g, +/-300 deg/s, +/-1.2 gauss).
    pub fn validation_range(&self) -> f64 {
        match self {
            Triad::Accel => 20.0 * crate::units::STANDARD_GRAVITY_M_S2,
            Triad::Gyro => 35.0,
            Triad::Mag => 8.0,
        }
    }
}

impl fmt::Display for Triad {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Triad {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Triad::ALL
            .into_iter()
            .find(|t| t.name() == s)
            .ok_or_else(|| format!("unknown triad `{s}`; valid triads: accel, gyro, mag"))
    }
}
