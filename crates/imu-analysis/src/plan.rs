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
use crate::reference::SegmentTruth;
use crate::segment::{Segment, SegmentKind, SegmentOptions, Segmentation};

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

// ------------------------------------------------------------------------------- file shape

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
struct PlanFile {
    format: String,
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    description: Option<String>,
    #[serde(default)]
    latitude_deg: Option<f64>,
    #[serde(default)]
    height_m: Option<f64>,
    #[serde(default)]
    gravity_m_s2: Option<f64>,
    #[serde(default)]
    powered_on_before_s: Option<f64>,
    #[serde(default)]
    temp_c: Option<f64>,
    #[serde(default)]
    direction_tolerance_deg: Option<f64>,
    #[serde(default)]
    rate_tolerance_percent: Option<f64>,
    #[serde(rename = "step", default)]
    steps: Vec<StepFile>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum StepKind {
    Static,
    IndexTable,
    RateSteps,
    Skip,
}

impl StepKind {
    fn name(self) -> &'static str {
        match self {
            StepKind::Static => "static",
            StepKind::IndexTable => "index-table",
            StepKind::RateSteps => "rate-steps",
            StepKind::Skip => "skip",
        }
    }
}

/// One `[[step]]`: a flat table (not a serde-tagged enum, so that toml can point at an unknown
/// key itself); which keys a kind takes is checked after parsing.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
struct StepFile {
    kind: StepKind,
    #[serde(default)]
    label: Option<String>,
    #[serde(default)]
    up: Option<SensorDirection>,
    #[serde(default)]
    north: Option<SensorDirection>,
    #[serde(default)]
    orientation: Option<OrientationFile>,
    #[serde(default)]
    axis: Option<SensorDirection>,
    #[serde(default)]
    step_deg: Option<f64>,
    #[serde(default)]
    positions: Option<u32>,
    #[serde(default)]
    start_deg: Option<f64>,
    #[serde(default)]
    rates_deg_s: Option<Vec<f64>>,
    #[serde(default)]
    start_s: Option<f64>,
    #[serde(default)]
    end_s: Option<f64>,
    #[serde(default)]
    windows_s: Option<Vec<[f64; 2]>>,
}

/// A compass or vertical direction of the local level frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum Compass {
    North,
    South,
    East,
    West,
    Up,
    Down,
}

impl Compass {
    /// As a unit vector in East-North-Up.
    fn enu(self) -> Vec3 {
        match self {
            Compass::East => Vec3::x(),
            Compass::West => -Vec3::x(),
            Compass::North => Vec3::y(),
            Compass::South => -Vec3::y(),
            Compass::Up => Vec3::z(),
            Compass::Down => -Vec3::z(),
        }
    }
}

/// `{ z = "up", x = "north" }`: where sensor axes point (as in the simulator's scenarios).
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct OrientationFile {
    #[serde(default)]
    x: Option<Compass>,
    #[serde(default)]
    y: Option<Compass>,
    #[serde(default)]
    z: Option<Compass>,
}

/// A direction in sensor axes: `"x"`, `"-z"`, `"+y"` or a vector `[x, y, z]` (normalised).
#[derive(Debug, Clone, Copy, PartialEq)]
struct SensorDirection(Vec3);

impl<'de> Deserialize<'de> for SensorDirection {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = SensorDirection;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a sensor axis (x, -x, +y, ..., -z) or a vector [x, y, z]")
            }
            fn visit_str<E: serde::de::Error>(self, s: &str) -> Result<SensorDirection, E> {
                parse_axis(s).map(SensorDirection).ok_or_else(|| {
                    E::custom(format!(
                        "`{s}` is not a sensor axis: write x, -x, +x, y, -y, +y, z, -z, +z or a \
                         vector [x, y, z]"
                    ))
                })
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<SensorDirection, A::Error> {
                let mut v = Vec::new();
                while let Some(x) = seq.next_element::<f64>()? {
                    v.push(x);
                }
                if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
                    return Err(serde::de::Error::custom(format!(
                        "a direction vector needs 3 finite numbers [x, y, z], got {v:?}"
                    )));
                }
                let d = Vec3::new(v[0], v[1], v[2]);
                if d.norm() < 1e-9 {
                    return Err(serde::de::Error::custom(
                        "a direction vector must not be [0, 0, 0]",
                    ));
                }
                Ok(SensorDirection(d.normalize()))
            }
        }
        d.deserialize_any(Visitor)
    }
}

/// A sensor direction written as in plans, `+z`, `-x`, `y` or `[x, y, z]` (normalised), from
/// text (a reference log's `# table-axis = ...` line).
pub(crate) fn parse_direction(s: &str) -> Option<Vec3> {
    let s = s.trim();
    if let Some(inner) = s.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
        let v: Vec<f64> = inner
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .ok()?;
        let [x, y, z] = v.as_slice() else {
            return None;
        };
        let d = Vec3::new(*x, *y, *z);
        return (d.iter().all(|c| c.is_finite()) && d.norm() > 1e-9).then(|| d.normalize());
    }
    parse_axis(s)
}

fn parse_axis(s: &str) -> Option<Vec3> {
    let (sign, name) = match s.as_bytes().first() {
        Some(b'-') => (-1.0, &s[1..]),
        Some(b'+') => (1.0, &s[1..]),
        _ => (1.0, s),
    };
    let v = match name {
        "x" => Vec3::x(),
        "y" => Vec3::y(),
        "z" => Vec3::z(),
        _ => return None,
    };
    Some(v * sign)
}

/// `+z` for an axis-aligned unit vector, else `[0.000, 0.866, 0.500]`.
pub fn format_direction(v: &Vec3) -> String {
    let names = ["x", "y", "z"];
    let i = v.iamax();
    if (v.norm() - 1.0).abs() < 1e-9 && (v[i].abs() - 1.0).abs() < 1e-9 {
        format!("{}{}", if v[i] < 0.0 { "-" } else { "+" }, names[i])
    } else {
        format!("[{:.3}, {:.3}, {:.3}]", v.x, v.y, v.z)
    }
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
    pub notes: Vec<String>,
}

/// The `[[step]]` (1-based) a byte offset falls in, by counting the step headers up to the
/// end of its line (an error on a whole table points at its header).
fn step_at(text: &str, offset: usize) -> Option<usize> {
    let offset = offset.min(text.len());
    let end = text[offset..].find('\n').map_or(text.len(), |i| offset + i);
    let before = text.get(..end).unwrap_or(text);
    let n = before
        .lines()
        .filter(|l| l.trim_start().starts_with("[[step]]"))
        .count();
    (n > 0).then_some(n)
}

fn parse_error(file: &str, text: &str, e: &toml::de::Error) -> PlanError {
    let offset = e.span().map_or(0, |s| s.start);
    let (line, column) = imu_model::line_col(text, offset);
    let raw = e.message().trim_end().to_string();
    let place = match step_at(text, offset) {
        Some(n) => format!("in [[step]] {n}"),
        None => "at the top level".to_string(),
    };
    let message = if raw.starts_with("unknown field") {
        let tokens: Vec<&str> = raw.split('`').skip(1).step_by(2).collect();
        let name = tokens.first().copied().unwrap_or_default();
        let expected = &tokens[1.min(tokens.len())..];
        format!(
            "unknown key `{name}` {place}; valid keys: {}{}",
            expected.join(", "),
            did_you_mean(name, expected)
        )
    } else if raw.starts_with("missing field `format`") {
        format!("{raw}; a plan file starts with format = \"{PLAN_FORMAT}\"")
    } else if raw.starts_with("unknown variant") {
        format!("{raw} ({place})")
    } else if raw.starts_with("missing field") {
        format!("{raw} {place}")
    } else {
        raw
    };
    PlanError::Parse {
        file: file.to_string(),
        line,
        column,
        message,
    }
}

/// Keys each step kind takes (besides `kind` and `label`).
fn keys_of(kind: StepKind) -> &'static [&'static str] {
    match kind {
        StepKind::Static => &["up", "north", "orientation", "start-s", "end-s"],
        StepKind::IndexTable => &[
            "axis",
            "step-deg",
            "positions",
            "start-deg",
            "up",
            "north",
            "orientation",
            "windows-s",
        ],
        StepKind::RateSteps => &[
            "axis",
            "rates-deg-s",
            "up",
            "north",
            "orientation",
            "windows-s",
        ],
        StepKind::Skip => &[],
    }
}

impl StepFile {
    /// The keys present, for the per-kind check.
    fn present(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        let mut add = |on: bool, k: &'static str| {
            if on {
                v.push(k);
            }
        };
        add(self.up.is_some(), "up");
        add(self.north.is_some(), "north");
        add(self.orientation.is_some(), "orientation");
        add(self.axis.is_some(), "axis");
        add(self.step_deg.is_some(), "step-deg");
        add(self.positions.is_some(), "positions");
        add(self.start_deg.is_some(), "start-deg");
        add(self.rates_deg_s.is_some(), "rates-deg-s");
        add(self.start_s.is_some(), "start-s");
        add(self.end_s.is_some(), "end-s");
        add(self.windows_s.is_some(), "windows-s");
        v
    }

    fn has_windows(&self) -> bool {
        self.start_s.is_some() || self.end_s.is_some() || self.windows_s.is_some()
    }
}

/// Up and (optionally) north in sensor axes from a step's `up`/`north` or `orientation`.
fn step_frame(s: &StepFile) -> Result<(Vec3, Option<Vec3>), String> {
    const HOW: &str = "give `up = \"-z\"` (the sensor direction pointing up; a vector [x, y, z] \
                       also works), optionally with `north`, or `orientation = { z = \"up\", \
                       x = \"north\" }`";
    match (&s.up, &s.north, &s.orientation) {
        (Some(_), _, Some(_)) | (None, Some(_), Some(_)) => Err(format!(
            "give either `up` (and `north`) or `orientation`, not both; {HOW}"
        )),
        (None, Some(_), None) => Err(format!("`north` needs `up`; {HOW}")),
        (None, None, None) => Err(format!("the orientation is missing; {HOW}")),
        (Some(up), north, None) => {
            let up = up.0;
            let Some(n) = north else {
                return Ok((up, None));
            };
            let n = n.0;
            // Perpendicular within 2 degrees, then made exactly perpendicular.
            if up.dot(&n).abs() > 2f64.to_radians().sin() {
                return Err(format!(
                    "`north` {} is not perpendicular to `up` {} ({:.1} deg apart)",
                    format_direction(&n),
                    format_direction(&up),
                    up.angle(&n).to_degrees()
                ));
            }
            Ok((up, Some((n - up * up.dot(&n)).normalize())))
        }
        (None, None, Some(o)) => {
            let axes = [o.x, o.y, o.z];
            let v: Vec<Option<Vec3>> = axes.iter().map(|a| a.map(Compass::enu)).collect();
            let (x, y, z) = match (v[0], v[1], v[2]) {
                (Some(x), Some(y), None) => (x, y, x.cross(&y)),
                (Some(x), None, Some(z)) => (x, z.cross(&x), z),
                (None, Some(y), Some(z)) => (y.cross(&z), y, z),
                (Some(x), Some(y), Some(z)) => (x, y, z),
                _ => {
                    return Err(format!(
                        "`orientation` needs the directions of at least two sensor axes, e.g. \
                         {{ z = \"up\", x = \"north\" }}; with only the vertical known, write \
                         `up` instead ({HOW})"
                    ));
                }
            };
            // Columns: the sensor axes in East-North-Up (enu_from_sensor).
            let m = Matrix3::from_columns(&[x, y, z]);
            if (m.transpose() * m - Matrix3::identity()).norm() > 1e-9 || m.determinant() < 0.5 {
                return Err(format!(
                    "the axis directions {axes:?} do not form a right-handed orthogonal frame"
                ));
            }
            let sensor_from_enu = m.transpose();
            Ok((
                sensor_from_enu * Compass::Up.enu(),
                Some(sensor_from_enu * Compass::North.enu()),
            ))
        }
    }
}

/// Check step `i` (0-based) of a plan and append the entries it expands to. `any_explicit`
/// is the first step that gives time ranges by hand, if any (then every step must).
fn expand_step(
    file: &str,
    text: &str,
    i: usize,
    s: &StepFile,
    any_explicit: Option<usize>,
    entries: &mut Vec<PlanEntry>,
) -> Result<(), PlanError> {
    let n = i + 1;
    let bad = |k: &str, m: String| PlanError::Invalid {
        file: file.to_string(),
        line: imu_model::line_of_key(text, &format!("step[{i}].{k}"))
            .or_else(|| imu_model::line_of_key(text, &format!("step[{i}]"))),
        context: format!("step {n} ({})", s.kind.name()),
        message: m,
    };
    let allowed = keys_of(s.kind);
    for k in s.present() {
        if !allowed.contains(&k) {
            return Err(bad(
                k,
                format!(
                    "`{k}` does not apply to a {} step (its keys: {})",
                    s.kind.name(),
                    ["kind", "label"]
                        .iter()
                        .chain(allowed)
                        .copied()
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
    }
    let line = imu_model::line_of_key(text, &format!("step[{i}]"));
    if s.kind == StepKind::Skip
        && let Some(first) = any_explicit
    {
        return Err(bad(
            "kind",
            format!(
                "a skip step matches a detected segment, but step {} gives its time range by \
                 hand (so no segment is detected); leave the segment's range out instead",
                first + 1
            ),
        ));
    }
    if let Some(first) = any_explicit
        && !s.has_windows()
    {
        return Err(bad(
            "kind",
            format!(
                "step {} gives its time range by hand, so every step must (start-s/end-s, or \
                 windows-s with one [start, end] per position or rate); detection is used only \
                 when no step gives one",
                first + 1
            ),
        ));
    }
    // A skip step has no orientation: its entry matches any segment and is never checked.
    let (up, north) = if s.kind == StepKind::Skip {
        (Vec3::zeros(), None)
    } else {
        step_frame(s).map_err(|m| bad("up", m))?
    };
    let label = s
        .label
        .as_deref()
        .map(|l| format!("{l}: "))
        .unwrap_or_default();
    let windows = |count: usize| -> Result<Vec<Option<[f64; 2]>>, PlanError> {
        let Some(w) = &s.windows_s else {
            return Ok(vec![None; count]);
        };
        if w.len() != count {
            return Err(bad(
                "windows-s",
                format!(
                    "windows-s has {} [start, end] pairs, the step expands to {count} segments",
                    w.len()
                ),
            ));
        }
        if let Some(p) = w.iter().find(|p| !(p[0].is_finite() && p[1] > p[0])) {
            return Err(bad(
                "windows-s",
                format!("window {p:?} must have start < end (seconds)"),
            ));
        }
        Ok(w.iter().map(|p| Some(*p)).collect())
    };
    let axis = |what: &str| {
        s.axis.map(|a| a.0).ok_or_else(|| {
            bad(
                "axis",
                format!("missing `axis` (the table axis in sensor axes, e.g. {what})"),
            )
        })
    };
    let frame_text = |up: &Vec3, north: &Option<Vec3>| match north {
        Some(nv) => format!(
            "up {}, north {}",
            format_direction(up),
            format_direction(nv)
        ),
        None => format!("up {}", format_direction(up)),
    };
    let base = PlanEntry {
        step: n,
        position: None,
        of: 1,
        line,
        kind: SegmentKind::Static,
        skip: false,
        description: String::new(),
        up_sensor: up.into(),
        north_sensor: north.map(Into::into),
        axis_sensor: None,
        rate_rad_s: 0.0,
        window_s: None,
    };
    match s.kind {
        StepKind::Skip => entries.push(PlanEntry {
            skip: true,
            description: format!("{label}skip"),
            ..base
        }),
        StepKind::Static => {
            let window_s = match (s.start_s, s.end_s) {
                (None, None) => None,
                (Some(a), Some(b)) if a.is_finite() && b > a => Some([a, b]),
                (Some(_), Some(_)) => {
                    return Err(bad("start-s", "start-s must be before end-s".into()));
                }
                _ => {
                    return Err(bad(
                        "start-s",
                        "give both start-s and end-s (seconds from the recording's first \
                         sample), or neither"
                            .into(),
                    ));
                }
            };
            entries.push(PlanEntry {
                description: format!("{label}static, {}", frame_text(&up, &north)),
                window_s,
                ..base
            });
        }
        StepKind::IndexTable => {
            let axis = axis("\"x\" or \"-y\"")?;
            let step_deg = s.step_deg.filter(|x| x.is_finite()).ok_or_else(|| {
                bad(
                    "step-deg",
                    "missing `step-deg` (the angle between positions, degrees)".into(),
                )
            })?;
            let positions = s.positions.filter(|&p| p > 0).ok_or_else(|| {
                bad(
                    "positions",
                    "missing or zero `positions` (the number of table positions, 12 for a \
                     full turn in 30-degree steps)"
                        .into(),
                )
            })? as usize;
            let start_deg = s.start_deg.unwrap_or(0.0);
            let unit = Unit::new_normalize(axis);
            for (p, window_s) in windows(positions)?.into_iter().enumerate() {
                let angle_deg = start_deg + step_deg * p as f64;
                // The unit turns by +angle about its own axis (as the simulator's index
                // table does: enu_from_sensor = q0 * R(axis, angle)), so directions fixed in
                // space turn by -angle in sensor axes.
                let r = Rotation3::from_axis_angle(&unit, -angle_deg.to_radians());
                let (up_p, north_p) = (r * up, north.map(|nv| r * nv));
                entries.push(PlanEntry {
                    position: Some(p + 1),
                    of: positions,
                    description: format!(
                        "{label}index-table, {angle_deg} deg about {}: {}",
                        format_direction(&axis),
                        frame_text(&up_p, &north_p)
                    ),
                    up_sensor: up_p.into(),
                    north_sensor: north_p.map(Into::into),
                    window_s,
                    ..base.clone()
                });
            }
        }
        StepKind::RateSteps => {
            let axis = axis("\"z\"")?;
            let rates = s.rates_deg_s.clone().unwrap_or_default();
            if rates.is_empty() || rates.iter().any(|r| !r.is_finite()) {
                return Err(bad(
                    "rates-deg-s",
                    "missing or empty `rates-deg-s` (the plateau rates in order, deg/s; 0 for \
                     a stop)"
                        .into(),
                ));
            }
            let vertical = axis.dot(&up).abs() > 1f64.to_radians().cos();
            if !vertical && rates.contains(&0.0) {
                return Err(bad(
                    "rates-deg-s",
                    format!(
                        "the table axis {} is not vertical (up is {}), so where the table \
                         stops (rate 0) gravity is at an unknown angle; plan the stops as \
                         separate static steps",
                        format_direction(&axis),
                        format_direction(&up)
                    ),
                ));
            }
            for (p, (r, window_s)) in rates.iter().zip(windows(rates.len())?).enumerate() {
                let entry = PlanEntry {
                    position: Some(p + 1),
                    of: rates.len(),
                    window_s,
                    ..base.clone()
                };
                entries.push(if *r == 0.0 {
                    // The table stopped at an angle nobody logged: north is lost (the axis is
                    // vertical here, so north is never along it).
                    PlanEntry {
                        description: format!(
                            "{label}rate-steps stop (0 deg/s) about {}: up {}, north unknown",
                            format_direction(&axis),
                            format_direction(&up)
                        ),
                        north_sensor: None,
                        ..entry
                    }
                } else {
                    PlanEntry {
                        kind: SegmentKind::Plateau,
                        description: format!(
                            "{label}rate-steps, {r} deg/s about {}",
                            format_direction(&axis)
                        ),
                        axis_sensor: Some(axis.into()),
                        rate_rad_s: r.to_radians(),
                        ..entry
                    }
                });
            }
        }
    }
    Ok(())
}

impl Plan {
    /// Reads and validates a plan file.
    pub fn load(path: &Path) -> Result<Plan, PlanError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| PlanError::Io {
            file: file.clone(),
            source,
        })?;
        Plan::from_toml_str(&text, &file)
    }

    /// Parses and validates plan text; `file` names it in messages.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Plan, PlanError> {
        let raw: PlanFile = toml::from_str(text).map_err(|e| parse_error(file, text, &e))?;
        let invalid = |key: &str, context: &str, message: String| PlanError::Invalid {
            file: file.to_string(),
            line: imu_model::line_of_key(text, key),
            context: context.to_string(),
            message,
        };
        if raw.format != PLAN_FORMAT {
            return Err(invalid(
                "format",
                "format",
                format!(
                    "`{}` is not a plan format this version reads; write format = \"{PLAN_FORMAT}\"",
                    raw.format
                ),
            ));
        }
        if let Some(l) = raw.latitude_deg
            && !(-90.0..=90.0).contains(&l)
        {
            return Err(invalid(
                "latitude-deg",
                "latitude-deg",
                format!("{l} is outside -90..90 degrees"),
            ));
        }
        let height_m = raw.height_m.unwrap_or(0.0);
        if !height_m.is_finite() || height_m.abs() > 20_000.0 {
            return Err(invalid(
                "height-m",
                "height-m",
                format!("{height_m} m is not a height above the ellipsoid"),
            ));
        }
        let (gravity_m_s2, gravity_source) = match (raw.gravity_m_s2, raw.latitude_deg) {
            (Some(g), _) => {
                if !(9.7..=9.9).contains(&g) {
                    return Err(invalid(
                        "gravity-m-s2",
                        "gravity-m-s2",
                        format!("{g} m/s^2 is not a gravity on Earth's surface (9.78..9.83)"),
                    ));
                }
                (g, format!("{g} m/s^2 (given in the plan)"))
            }
            (None, Some(lat)) => {
                let g = normal_gravity_m_s2(lat, height_m);
                (
                    g,
                    format!(
                        "{g:.5} m/s^2 (WGS-84 normal gravity at latitude {lat} deg, height {height_m} m)"
                    ),
                )
            }
            (None, None) => {
                return Err(invalid(
                    "format",
                    "gravity",
                    "give latitude-deg (gravity then follows from WGS-84 normal gravity, and \
                     Earth's rate from the latitude) or gravity-m-s2"
                        .into(),
                ));
            }
        };
        let positive_or = |v: Option<f64>, key: &str, default: f64| {
            let x = v.unwrap_or(default);
            if x.is_finite() && x > 0.0 {
                Ok(x)
            } else {
                Err(invalid(key, key, format!("{x} must be positive")))
            }
        };
        let direction_tolerance_deg = positive_or(
            raw.direction_tolerance_deg,
            "direction-tolerance-deg",
            DEFAULT_DIRECTION_TOLERANCE_DEG,
        )?;
        let rate_tolerance_percent = positive_or(
            raw.rate_tolerance_percent,
            "rate-tolerance-percent",
            DEFAULT_RATE_TOLERANCE_PERCENT,
        )?;
        let powered_on_before_s = raw.powered_on_before_s.unwrap_or(0.0);
        if !(powered_on_before_s.is_finite() && powered_on_before_s >= 0.0) {
            return Err(invalid(
                "powered-on-before-s",
                "powered-on-before-s",
                "must be 0 or more seconds".into(),
            ));
        }
        if let Some(t) = raw.temp_c
            && !(-60.0..=150.0).contains(&t)
        {
            return Err(invalid(
                "temp-c",
                "temp-c",
                format!("{t} deg C is not a sensor temperature"),
            ));
        }
        if raw.steps.is_empty() {
            return Err(invalid(
                "format",
                "step",
                "a plan needs at least one [[step]]".into(),
            ));
        }
        if raw.steps.iter().all(|s| s.kind == StepKind::Skip) {
            return Err(invalid(
                "format",
                "step",
                "every step is a skip: a plan needs at least one segment to fit".into(),
            ));
        }
        let any_explicit = raw.steps.iter().position(StepFile::has_windows);
        let mut entries = Vec::new();
        for (i, step) in raw.steps.iter().enumerate() {
            expand_step(file, text, i, step, any_explicit, &mut entries)?;
        }
        Ok(Plan {
            file: file.to_string(),
            name: raw.name,
            description: raw.description,
            latitude_deg: raw.latitude_deg,
            gravity_m_s2,
            gravity_source,
            powered_on_before_s,
            temp_c: raw.temp_c,
            direction_tolerance_deg,
            rate_tolerance_percent,
            entries,
        })
    }

    /// True when the plan gives every segment's time range by hand.
    pub fn explicit_windows(&self) -> bool {
        self.entries.iter().all(|e| e.window_s.is_some())
    }

    /// Number of entries of one kind (skip entries not counted).
    pub fn count(&self, kind: SegmentKind) -> usize {
        self.entries
            .iter()
            .filter(|e| e.kind == kind && !e.skip)
            .count()
    }

    /// Number of skip entries.
    pub fn count_skips(&self) -> usize {
        self.entries.iter().filter(|e| e.skip).count()
    }

    /// The segments of `series`: detected, or, when the plan gives time ranges, exactly those
    /// (detection still runs for its thresholds, which the report shows). Detected segments
    /// matched to a skip step are moved to [`Segmentation::skipped`].
    pub fn segmentation(
        &self,
        series: &ImuSeries,
        opts: &SegmentOptions,
    ) -> Result<Segmentation, crate::reference::ReferenceError> {
        let mut seg = crate::segment::detect(series, opts)?;
        if !self.explicit_windows() {
            if self.count_skips() > 0 {
                let pairs = self.check(&seg.segments, true)?;
                let skipped: Vec<(usize, usize)> = pairs
                    .into_iter()
                    .filter(|(e, _)| self.entries[*e].skip)
                    .collect();
                for &(e, s) in skipped.iter().rev() {
                    let segment = seg.segments.remove(s);
                    seg.skipped.insert(
                        0,
                        crate::segment::SkippedSegment {
                            number: s + 1,
                            by: self.entries[e].name(),
                            segment,
                        },
                    );
                }
            }
            return Ok(seg);
        }
        let mut segments = Vec::with_capacity(self.entries.len());
        for e in &self.entries {
            let [a, b] = e.window_s.expect("explicit");
            let lo = series.t_s.partition_point(|&t| t < a);
            let hi = series.t_s.partition_point(|&t| t <= b);
            if hi < lo + 2 {
                let end = series.t_s.last().copied().unwrap_or(0.0);
                return Err(PlanMismatch {
                    file: self.file.clone(),
                    summary: "a time range given by hand holds no data".into(),
                    problems: vec![format!(
                        "{}: {a}-{b} s holds {} samples (the recording spans 0-{end:.1} s)",
                        e.name(),
                        hi.saturating_sub(lo)
                    )],
                }
                .into());
            }
            segments.push(Segment::from_samples(series, lo..hi, e.kind));
        }
        seg.segments = segments;
        Ok(seg)
    }

    /// The true input of each of `segments` (which must follow the plan, see [`PlanMismatch`]).
    pub fn segment_truth(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<Vec<SegmentTruth>, PlanMismatch> {
        Ok(self
            .resolve(series, segments)?
            .into_iter()
            .map(|r| r.truth)
            .collect())
    }

    /// What the plan leaves unknown about the true input of `segments`, and notes.
    pub fn caveats(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<PlanCaveats, PlanMismatch> {
        let resolved = self.resolve(series, segments)?;
        let mut notes = vec![format!(
            "plan {}: gravity {}",
            self.file, self.gravity_source
        )];
        let mut sd = [0.0f64; 3];
        let mut n_unknown = 0;
        for r in &resolved {
            if r.rate_std_rad_s.iter().any(|s| *s > 0.0) {
                n_unknown += 1;
            }
            for (m, x) in sd.iter_mut().zip(r.rate_std_rad_s) {
                *m = m.max(x);
            }
        }
        let gyro_bias_std_rad_s = (n_unknown > 0).then_some(sd);
        if n_unknown > 0 {
            notes.push(format!(
                "Earth's rate is not fully known in {n_unknown} of {} segments (no north in the \
                 plan, a table stopped at an unlogged angle, no latitude, or a plateau's \
                 partial turn): up to [{:.1e}, {:.1e}, {:.1e}] rad/s per axis, carried as a \
                 systematic gyro bias uncertainty; a g-sensitivity fitted from these segments \
                 can be off by up to {:.1e} (rad/s)/(m/s^2) more than its standard error says \
                 (give north in the plan where it matters)",
                resolved.len(),
                sd[0],
                sd[1],
                sd[2],
                EARTH_RATE_RAD_S * self.latitude_deg.map_or(1.0, |l| l.to_radians().cos())
                    / self.gravity_m_s2
            ));
        }
        if series.temp.is_empty() {
            notes.push(format!(
                "the recording has no temperature readings: {} deg C assumed{}",
                self.temp_c.unwrap_or(REFERENCE_TEMP_C),
                if self.temp_c.is_some() {
                    " (plan temp-c)"
                } else {
                    " (give temp-c in the plan); temperature effects cannot be fitted"
                }
            ));
        }
        Ok(PlanCaveats {
            gyro_bias_std_rad_s,
            notes,
        })
    }

    /// Match, check and compute the truth of every segment.
    fn resolve(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<Vec<Resolved>, PlanMismatch> {
        // The segments skip steps matched are gone (see `segmentation`): match the rest.
        let pairs = self.check(segments, false)?;
        Ok(pairs
            .into_iter()
            .map(|(e, s)| self.truth_of(&self.entries[e], &segments[s], series))
            .collect())
    }

    /// Problems of matching entry `e` with segment `s` (empty if compatible).
    fn problems(&self, e: &PlanEntry, s: &Segment, index: usize) -> Vec<String> {
        if e.skip {
            return Vec::new();
        }
        let head = format!(
            "{}: segment {} at {:.1}-{:.1} s",
            e.name(),
            index + 1,
            s.start_s,
            s.end_s
        );
        let kind = |k: SegmentKind| match k {
            SegmentKind::Static => "static",
            SegmentKind::Plateau => "a rate plateau",
        };
        if e.kind != s.kind {
            return vec![format!(
                "{head}: the plan expects {} but the segment is {} (mean rate {:.2} deg/s)",
                kind(e.kind),
                kind(s.kind),
                s.mean_gyro().norm().to_degrees()
            )];
        }
        let mut out = Vec::new();
        let tol = self.direction_tolerance_deg;
        let planned_f = self.specific_force_dir(e);
        let measured_f = s.mean_accel();
        if let Some(pf) = planned_f
            && measured_f.norm() > 0.0
        {
            let angle = pf.angle(&measured_f).to_degrees();
            if angle > tol {
                out.push(format!(
                    "{head}: measured up {} is {angle:.1} deg from the planned {} (tolerance \
                     {tol} deg)",
                    format_direction(&measured_f.normalize()),
                    format_direction(&pf),
                ));
            }
        }
        if let Some(axis) = e.axis_sensor.map(Vec3::from) {
            let nominal_deg_s = e.rate_rad_s.to_degrees();
            let w = s.mean_gyro();
            let about_deg_s = w.dot(&axis).to_degrees();
            let off_percent = 100.0 * (about_deg_s - nominal_deg_s).abs() / nominal_deg_s.abs();
            if about_deg_s.signum() != nominal_deg_s.signum()
                || off_percent > self.rate_tolerance_percent
            {
                out.push(format!(
                    "{head}: measured {about_deg_s:.2} deg/s about {}, planned \
                     {nominal_deg_s} deg/s ({off_percent:.0} % off, tolerance {} %)",
                    format_direction(&axis),
                    self.rate_tolerance_percent
                ));
            } else {
                let planned_axis = axis * nominal_deg_s.signum();
                let angle = planned_axis.angle(&w).to_degrees();
                if angle > tol {
                    out.push(format!(
                        "{head}: measured rotation axis {} is {angle:.1} deg from the planned {} \
                         (tolerance {tol} deg)",
                        format_direction(&w.normalize()),
                        format_direction(&planned_axis)
                    ));
                }
            }
        }
        out
    }

    /// Unit direction of the planned mean specific force, when gravity dominates it.
    fn specific_force_dir(&self, e: &PlanEntry) -> Option<Vec3> {
        let up = e.up();
        match e.axis_sensor.map(Vec3::from) {
            None => Some(up),
            Some(a) => {
                let along = up.dot(&a);
                (along.abs() > 0.5).then(|| a * along.signum())
            }
        }
    }

    /// Align entries (with or without the skip entries) with segments (a Needleman-Wunsch
    /// alignment: a position too many or too few shows as a gap where it happens instead of
    /// shifting every later match), then check every matched pair. Returns `(entry, segment)`
    /// index pairs covering both lists (entry indices into `self.entries`).
    fn check(
        &self,
        segments: &[Segment],
        with_skips: bool,
    ) -> Result<Vec<(usize, usize)>, PlanMismatch> {
        let used: Vec<usize> = (0..self.entries.len())
            .filter(|&e| with_skips || !self.entries[e].skip)
            .collect();
        let (ne, ns) = (used.len(), segments.len());
        let cost = |e: usize, s: usize| -> f64 {
            let (pe, sg) = (&self.entries[used[e]], &segments[s]);
            if pe.skip {
                0.0
            } else if pe.kind != sg.kind {
                1.8
            } else if self.problems(pe, sg, s).is_empty() {
                0.0
            } else {
                1.0
            }
        };
        const GAP: f64 = 1.0;
        let mut d = vec![vec![0.0f64; ns + 1]; ne + 1];
        for (i, row) in d.iter_mut().enumerate() {
            row[0] = i as f64 * GAP;
        }
        for (j, x) in d[0].iter_mut().enumerate() {
            *x = j as f64 * GAP;
        }
        for i in 1..=ne {
            for j in 1..=ns {
                d[i][j] = (d[i - 1][j - 1] + cost(i - 1, j - 1))
                    .min(d[i - 1][j] + GAP)
                    .min(d[i][j - 1] + GAP);
            }
        }
        // Trace back, preferring matches; collect the alignment in order.
        enum Step {
            Pair(usize, usize),
            NoSegment(usize),
            NoEntry(usize),
        }
        let mut path = Vec::new();
        let (mut i, mut j) = (ne, ns);
        while i > 0 || j > 0 {
            if i > 0 && j > 0 && (d[i][j] - (d[i - 1][j - 1] + cost(i - 1, j - 1))).abs() < 1e-9 {
                path.push(Step::Pair(used[i - 1], j - 1));
                i -= 1;
                j -= 1;
            } else if i > 0 && (j == 0 || (d[i][j] - (d[i - 1][j] + GAP)).abs() < 1e-9) {
                path.push(Step::NoSegment(used[i - 1]));
                i -= 1;
            } else {
                path.push(Step::NoEntry(j - 1));
                j -= 1;
            }
        }
        path.reverse();

        let mut problems = Vec::new();
        let mut pairs = Vec::new();
        // The segment that came last before a gap, for saying where a missing one should be.
        let mut last_segment: Option<usize> = None;
        for step in &path {
            match *step {
                Step::Pair(e, s) => {
                    problems.extend(self.problems(&self.entries[e], &segments[s], s));
                    pairs.push((e, s));
                    last_segment = Some(s);
                }
                Step::NoSegment(e) => {
                    let after = match last_segment {
                        Some(s) => format!(
                            "after segment {} ({:.1}-{:.1} s)",
                            s + 1,
                            segments[s].start_s,
                            segments[s].end_s
                        ),
                        None => "before the first segment".into(),
                    };
                    let next = segments.get(last_segment.map_or(0, |s| s + 1)).map_or_else(
                        || " (the recording has no more segments)".to_string(),
                        |n| {
                            format!(
                                " and before the segment at {:.1}-{:.1} s",
                                n.start_s, n.end_s
                            )
                        },
                    );
                    problems.push(format!(
                        "{} has no segment: expected {after}{next}",
                        self.entries[e].name()
                    ));
                }
                Step::NoEntry(s) => {
                    let sg = &segments[s];
                    let what = match sg.kind {
                        SegmentKind::Static => format!(
                            "static, measured up {}",
                            format_direction(&sg.mean_accel().normalize())
                        ),
                        SegmentKind::Plateau => {
                            let w = sg.mean_gyro();
                            format!(
                                "rate plateau, {:.2} deg/s about {}",
                                w.norm().to_degrees(),
                                format_direction(&w.normalize())
                            )
                        }
                    };
                    problems.push(format!(
                        "segment {} at {:.1}-{:.1} s ({what}) is not in the plan",
                        s + 1,
                        sg.start_s,
                        sg.end_s
                    ));
                    last_segment = Some(s);
                }
            }
        }
        if problems.is_empty() {
            return Ok(pairs);
        }
        let count = |k: SegmentKind| segments.iter().filter(|s| s.kind == k).count();
        let summary = if ne != ns {
            let skips = if with_skips && self.count_skips() > 0 {
                format!(", {} skip", self.count_skips())
            } else {
                String::new()
            };
            format!(
                "the plan expects {ne} segments ({} static, {} plateau{skips}), the recording has \
                 {ns} ({} static, {} plateau); fix the plan, or give the time ranges by hand \
                 (start-s/end-s, windows-s)",
                self.count(SegmentKind::Static),
                self.count(SegmentKind::Plateau),
                count(SegmentKind::Static),
                count(SegmentKind::Plateau),
            )
        } else {
            format!(
                "the recording does not follow the plan ({ne} segments each; {} {})",
                problems.len(),
                if problems.len() == 1 {
                    "mismatch"
                } else {
                    "mismatches"
                }
            )
        };
        Err(PlanMismatch {
            file: self.file.clone(),
            summary,
            problems,
        })
    }

    /// Earth's rate in sensor axes for an orientation, and the per-axis standard deviation of
    /// what the plan leaves unknown of it.
    fn earth_rate(&self, up: &Vec3, north: Option<&Vec3>) -> (Vec3, [f64; 3]) {
        let om = EARTH_RATE_RAD_S;
        match (self.latitude_deg, north) {
            (Some(lat), Some(n)) => {
                let l = lat.to_radians();
                ((n * l.cos() + up * l.sin()) * om, [0.0; 3])
            }
            (Some(lat), None) => (
                up * imu_model::earth::earth_rate_split_rad_s(lat).0,
                std::array::from_fn(|a| unknown_heading_variance_rad2_s2(Some(lat), up[a]).sqrt()),
            ),
            (None, _) => (
                Vec3::zeros(),
                [unknown_heading_variance_rad2_s2(None, 0.0).sqrt(); 3],
            ),
        }
    }

    fn truth_of(&self, e: &PlanEntry, s: &Segment, series: &ImuSeries) -> Resolved {
        let g = self.gravity_m_s2;
        let up = e.up();
        let north = e.north_sensor.map(Vec3::from);
        let (earth, earth_sd) = self.earth_rate(&up, north.as_ref());
        let (f, w, sd) = match e.axis_sensor.map(Vec3::from) {
            None => (up * g, earth, earth_sd),
            Some(a) => {
                // The table axis keeps its direction in space, so gravity's and Earth rate's
                // components along it hold; the perpendicular parts turn with the table and
                // average out over whole turns. What is left of Earth rate's perpendicular part
                // after a partial turn (at most |mean of a unit phasor over the angle turned|
                // = 2/angle) is carried as uncertainty. Gravity's perpendicular part is zero
                // for a vertical table axis (the usual set-up); otherwise the along-axis mean
                // is an approximation (the accel is not fitted to plateaus).
                let along_sd = (0..3)
                    .map(|b| (a[b] * earth_sd[b]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let turned_rad = (e.rate_rad_s * (s.end_s - s.start_s)).abs();
                let perp = EARTH_RATE_RAD_S * (2.0 / turned_rad.max(1e-9)).min(1.0);
                let sd = std::array::from_fn(|b| {
                    let along = a[b].abs() * along_sd;
                    let across = perp * ((1.0 - a[b] * a[b]).max(0.0) / 2.0).sqrt();
                    along.hypot(across)
                });
                (a * (g * up.dot(&a)), a * (e.rate_rad_s + earth.dot(&a)), sd)
            }
        };
        let (temp_c, time_since_power_on_s) = crate::reference::recording_conditions(
            series,
            s,
            self.temp_c,
            self.powered_on_before_s,
        );
        Resolved {
            truth: SegmentTruth {
                specific_force_m_s2: f.into(),
                angular_rate_rad_s: w.into(),
                temp_c,
                time_since_power_on_s,
            },
            rate_std_rad_s: sd,
        }
    }

    /// One-line description for reports and provenance.
    pub fn describe(&self) -> String {
        format!(
            "test plan {}{} ({} segments: {} static, {} rate plateaus{}{})",
            self.file,
            self.name
                .as_deref()
                .map(|n| format!(" `{n}`"))
                .unwrap_or_default(),
            self.entries.len(),
            self.count(SegmentKind::Static),
            self.count(SegmentKind::Plateau),
            match self.count_skips() {
                0 => String::new(),
                k => format!(", {k} skipped"),
            },
            if self.explicit_windows() {
                ", time ranges given by hand"
            } else {
                ""
            }
        )
    }
}

/// A matched segment's truth and the unknown part of its angular rate.
struct Resolved {
    truth: SegmentTruth,
    rate_std_rad_s: [f64; 3],
}

#[cfg(test)]
mod tests {
    use super::*;

    const PLAN: &str = r#"format = "imud-plan/1"
latitude-deg = 40.0

[[step]]
kind = "index-table"
axis = "x"
step-deg = 90.0
positions = 4
up = "z"

[[step]]
kind = "static"
orientation = { z = "up", x = "north" }

[[step]]
kind = "rate-steps"
axis = "z"
rates-deg-s = [20, 0, -20]
up = "z"
"#;

    #[test]
    fn expands_steps_in_order() {
        let p = Plan::from_toml_str(PLAN, "p.toml").unwrap();
        assert_eq!(p.entries.len(), 4 + 1 + 3);
        // Turning the unit +90 deg about x moves "up" from +z to +y in sensor axes (the
        // simulator's index table: q = q0 * R(x, 90 deg)).
        let ups: Vec<String> = p.entries[..4]
            .iter()
            .map(|e| format_direction(&Vec3::from(e.up_sensor)))
            .collect();
        assert_eq!(ups, ["+z", "+y", "-z", "-y"]);
        assert_eq!(p.entries[4].north_sensor, Some([1.0, 0.0, 0.0]));
        assert_eq!(p.entries[5].kind, SegmentKind::Plateau);
        assert_eq!(p.entries[6].kind, SegmentKind::Static);
        assert_eq!(p.entries[6].north_sensor, None);
        assert_eq!(p.entries[0].line, Some(4));
        assert_eq!(p.entries[5].line, Some(15));
        assert!(
            (p.gravity_m_s2 - 9.80170).abs() < 1e-5,
            "{}",
            p.gravity_m_s2
        );
        assert!(!p.explicit_windows());
    }

    #[test]
    fn table_1_earth_rate_components() {
        // Position 5 of Table 1: spin (z) north, input1 (x) east, input2 (y) down: input2
        // sees -Omega sin L, the spin axis Omega cos L.
        let text = "format = \"imud-plan/1\"\nlatitude-deg = 40.0\n[[step]]\nkind = \"static\"\norientation = { z = \"north\", x = \"east\", y = \"down\" }\n";
        let p = Plan::from_toml_str(text, "t.toml").unwrap();
        let e = &p.entries[0];
        let (w, sd) = p.earth_rate(&e.up(), e.north_sensor.map(Vec3::from).as_ref());
        let l = 40f64.to_radians();
        let om = EARTH_RATE_RAD_S;
        assert!((w - Vec3::new(0.0, -om * l.sin(), om * l.cos())).norm() < 1e-15);
        assert_eq!(sd, [0.0; 3]);
        // Without north only the vertical part is known; the rest is uncertainty.
        let (w, sd) = p.earth_rate(&e.up(), None);
        assert!((w - Vec3::new(0.0, -om * l.sin(), 0.0)).norm() < 1e-15);
        assert_eq!(sd[1], 0.0);
        assert!((sd[0] - om * l.cos() / 2f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn bad_files_name_line_and_key() {
        let e = Plan::from_toml_str(&PLAN.replace("step-deg", "stepdeg"), "b.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("b.toml:7:"), "{e}");
        assert!(
            e.contains("unknown key `stepdeg` in [[step]] 1")
                && e.contains("did you mean `step-deg`"),
            "{e}"
        );
        let e = Plan::from_toml_str(&PLAN.replace("positions = 4\n", ""), "b.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("b.toml:4: step 1 (index-table)"), "{e}");
        assert!(e.contains("missing or zero `positions`"), "{e}");
        let e = Plan::from_toml_str(
            &PLAN.replace(
                "up = \"z\"\n\n[[step]]\nkind = \"static\"",
                "up = \"w\"\n\n[[step]]\nkind = \"static\"",
            ),
            "b.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("b.toml:9:") && e.contains("`w` is not a sensor axis"),
            "{e}"
        );
        let e = Plan::from_toml_str(
            &PLAN.replace("rates-deg-s", "positions = 3\nrates-deg-s"),
            "b.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("b.toml:18: step 3 (rate-steps)"), "{e}");
        assert!(e.contains("`positions` does not apply"), "{e}");
        let e = Plan::from_toml_str(
            &PLAN.replace("kind = \"static\"", "kind = \"statc\""),
            "b.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("b.toml:12:") && e.contains("statc"), "{e}");
        let e = Plan::from_toml_str(&PLAN.replace("kind = \"static\"\n", ""), "b.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing field `kind` in [[step]] 2"), "{e}");
        let e = Plan::from_toml_str(&PLAN.replace("latitude-deg", "latitude"), "b.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("b.toml:2:1: unknown key `latitude` at the top level"),
            "{e}"
        );
        assert!(e.contains("did you mean `latitude-deg`"), "{e}");
        let e = Plan::from_toml_str(&PLAN.replace("latitude-deg = 40.0\n", ""), "b.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("give latitude-deg"), "{e}");
        let e = Plan::from_toml_str(&PLAN.replace("format = \"imud-plan/1\"\n", ""), "b.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("format = \"imud-plan/1\""), "{e}");
        // A time range on one step only: all or none.
        let e = Plan::from_toml_str(
            &PLAN.replace(
                "orientation = {",
                "start-s = 1.0\nend-s = 5.0\norientation = {",
            ),
            "b.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("every step must"), "{e}");
    }

    #[test]
    fn a_skip_step_takes_no_keys_and_no_time_ranges() {
        let skip = PLAN.replace(
            "kind = \"static\"\norientation = { z = \"up\", x = \"north\" }",
            "kind = \"skip\"\nlabel = \"bumped\"",
        );
        let p = Plan::from_toml_str(&skip, "s.toml").unwrap();
        assert!(p.entries[4].skip);
        assert_eq!(p.entries[4].name(), "step 2 (line 11) [bumped: skip]");
        assert_eq!((p.count(SegmentKind::Static), p.count_skips()), (5, 1));
        assert_eq!(
            p.describe(),
            "test plan s.toml (8 segments: 5 static, 2 rate plateaus, 1 skipped)"
        );
        let e = Plan::from_toml_str(
            &skip.replace("label = \"bumped\"", "axis = \"x\""),
            "s.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("`axis` does not apply to a skip step (its keys: kind, label)"),
            "{e}"
        );
        let e = Plan::from_toml_str(
            &skip.replace(
                "positions = 4\n",
                "positions = 4\nwindows-s = [[0, 1], [2, 3], [4, 5], [6, 7]]\n",
            ),
            "s.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("a skip step matches a detected segment, but step 1 gives its time range"),
            "{e}"
        );
    }

    fn segment(kind: SegmentKind, t: f64, accel: [f64; 3], gyro: [f64; 3]) -> Segment {
        Segment {
            kind,
            start_s: t,
            end_s: t + 10.0,
            first_sample: 0,
            n: 1,
            mean_accel_m_s2: accel,
            mean_gyro_rad_s: gyro,
            std_accel_m_s2: [0.01; 3],
            std_gyro_rad_s: [0.01; 3],
        }
    }

    #[test]
    fn alignment_names_the_missing_and_the_wrong() {
        let p = Plan::from_toml_str(PLAN, "p.toml").unwrap();
        let g = 9.8;
        let w = 20f64.to_radians();
        use SegmentKind::*;
        let mut segs = vec![
            segment(Static, 0.0, [0.0, 0.0, g], [0.0; 3]),
            segment(Static, 20.0, [0.0, g, 0.0], [0.0; 3]),
            segment(Static, 40.0, [0.0, 0.0, -g], [0.0; 3]),
            segment(Static, 60.0, [0.0, -g, 0.0], [0.0; 3]),
            segment(Static, 80.0, [0.0, 0.0, g], [0.0; 3]),
            segment(Plateau, 100.0, [0.0, 0.0, g], [0.0, 0.0, w]),
            segment(Static, 120.0, [0.0, 0.0, g], [0.0; 3]),
            segment(Plateau, 140.0, [0.0, 0.0, g], [0.0, 0.0, -w]),
        ];
        assert_eq!(p.check(&segs, true).unwrap().len(), 8);
        // One index position missing from the recording: named where it happened.
        let mut missing = segs.clone();
        missing.remove(2);
        let e = p.check(&missing, true).unwrap_err().to_string();
        assert!(
            e.contains("expects 8 segments (6 static, 2 plateau), the recording has 7"),
            "{e}"
        );
        assert!(
            e.contains("step 1 (line 4) position 3 of 4") && e.contains("has no segment"),
            "{e}"
        );
        assert!(e.contains("after segment 2 (20.0-30.0 s)"), "{e}");
        assert_eq!(e.matches("\n  - ").count(), 1, "{e}");
        // Wrong direction of rotation of the table: the 90 deg position is measured at -y.
        segs[1].mean_accel_m_s2 = [0.0, -g, 0.0];
        let e = p.check(&segs, true).unwrap_err().to_string();
        assert!(e.contains("step 1 (line 4) position 2 of 4"), "{e}");
        assert!(
            e.contains("measured up -y is 180.0 deg from the planned +y"),
            "{e}"
        );
        // A plateau at the wrong rate.
        segs[1].mean_accel_m_s2 = [0.0, g, 0.0];
        segs[5].mean_gyro_rad_s = [0.0, 0.0, 1.5 * w];
        let e = p.check(&segs, true).unwrap_err().to_string();
        assert!(e.contains("step 3 (line 15) position 1 of 3"), "{e}");
        assert!(
            e.contains("measured 30.00 deg/s about +z, planned 20 deg/s"),
            "{e}"
        );
        // A skip step matches any one segment, even one the plan could not describe, and the
        // rest is matched as before: with the skip, all 8; without, the 7 others.
        let skip = PLAN.replace(
            "kind = \"static\"\norientation = { z = \"up\", x = \"north\" }",
            "kind = \"skip\"",
        );
        let ps = Plan::from_toml_str(&skip, "s.toml").unwrap();
        let mut odd = segs.clone();
        odd[5].mean_gyro_rad_s = [0.0, 0.0, w];
        odd[4].mean_accel_m_s2 = [g, 0.0, 0.0];
        let pairs = ps.check(&odd, true).unwrap();
        assert!(pairs.contains(&(4, 4)), "{pairs:?}");
        odd.remove(4);
        let rest = ps.check(&odd, false).unwrap();
        assert_eq!(rest.len(), 7);
        assert!(rest.iter().all(|(e, _)| !ps.entries[*e].skip));
        // A static where a plateau was planned.
        segs[5].mean_gyro_rad_s = [0.0; 3];
        segs[5].kind = Static;
        let e = p.check(&segs, true).unwrap_err().to_string();
        assert!(
            e.contains("expects a rate plateau but the segment is static"),
            "{e}"
        );
    }
}
