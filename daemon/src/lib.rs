//! The imud daemon as a library: configuration, the device drivers, the device session, the
//! per-frame pipeline (with the loss accounting), the device-clock fit and the ROS 2 (DDS)
//! output. `main.rs` is the thin binary; benchmarks and tests use these modules.

pub mod clock;
pub mod config;
pub mod drivers;
pub mod health;
pub mod offline;
pub mod pipeline;
pub mod replay;
pub mod ros2;
pub mod session;
