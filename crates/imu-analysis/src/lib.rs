//! Offline analyses of IMU recordings, with IMU meaning, on top of `imu-stats` (numerics) and
//! `imu-model` (the error model). Layers, lowest first; a module imports only from layers below
//! it (or its own children):
//!
//! - [`input`]: imud recordings, rosbag2 MCAP (`sensor_msgs/msg/Imu`) and CSV -> [`ImuSeries`].
//! - [`segment`]: static intervals and rate plateaus, thresholds from the data.
//! - [`reference`]: the true input of each segment: a test plan, a reference log or the
//!   simulator's truth (leaves `segment_truth` and `direction` below `plan`, `log`, `truth`).
//! - [`health`]: the calibration held against gravity and Earth's rate in still windows: the
//!   daemon's live health checks, and the offline check of a recording.
//! - [`calibrate`]: fits of the error model to segments (and reference-free, to still poses and
//!   the moves between them); the calibration file imud loads.
//! - [`characterize`]: thermal, impact and dynamic tests.
//! - [`workbench`]: the model workbench: noise floor, verdicts, candidates, the ladder.
//! - [`render`]: SVG charts (a leaf the analyses draw with) and HTML report pages.
//! - [`provenance`]: input hashes for the files the tools write.
//!
//! No device I/O and no tokio here: these are pure computations over files.

pub mod calibrate;
pub mod characterize;
pub mod health;
pub mod input;
pub mod note;
pub mod provenance;
pub mod reference;
pub mod render;
pub mod segment;
pub mod workbench;

pub use input::{ImuSeries, InputError, Source};
