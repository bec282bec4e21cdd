//! ROS 2 messages for the MCAP log and the daemon's DDS output: a CDR (XCDR1, little-endian) encoder and decoder, the message
//! types imud records, and their `ros2msg` schema text exactly as rosbag2 writes it; `bag`: the
//! files of a rosbag2 directory; `sqlite`: its sqlite3 storage (`.db3`).
//!
//! The standard types (`sensor_msgs/msg/Imu`, `Temperature`, `MagneticField` and their
//! `std_msgs`, `builtin_interfaces` and `geometry_msgs` parts) match the upstream `.msg` files
//! field for field, so the recordings open in Foxglove, PlotJuggler, `ros2 bag`, Python
//! `mcap-ros2-support` and `rosbags`. The `imud_msgs` types mirror imu-rec's own sample types.
//!
//! Wire format: a 4-byte encapsulation header `00 01 00 00` (CDR, little-endian), then the fields
//! in declaration order, each primitive aligned to its own size (8 for `float64`/`uint64`)
//! relative to the first byte after the header; strings are a `uint32` length that counts a
//! trailing NUL, the bytes and the NUL; sequences are a `uint32` count and the elements; fixed
//! arrays are the elements alone.

use crate::sample::{CalibrationHealth, DaemonStatus, RawSample, raw_flags};

pub mod bag;
mod cdr;
mod definitions;
mod diagnostics;
mod messages;
pub mod sqlite;

pub use cdr::*;
pub use definitions::*;
pub use diagnostics::*;
pub use messages::*;

/// Encapsulation header of little-endian plain CDR (`CDR_LE`), the first four bytes of every
/// message.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// The line rosbag2 puts before each dependent definition in `ros2msg` schema text (80 `=`).
pub const DEFINITION_SEPARATOR: &str =
    "================================================================================";

#[cfg(test)]
mod tests;
