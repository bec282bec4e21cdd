//! The imud daemon as a library: configuration, the device session, the per-frame pipeline and
//! the device-clock fit. `main.rs` is the thin binary; benchmarks and tests use these modules.

pub mod clock;
pub mod config;
pub mod offline;
pub mod pipeline;
pub mod session;
