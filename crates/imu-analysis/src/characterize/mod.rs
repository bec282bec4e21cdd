//! The paper's characterisation tests beyond calibration: thermal (warm-up, temperature
//! coefficients with coloured-noise significance, 3.1.3/3.2.3), impact (shock response and
//! bias shifts, 3.3) and dynamic (integrated angle against a rate table, 3.4); `units` holds the
//! units their pages and summaries are read in (mg, deg/h); `noise` the Allan-family deviations
//! and noise terms of a static recording (`imu-noise`, `imud.noise`).

pub mod dynamic;
pub mod impact;
pub mod noise;
pub mod thermal;
pub mod units;
