//! imud's files: MCAP topics, message schemas, the fixed-layout sample types, and the writers and
//! readers for them. No shared-memory transport: the offline tools depend on this crate alone, and
//! `imu-bus` places the same sample types in shared memory.
//!
//! Everything that crosses a process boundary (a shared-memory payload, an MCAP channel, a truth
//! file written by the simulator) is defined here and nowhere else, so that a producer and its
//! consumers cannot drift apart.
//!
//! - [`sample`]: the `#[repr(C)]` samples and health counters (the shared-memory payloads and the
//!   recording's records).
//! - [`recording`]: the daemon's MCAP recording (writer, reader, the ROS 2 topics it carries).
//! - [`truth`]: the simulator's ground-truth recording (`/truth/sample`, `/truth/segment`,
//!   metadata with the scenario and the truth error model), keyed by the device's timer ticks.
//! - [`mcap_read`]: a tolerant streaming MCAP reader that reads a truncated file (a process killed
//!   mid-write) up to its last good record and says where it stopped ([`mcap_read::Unfinished`]).
//! - [`recover`]: repairs such a file (summary, indexes, footer) so every reader opens it.
//! - [`ros1`]: ROS 1 serialization and bag files (2.0), read in the same tolerant way;
//!   [`ros2`]: CDR, the message types, rosbag2 directories and their sqlite3 storage.

pub mod mcap_read;
pub mod recording;
pub mod recover;
pub mod ros1;
pub mod ros2;
pub mod sample;
pub mod truth;

pub use mcap_read::{McapReadError, ReadReport, Unfinished};
pub use sample::{CalibrationHealth, CorrectedSample, DaemonStatus, RawSample};
