//! Test plans: a TOML file stating a calibration procedure and its nominal inputs in order (the
//! positions of an index table, the Table 1 Earth-rate positions, rate-table plateaus), so that
//! a recording from real hardware can be calibrated without a simulator truth file (Aslan &
//! Saranli 3.1.2, 3.2.2, 3.2.3).
//!
//! A plan expands to one entry per segment the recording should contain, in order. The entries
//! are matched to the detected (or explicitly given) segments by a small sequence alignment,
//! so that a position too many or too few is named where it happens, and every match is
//! checked: kind, measured gravity direction against the planned one, plateau rate against the
//! nominal rate. The true input of each segment then follows from the plan: specific force
//! `g * up` (local gravity from the plan, by default WGS-84 normal gravity at the latitude),
//! the table rate, and Earth's rate in the sensor frame where the plan fixes north. Where it
//! does not (no `north`, or the table stopped at an unknown angle), the vertical part of
//! Earth's rate is still used and the unknown horizontal part is carried as a systematic gyro
//! bias uncertainty ([`PlanCaveats`]). On an index table that part turns with gravity, so it
//! can also bias a fitted g-sensitivity, by up to `Omega cos L / g` (5.7e-6 (rad/s)/(m/s^2) at
//! 40 deg): that is not carried in the standard errors, only said in a note; plan north where
//! g-sensitivity matters (Table 1). Temperature and time since power-on come from the
//! recording.
//!
//! A `skip` step stands for one segment the recording holds but the fit must not use (a
//! position known to have been disturbed, a pause in a transition): it is matched like any
//! step, so the order of the others is kept, and its segment is dropped from the segmentation
//! (listed in [`Segmentation::skipped`] with the step that skipped it). It applies to detected
//! segments only: with time ranges given by hand, leave the segment's range out instead.
//!
//! ```toml
//! format = "imud-plan/1"
//! latitude-deg = 40.0
//!
//! [[step]]                       # 12 positions, 30 degrees apart, about the sensor x axis
//! kind = "index-table"
//! axis = "x"
//! step-deg = 30.0
//! positions = 12
//! up = "z"                       # the sensor direction pointing up at table angle 0
//!
//! [[step]]                       # Table 1 position 1
//! kind = "static"
//! orientation = { z = "up", x = "north" }
//!
//! [[step]]                       # rate-table plateaus; 0 is a stop (a static segment)
//! kind = "rate-steps"
//! axis = "z"
//! rates-deg-s = [20, 40, 0, -20, -40, 0]
//! up = "z"
//!
//! [[step]]                       # a segment to leave out of the fit
//! kind = "skip"
//! label = "table bumped during this stop"
//! ```

use std::path::Path;

use imu_model::Vec3;
use imu_model::did_you_mean;
use imu_model::earth::{normal_gravity_m_s2, unknown_heading_variance_rad2_s2};
use imu_model::nalgebra::{Matrix3, Rotation3, Unit};
use imu_model::units::{EARTH_RATE_RAD_S, REFERENCE_TEMP_C};
use serde::Deserialize;

use crate::ImuSeries;
use crate::reference::direction::{format_direction, parse_axis};
use crate::reference::segment_truth::SegmentTruth;
use crate::segment::{Segment, SegmentKind, SegmentOptions, Segmentation};

mod check;
mod load;
mod parse;

use parse::*;

/// The `format` value of a plan file.
pub const PLAN_FORMAT: &str = "imud-plan/1";

/// Default largest angle between measured and planned gravity (or rotation axis), degrees.
pub const DEFAULT_DIRECTION_TOLERANCE_DEG: f64 = 10.0;
/// Default largest deviation of a plateau's measured rate from the nominal one, percent.
pub const DEFAULT_RATE_TOLERANCE_PERCENT: f64 = 10.0;
/// Errors loading a plan file.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The file could not be read.
    #[error("{file}: cannot read the plan")]
    Io {
        /// The plan file.
        file: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// Not valid TOML, or not the plan's shape (unknown key, wrong type, missing field).
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        /// The plan file.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong and what to do.
        message: String,
    },
    /// The values parse but do not make a usable plan.
    #[error("{file}{}: {context}: {message}", .line.map(|l| format!(":{l}")).unwrap_or_default())]
    Invalid {
        /// The plan file.
        file: String,
        /// 1-based line of the offending key or step, when found.
        line: Option<usize>,
        /// Where in the plan (`step 3 (index-table)`, `latitude-deg`).
        context: String,
        /// What is wrong and what to do.
        message: String,
    },
}

/// The recording does not follow the plan: every problem found, each naming the plan step,
/// the segment's time range, and what was planned and measured.
#[derive(Debug, thiserror::Error)]
#[error("{file}: {summary}:{}", .problems.iter().map(|p| format!("\n  - {p}")).collect::<String>())]
pub struct PlanMismatch {
    /// The plan file.
    pub file: String,
    /// One line on the whole (counts).
    pub summary: String,
    /// The individual problems, in plan order.
    pub problems: Vec<String>,
}

/// Failures of [`Plan::segmentation`].
#[derive(Debug, thiserror::Error)]
pub enum PlanSegmentationError {
    /// Segment detection failed.
    #[error(transparent)]
    Segment(#[from] crate::segment::SegmentError),
    /// The recording does not follow the plan.
    #[error(transparent)]
    Mismatch(#[from] PlanMismatch),
}

// ------------------------------------------------------------------------------ the plan

/// One expected segment of the recording.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PlanEntry {
    /// The `[[step]]` it comes from, 1-based.
    pub step: usize,
    /// Position within a compact step (index-table position, rate-steps entry), 1-based.
    pub position: Option<usize>,
    /// Number of entries the step expands to.
    pub of: usize,
    /// 1-based line of the step in the plan file, when found.
    pub line: Option<usize>,
    /// Static or plateau (for a skip entry: either; `Static` is stored).
    pub kind: SegmentKind,
    /// A `skip` step: matches any one segment, which is then left out of the fit; the
    /// orientation and rate fields are not used (up is stored as zero).
    pub skip: bool,
    /// What is expected, for messages (`index-table, 30 deg about +x`).
    pub description: String,
    /// Unit vector of the sensor direction pointing up (for a plateau: at the run's start; the
    /// table axis does not move, so its component along the axis holds throughout).
    pub up_sensor: [f64; 3],
    /// Unit vector of the sensor direction pointing north, when the plan fixes it.
    pub north_sensor: Option<[f64; 3]>,
    /// Rotation axis of a plateau (unit, sensor frame).
    pub axis_sensor: Option<[f64; 3]>,
    /// Nominal table rate about `axis_sensor`, rad/s (0 for static entries).
    pub rate_rad_s: f64,
    /// Explicit time range on the recording's clock (seconds from its first sample).
    pub window_s: Option<[f64; 2]>,
}

impl PlanEntry {
    /// `step 3 (line 27) position 5 of 12 [index-table, 120 deg about +x]`.
    pub fn name(&self) -> String {
        let mut s = format!("step {}", self.step);
        if let Some(l) = self.line {
            s.push_str(&format!(" (line {l})"));
        }
        if let Some(p) = self.position {
            s.push_str(&format!(" position {p} of {}", self.of));
        }
        format!("{s} [{}]", self.description)
    }

    fn up(&self) -> Vec3 {
        Vec3::from(self.up_sensor)
    }
}

/// A parsed, validated test plan.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Plan {
    /// The plan file (as given), for messages.
    pub file: String,
    /// Short name.
    pub name: Option<String>,
    /// What procedure it describes.
    pub description: Option<String>,
    /// Site latitude, degrees (sets Earth's rate and, by default, gravity).
    pub latitude_deg: Option<f64>,
    /// Local gravity used, m/s^2.
    pub gravity_m_s2: f64,
    /// Where `gravity_m_s2` comes from.
    pub gravity_source: String,
    /// Time the unit had been powered when the recording's first sample was taken, s.
    pub powered_on_before_s: f64,
    /// Temperature to assume when the recording has none, deg C.
    pub temp_c: Option<f64>,
    /// Largest angle between measured and planned gravity direction or rotation axis, deg.
    pub direction_tolerance_deg: f64,
    /// Largest deviation of a plateau's measured rate from its nominal rate, percent.
    pub rate_tolerance_percent: f64,
    /// The expected segments, in order.
    pub entries: Vec<PlanEntry>,
}

/// What a plan cannot tell about the true input, for the fit.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlanCaveats {
    /// Systematic uncertainty of the gyro's true input shared by the segments (Earth's rate
    /// where north is unknown), per axis, rad/s; add it in quadrature to the bias standard
    /// errors. `None` if the plan determines the input completely.
    pub gyro_bias_std_rad_s: Option<[f64; 3]>,
    /// Remarks for the report (gravity used, unknown Earth rate, assumed temperature).
    pub notes: Vec<crate::note::Note>,
}

#[cfg(test)]
mod tests;
