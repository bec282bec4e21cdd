//! Reference logs: a time-stamped record of the true input in the sensor frame, such as a rate
//! table's log, as a CSV file whose header names the columns and their units:
//!
//! ```text
//! t_s,wx_deg_s,wy_deg_s,wz_deg_s,fx_m_s2,fy_m_s2,fz_m_s2
//! 12.00,0.0,0.0,20.0,0.0,0.0,9.80665
//! ```
//!
//! Time: `t_s`, `t_ms` or `t_ns` (any origin: the log's own clock). Angular rate, required:
//! `wx_rad_s`/`wx_deg_s` and likewise `wy_*`, `wz_*`, the sensor's true inertial rate (so a
//! log made from a table's rate lacks Earth's rate, 15 deg/h, which matters only for gyros
//! stable to a few deg/h). Specific force, optional but needed for the accelerometer fit:
//! `fx_m_s2`/`fx_g` and likewise. Lines starting with `#` are comments.
//!
//! A rate table logs one column, its rate about its own axis: `t_s,rate_deg_s` (or
//! `rate_rad_s`), with the table axis in sensor axes given by a comment line
//! `# table-axis = +z` (a sensor axis or a vector `[x, y, z]`; positive rates turn the table
//! right-handed about it). It applies to the rows after it, so a log of several mountings
//! (each sensor axis on the table in turn) gives a new `# table-axis` line where the unit was
//! re-mounted. Unless the log also has the specific force columns, the table axis is taken as
//! VERTICAL: the specific force is local gravity along the axis, pointing up (along `+axis` or
//! `-axis`, whichever way the measured accel points: a bias cannot flip the sign of 1 g), and a
//! still segment whose measured gravity is not along the axis is refused. Local gravity is
//! `# gravity-m-s2 = G`, else WGS-84 normal gravity at `# latitude-deg = L`, else 9.80665
//! (a note says so). With the latitude, Earth's rate along the vertical (`Omega sin L`) is
//! added to the table's rate (a table logs its rate relative to the ground) and the
//! horizontal part, which the log cannot know, is carried as gyro bias uncertainty; without
//! it, all of Earth's rate is.
//!
//! ```text
//! # table-axis = +z
//! # latitude-deg = 40.0
//! t_s,rate_deg_s
//! 0.00,0.0
//! 0.01,0.4
//! ```
//!
//! The log's clock is aligned with the recording's by cross-correlating the magnitude of the
//! reference rate with the magnitude of the measured gyro rate (scale, misalignment and bias
//! errors barely change a magnitude profile): coarse over every overlap on binned data, then at
//! the recording's sample spacing around the best coarse lag, with parabolic interpolation of
//! the peak. The correlation is zero-padded (not normalised per overlap), so a repeated
//! pattern such as three identical rate-table runs cannot match one run late. The reference is
//! then averaged over each segment's time range.

use std::path::Path;

use imu_model::Vec3;
use imu_model::units::{DEG_TO_RAD, EARTH_RATE_RAD_S, STANDARD_GRAVITY_M_S2};

use crate::ImuSeries;
use crate::reference::direction::{format_direction, parse_direction};
use crate::reference::segment_truth::SegmentTruth;
use crate::segment::{Segment, SegmentKind};
use imu_model::did_you_mean;
use imu_model::earth::normal_gravity_m_s2;

mod align;
mod parse;
mod truth;

/// Largest relative difference between a plateau's measured and reference rate magnitude
/// before the log is taken to be in other units or of another run.
const RATE_TOLERANCE: f64 = 0.1;
/// Largest angle between a still segment's measured and reference specific force, degrees.
const DIRECTION_TOLERANCE_DEG: f64 = 10.0;
/// Smallest correlation accepted for the time alignment.
const MIN_CORRELATION: f64 = 0.5;

/// Errors reading or using a reference log.
#[derive(Debug, thiserror::Error)]
pub enum ReferenceLogError {
    /// The file could not be read.
    #[error("{file}: cannot read the reference log")]
    Io {
        /// The log file.
        file: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A line of the CSV is malformed, or the header is incomplete.
    #[error("{file}:{line}: {message}")]
    Csv {
        /// The log file.
        file: String,
        /// 1-based line.
        line: usize,
        /// What is wrong and what to do.
        message: String,
    },
    /// The clocks could not be aligned.
    #[error("{file}: cannot align the log with the recording: {message}")]
    Align {
        /// The log file.
        file: String,
        /// Why, and what to do.
        message: String,
    },
    /// The log does not cover, or does not match, the recording's segments.
    #[error("{file}: {summary}:{}", .problems.iter().map(|p| format!("\n  - {p}")).collect::<String>())]
    Segments {
        /// The log file.
        file: String,
        /// One line on the whole.
        summary: String,
        /// Each problem, naming the segment and its time range.
        problems: Vec<String>,
    },
}

/// A parsed reference log (times on the log's own clock, SI units, sensor frame).
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceLog {
    /// The file, for messages.
    pub file: String,
    /// Times on the log's clock, s (strictly increasing).
    pub t_s: Vec<f64>,
    /// True angular rate, rad/s.
    pub angular_rate_rad_s: Vec<[f64; 3]>,
    /// True specific force, m/s^2, when the log has it.
    pub specific_force_m_s2: Option<Vec<[f64; 3]>>,
    /// A one-column table log: the table axis (unit, sensor frame) of each row, and local
    /// gravity and latitude for the input the log does not give. None for a three-axis log.
    pub table: Option<TableLog>,
}

/// What a one-column rate table log adds (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct TableLog {
    /// The table axis of each row (unit vector, sensor frame).
    pub axis_sensor: Vec<[f64; 3]>,
    /// Where the axis changes: (1-based line of the `# table-axis` line, first row, axis).
    pub axis_lines: Vec<(usize, usize, [f64; 3])>,
    /// Local gravity, m/s^2.
    pub gravity_m_s2: f64,
    /// Where `gravity_m_s2` comes from.
    pub gravity_source: String,
    /// Site latitude, degrees, when the log gives it (Earth's vertical rate is then added).
    pub latitude_deg: Option<f64>,
}

/// A reference log with its clock offset to the recording.
#[derive(Clone, Debug, PartialEq)]
pub struct AlignedLog {
    /// The log.
    pub log: ReferenceLog,
    /// Log clock minus recording clock for the same instant, s (the recording's clock counts
    /// from its first sample).
    pub offset_s: f64,
    /// Correlation of reference and measured rate magnitudes at `offset_s`; `None` when the
    /// offset was given rather than found.
    pub correlation: Option<f64>,
}

#[cfg(test)]
mod tests;
