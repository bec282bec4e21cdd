//! The true input over one segment, whatever the reference, and the conditions the recording
//! itself gives (temperature, time since power-on). A leaf: plans, logs and the simulator's
//! truth all produce it.

use crate::ImuSeries;
use crate::segment::Segment;

/// The true input over one segment, from a reference (sensor frame).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SegmentTruth {
    /// Mean true specific force, m/s^2.
    pub specific_force_m_s2: [f64; 3],
    /// Mean true angular rate (including Earth rate), rad/s.
    pub angular_rate_rad_s: [f64; 3],
    /// Mean true temperature, deg C.
    pub temp_c: f64,
    /// Mean time since power-on, s.
    pub time_since_power_on_s: f64,
}

/// Mean temperature and time since power-on over segment `s`, from the recording itself: its
/// temperature readings (else `fallback_temp_c`, else [`imu_model::units::REFERENCE_TEMP_C`]) and its
/// time since the first sample plus `powered_on_before_s`.
pub(crate) fn recording_conditions(
    series: &ImuSeries,
    s: &Segment,
    fallback_temp_c: Option<f64>,
    powered_on_before_s: f64,
) -> (f64, f64) {
    let times = &series.t_s[s.range()];
    let n = times.len().max(1) as f64;
    let temp_c = if series.temp.is_empty() {
        fallback_temp_c.unwrap_or(imu_model::units::REFERENCE_TEMP_C)
    } else {
        times.iter().map(|&t| series.temp_at(t)).sum::<f64>() / n
    };
    (temp_c, powered_on_before_s + times.iter().sum::<f64>() / n)
}
