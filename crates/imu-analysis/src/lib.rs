//! Offline analyses of IMU recordings, shared by the client binaries: reading inputs (imud
//! recordings, rosbag2 MCAP with `sensor_msgs/msg/Imu`, CSV) into SI time series.
//!
//! No device I/O and no tokio here: these are pure computations over files.

pub mod input;

pub use input::{ImuSeries, InputError, Source};
