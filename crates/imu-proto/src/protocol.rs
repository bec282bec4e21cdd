//! Which serial protocol a device speaks: the one choice the simulator, the daemon's
//! configuration and its command line share.

use std::fmt;
use std::str::FromStr;

/// A device protocol this crate has a codec for.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum DeviceProtocol {
    /// The 3DM-GX1's single-byte commands and fixed-length replies ([`crate::command`],
    /// [`crate::reply`]).
    #[default]
    Gx1,
    /// MIP packets, as spoken by the 3DM-GX3/GX4/GX5, CV5/CV7 and GQ7 ([`crate::mip`]).
    Mip,
    /// Xsens Xbus messages, as spoken by the MTi-1/10/100/600 series ([`crate::xsens`]).
    Xsens,
    /// VectorNav's ASCII registers and binary outputs, as spoken by the VN-100/200/300
    /// ([`crate::vectornav`]).
    Vectornav,
}

impl DeviceProtocol {
    /// Every protocol, in the order they are listed to users.
    pub const ALL: [DeviceProtocol; 4] = [
        DeviceProtocol::Gx1,
        DeviceProtocol::Mip,
        DeviceProtocol::Xsens,
        DeviceProtocol::Vectornav,
    ];

    /// The name used in configuration files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            DeviceProtocol::Gx1 => "3dm-gx1",
            DeviceProtocol::Mip => "mip",
            DeviceProtocol::Xsens => "xsens",
            DeviceProtocol::Vectornav => "vectornav",
        }
    }
}

impl fmt::Display for DeviceProtocol {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The name is not one of [`DeviceProtocol::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown device protocol {0:?}: expected \"3dm-gx1\", \"mip\", \"xsens\" or \"vectornav\"")]
pub struct UnknownProtocol(pub String);

impl FromStr for DeviceProtocol {
    type Err = UnknownProtocol;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| UnknownProtocol(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_are_errors() {
        for p in DeviceProtocol::ALL {
            assert_eq!(p.name().parse(), Ok(p));
        }
        let err = "gx5".parse::<DeviceProtocol>().unwrap_err().to_string();
        assert!(err.contains("\"gx5\"") && err.contains("\"mip\""), "{err}");
    }
}
