//! Reading a plan file: its TOML shape, errors that name the file, line, step and key, and the
//! expansion of each step into the segments it expects.

use super::*;

// ------------------------------------------------------------------------------- file shape

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub(super) struct PlanFile {
    pub(super) format: String,
    #[serde(default)]
    pub(super) name: Option<String>,
    #[serde(default)]
    pub(super) description: Option<String>,
    #[serde(default)]
    pub(super) latitude_deg: Option<f64>,
    #[serde(default)]
    pub(super) height_m: Option<f64>,
    #[serde(default)]
    pub(super) gravity_m_s2: Option<f64>,
    #[serde(default)]
    pub(super) powered_on_before_s: Option<f64>,
    #[serde(default)]
    pub(super) temp_c: Option<f64>,
    #[serde(default)]
    pub(super) direction_tolerance_deg: Option<f64>,
    #[serde(default)]
    pub(super) rate_tolerance_percent: Option<f64>,
    #[serde(rename = "step", default)]
    pub(super) steps: Vec<StepFile>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub(super) enum StepKind {
    Static,
    IndexTable,
    RateSteps,
    Skip,
}

impl StepKind {
    pub(super) fn name(self) -> &'static str {
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
pub(super) struct StepFile {
    pub(super) kind: StepKind,
    #[serde(default)]
    pub(super) label: Option<String>,
    #[serde(default)]
    pub(super) up: Option<SensorDirection>,
    #[serde(default)]
    pub(super) north: Option<SensorDirection>,
    #[serde(default)]
    pub(super) orientation: Option<OrientationFile>,
    #[serde(default)]
    pub(super) axis: Option<SensorDirection>,
    #[serde(default)]
    pub(super) step_deg: Option<f64>,
    #[serde(default)]
    pub(super) positions: Option<u32>,
    #[serde(default)]
    pub(super) start_deg: Option<f64>,
    #[serde(default)]
    pub(super) rates_deg_s: Option<Vec<f64>>,
    #[serde(default)]
    pub(super) start_s: Option<f64>,
    #[serde(default)]
    pub(super) end_s: Option<f64>,
    #[serde(default)]
    pub(super) windows_s: Option<Vec<[f64; 2]>>,
}

/// A compass or vertical direction of the local level frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub(super) enum Compass {
    North,
    South,
    East,
    West,
    Up,
    Down,
}

impl Compass {
    /// As a unit vector in East-North-Up.
    pub(super) fn enu(self) -> Vec3 {
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
pub(super) struct OrientationFile {
    #[serde(default)]
    pub(super) x: Option<Compass>,
    #[serde(default)]
    pub(super) y: Option<Compass>,
    #[serde(default)]
    pub(super) z: Option<Compass>,
}

/// A direction in sensor axes: `"x"`, `"-z"`, `"+y"` or a vector `[x, y, z]` (normalised).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SensorDirection(Vec3);

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

/// The `[[step]]` (1-based) a byte offset falls in, by counting the step headers up to the
/// end of its line (an error on a whole table points at its header).
pub(super) fn step_at(text: &str, offset: usize) -> Option<usize> {
    let offset = offset.min(text.len());
    let end = text[offset..].find('\n').map_or(text.len(), |i| offset + i);
    let before = text.get(..end).unwrap_or(text);
    let n = before
        .lines()
        .filter(|l| l.trim_start().starts_with("[[step]]"))
        .count();
    (n > 0).then_some(n)
}

pub(super) fn parse_error(file: &str, text: &str, e: &toml::de::Error) -> PlanError {
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
pub(super) fn keys_of(kind: StepKind) -> &'static [&'static str] {
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
    pub(super) fn present(&self) -> Vec<&'static str> {
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

    pub(super) fn has_windows(&self) -> bool {
        self.start_s.is_some() || self.end_s.is_some() || self.windows_s.is_some()
    }
}

/// Up and (optionally) north in sensor axes from a step's `up`/`north` or `orientation`.
pub(super) fn step_frame(s: &StepFile) -> Result<(Vec3, Option<Vec3>), String> {
    pub(super) const HOW: &str = "give `up = \"-z\"` (the sensor direction pointing up; a vector [x, y, z] \
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
pub(super) fn expand_step(
    file: &str,
    text: &str,
    i: usize,
    s: &StepFile,
    any_explicit: Option<usize>,
    entries: &mut Vec<PlanEntry>,
) -> Result<(), PlanError> {
    let step = StepExpansion {
        file,
        text,
        i,
        s,
        label: String::new(),
        up: Vec3::zeros(),
        north: None,
    };
    step.check_keys(any_explicit)?;
    // A skip step has no orientation: its entry matches any segment and is never checked.
    let (up, north) = if s.kind == StepKind::Skip {
        (Vec3::zeros(), None)
    } else {
        step_frame(s).map_err(|m| step.bad("up", m))?
    };
    let label = s
        .label
        .as_deref()
        .map(|l| format!("{l}: "))
        .unwrap_or_default();
    let step = StepExpansion {
        label,
        up,
        north,
        ..step
    };
    let base = step.base_entry();
    match s.kind {
        StepKind::Skip => entries.push(PlanEntry {
            skip: true,
            description: format!("{}skip", step.label),
            ..base
        }),
        StepKind::Static => entries.push(step.static_entry(base)?),
        StepKind::IndexTable => step.push_index_table(base, entries)?,
        StepKind::RateSteps => step.push_rate_steps(base, entries)?,
    }
    Ok(())
}

/// `up +z, north +x`, or `up +z` when north is not fixed.
fn frame_text(up: &Vec3, north: &Option<Vec3>) -> String {
    match north {
        Some(nv) => format!(
            "up {}, north {}",
            format_direction(up),
            format_direction(nv)
        ),
        None => format!("up {}", format_direction(up)),
    }
}

/// One plan step being expanded into entries: where it is, and its frame once read.
struct StepExpansion<'a> {
    /// The plan file's name, for messages.
    file: &'a str,
    /// The plan file's text, to find lines of keys.
    text: &'a str,
    /// 0-based index of the step.
    i: usize,
    /// The step as read.
    s: &'a StepFile,
    /// `label: ` prefix of descriptions (empty without a label).
    label: String,
    /// Sensor direction pointing up (zero for a skip step).
    up: Vec3,
    /// Sensor direction pointing north, when the step fixes it.
    north: Option<Vec3>,
}

impl StepExpansion<'_> {
    /// An error about key `k` of this step (at its line, else the step's line).
    fn bad(&self, k: &str, m: String) -> PlanError {
        let (i, text) = (self.i, self.text);
        PlanError::Invalid {
            file: self.file.to_string(),
            line: imu_model::line_of_key(text, &format!("step[{i}].{k}"))
                .or_else(|| imu_model::line_of_key(text, &format!("step[{i}]"))),
            context: format!("step {} ({})", i + 1, self.s.kind.name()),
            message: m,
        }
    }

    /// Checks that the step gives only keys of its kind, and that it agrees with the other
    /// steps on time ranges given by hand (`any_explicit`: the first step that gives one).
    fn check_keys(&self, any_explicit: Option<usize>) -> Result<(), PlanError> {
        let s = self.s;
        let allowed = keys_of(s.kind);
        for k in s.present() {
            if !allowed.contains(&k) {
                return Err(self.bad(
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
        if s.kind == StepKind::Skip
            && let Some(first) = any_explicit
        {
            return Err(self.bad(
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
            return Err(self.bad(
                "kind",
                format!(
                    "step {} gives its time range by hand, so every step must (start-s/end-s, or \
                     windows-s with one [start, end] per position or rate); detection is used only \
                     when no step gives one",
                    first + 1
                ),
            ));
        }
        Ok(())
    }

    /// The entry every entry of the step starts from: a static entry in the step's frame.
    fn base_entry(&self) -> PlanEntry {
        PlanEntry {
            step: self.i + 1,
            position: None,
            of: 1,
            line: imu_model::line_of_key(self.text, &format!("step[{}]", self.i)),
            kind: SegmentKind::Static,
            skip: false,
            description: String::new(),
            up_sensor: self.up.into(),
            north_sensor: self.north.map(Into::into),
            axis_sensor: None,
            rate_rad_s: 0.0,
            window_s: None,
        }
    }

    /// The `windows-s` of a step that expands to `count` segments (`None` each without it).
    fn windows(&self, count: usize) -> Result<Vec<Option<[f64; 2]>>, PlanError> {
        let Some(w) = &self.s.windows_s else {
            return Ok(vec![None; count]);
        };
        if w.len() != count {
            return Err(self.bad(
                "windows-s",
                format!(
                    "windows-s has {} [start, end] pairs, the step expands to {count} segments",
                    w.len()
                ),
            ));
        }
        if let Some(p) = w.iter().find(|p| !(p[0].is_finite() && p[1] > p[0])) {
            return Err(self.bad(
                "windows-s",
                format!("window {p:?} must have start < end (seconds)"),
            ));
        }
        Ok(w.iter().map(|p| Some(*p)).collect())
    }

    /// The table axis of the step; `what` gives examples for the message when it is missing.
    fn axis(&self, what: &str) -> Result<Vec3, PlanError> {
        self.s.axis.map(|a| a.0).ok_or_else(|| {
            self.bad(
                "axis",
                format!("missing `axis` (the table axis in sensor axes, e.g. {what})"),
            )
        })
    }

    /// The one entry of a static step, with its time range when given by hand.
    fn static_entry(&self, base: PlanEntry) -> Result<PlanEntry, PlanError> {
        let s = self.s;
        let window_s = match (s.start_s, s.end_s) {
            (None, None) => None,
            (Some(a), Some(b)) if a.is_finite() && b > a => Some([a, b]),
            (Some(_), Some(_)) => {
                return Err(self.bad("start-s", "start-s must be before end-s".into()));
            }
            _ => {
                return Err(self.bad(
                    "start-s",
                    "give both start-s and end-s (seconds from the recording's first \
                     sample), or neither"
                        .into(),
                ));
            }
        };
        Ok(PlanEntry {
            description: format!(
                "{}static, {}",
                self.label,
                frame_text(&self.up, &self.north)
            ),
            window_s,
            ..base
        })
    }

    /// Appends one static entry per position of an index-table step, the frame turned by
    /// each position's angle about the table axis.
    fn push_index_table(
        &self,
        base: PlanEntry,
        entries: &mut Vec<PlanEntry>,
    ) -> Result<(), PlanError> {
        let (s, label, up, north) = (self.s, &self.label, self.up, self.north);
        let axis = self.axis("\"x\" or \"-y\"")?;
        let step_deg = s.step_deg.filter(|x| x.is_finite()).ok_or_else(|| {
            self.bad(
                "step-deg",
                "missing `step-deg` (the angle between positions, degrees)".into(),
            )
        })?;
        let positions = s.positions.filter(|&p| p > 0).ok_or_else(|| {
            self.bad(
                "positions",
                "missing or zero `positions` (the number of table positions, 12 for a \
                 full turn in 30-degree steps)"
                    .into(),
            )
        })? as usize;
        let start_deg = s.start_deg.unwrap_or(0.0);
        let unit = Unit::new_normalize(axis);
        for (p, window_s) in self.windows(positions)?.into_iter().enumerate() {
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
        Ok(())
    }

    /// Appends one entry per rate of a rate-steps step: a plateau about the table axis, or
    /// a static entry with north unknown where the rate is 0.
    fn push_rate_steps(
        &self,
        base: PlanEntry,
        entries: &mut Vec<PlanEntry>,
    ) -> Result<(), PlanError> {
        let (label, up) = (&self.label, self.up);
        let axis = self.axis("\"z\"")?;
        let rates = self.s.rates_deg_s.clone().unwrap_or_default();
        if rates.is_empty() || rates.iter().any(|r| !r.is_finite()) {
            return Err(self.bad(
                "rates-deg-s",
                "missing or empty `rates-deg-s` (the plateau rates in order, deg/s; 0 for \
                 a stop)"
                    .into(),
            ));
        }
        let vertical = axis.dot(&up).abs() > 1f64.to_radians().cos();
        if !vertical && rates.contains(&0.0) {
            return Err(self.bad(
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
        for (p, (r, window_s)) in rates.iter().zip(self.windows(rates.len())?).enumerate() {
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
        Ok(())
    }
}
