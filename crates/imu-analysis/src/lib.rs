//! Offline analyses of IMU recordings, shared by the client binaries: reading inputs (imud
//! recordings, rosbag2 MCAP with `sensor_msgs/msg/Imu`, CSV) into SI time series; Allan-family
//! deviations and IEEE noise terms; small SVG charts.
//!
//! No device I/O and no tokio here: these are pure computations over files.

pub mod allan;
pub mod diagnose;
pub mod dynamic;
pub mod fit;
pub mod impact;
pub mod input;
pub mod lsq;
pub mod noise;
pub mod plan;
pub mod plot;
pub mod provenance;
pub mod reference;
pub mod reference_free;
pub mod reference_log;
pub mod report;
pub mod segment;
pub mod stats;
pub mod thermal;

pub use input::{ImuSeries, InputError, Source};
