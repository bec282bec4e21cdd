//! The imud daemon as a library: configuration, the device session, the per-frame pipeline, the
//! device-clock fit, the loss accounting and the ROS 2 (DDS) output. `main.rs` is the thin binary; benchmarks and tests
//! use these modules.

pub mod clock;
pub mod config;
pub mod gaps;
pub mod health;
pub mod link;
pub mod offline;
pub mod pipeline;
pub mod ros2;
pub mod session;
pub mod startup;
