//! The Ferraris procedure as a reference (Ferraris et al. 1995, the calibration many labs do by
//! hand): the unit rests on each of its six faces in any order, and is turned once through a
//! full turn about each axis, with no table and no time windows. Each still face's true input
//! is gravity along the sensor axis that points up (recognised from the measured gravity); each
//! turn's is 360 degrees about the axis it turned about (recognised from the integrated rate,
//! after removing the gyro's reading at rest) over the turn's samples: the motion between two
//! rests, bounded by where the rate leaves and rejoins the rest's, so that a session cut into
//! parts and joined with no motion between them (another face's samples right after a turn's
//! last rest) still gives each turn its own samples only, and a turn at either end of it counts. Earth's rate enters with
//! its vertical part where the latitude is given; the part a heading would fix is carried as a
//! systematic gyro bias uncertainty, as for a plan without north. A labelled session (a
//! `part`/`label` column) whose parts are named like faces and turns (`+x`, `face-x+`,
//! `turn-z`, `rot_x`: the grammar is in `labels.rs`) takes its faces and turns from the labels
//! instead, each checked against what gravity and the rate say.

mod labels;
mod sign;

pub use labels::{PartName, parse_part};
pub use sign::{SignCheck, check_sign};

use imu_model::Vec3;
use imu_model::earth::{
    earth_rate_split_rad_s, normal_gravity_m_s2, unknown_heading_variance_rad2_s2,
};
use imu_model::units::STANDARD_GRAVITY_M_S2;

use super::segment_truth::recording_conditions;
use super::{ReferenceCaveats, SegmentTruth};
use crate::ImuSeries;
use crate::segment::{Segment, SegmentError, SegmentKind, SegmentOptions, Segmentation};

/// A turn is a full turn when its integrated angle is within this of 360 degrees.
const TURN_TOLERANCE_DEG: f64 = 60.0;
/// Share of a turn's integrated angle that must be about its main axis.
const TURN_AXIS_SHARE: f64 = 0.9;

/// The procedure's settings (a plan file with `procedure = "ferraris"`).
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Ferraris {
    /// The file it came from, for messages.
    #[serde(skip)]
    pub file: String,
    /// `imud-plan/1`.
    pub format: String,
    /// `ferraris`.
    pub procedure: String,
    /// Plan name, for reports.
    #[serde(default)]
    pub name: Option<String>,
    /// What the session is, for reports.
    #[serde(default)]
    pub description: Option<String>,
    /// Latitude, degrees: gives local gravity and the vertical part of Earth's rate.
    #[serde(default)]
    pub latitude_deg: Option<f64>,
    /// Local gravity, m/s^2 (default: WGS-84 normal gravity at the latitude, else standard).
    #[serde(default)]
    pub gravity_m_s2: Option<f64>,
    /// Largest angle between a still face's measured gravity and the nearest sensor axis, deg.
    #[serde(default = "default_face_tolerance_deg")]
    pub face_tolerance_deg: f64,
    /// Temperature when the recording has none, deg C.
    #[serde(default)]
    pub temp_c: Option<f64>,
}

fn default_face_tolerance_deg() -> f64 {
    15.0
}

/// Failures of the Ferraris procedure.
#[derive(Debug, thiserror::Error)]
pub enum FerrarisError {
    /// Segmentation failed.
    #[error(transparent)]
    Segment(#[from] SegmentError),
    /// A still face is not close to any sensor axis.
    #[error(
        "{file}: still segment at {start_s:.1}-{end_s:.1} s has gravity {angle_deg:.1} deg from \
         the nearest sensor axis (tolerance {tolerance_deg} deg): the Ferraris procedure rests \
         the unit on its faces (a box or cube whose faces are square to the sensor axes)"
    )]
    NotOnAFace {
        /// The plan file.
        file: String,
        /// Start of the segment, s.
        start_s: f64,
        /// End of the segment, s.
        end_s: f64,
        /// Angle to the nearest axis, degrees.
        angle_deg: f64,
        /// The tolerance, degrees.
        tolerance_deg: f64,
    },
    /// A labelled part does not show what its name says.
    #[error("{file}: part `{part}` ({start_s:.1}-{end_s:.1} s): {message}")]
    Label {
        /// The plan file.
        file: String,
        /// The part's label as written.
        part: String,
        /// Its first sample's time, s.
        start_s: f64,
        /// Its last sample's time, s.
        end_s: f64,
        /// What the data say instead.
        message: String,
    },
    /// Gravity says a gyro axis reports rotation the other way.
    #[error(
        "{file}: gravity says the gyro reports rotation the other way about {axes} (the \
         coefficient of its rate in the accelerometer's change; +1 agrees): its sign is flipped, \
         a negative gain, which a calibration does not hold. Negate that axis' scale when \
         reading it: for a text recording --csv-gyro counts:{per_axis} (S your counts' scale, \
         rad/s per count)"
    )]
    GyroSign {
        /// The plan file.
        file: String,
        /// The flipped axes with their coefficients.
        axes: String,
        /// The per-axis scales that fix it (`S,S,-S`).
        per_axis: String,
    },
    /// Labelled parts whose names are neither a face, a turn, nor a part that says it is none.
    #[error(
        "{file}: {count} labelled part(s) name no face and no turn: {parts}; name faces like \
         `+x`, `face-x-` or imucal's `x_p`/`x_a`, turns like `turn-z` or `z_rot`, and parts \
         that are neither `move` or `rest` (the grammar: reference/ferraris/labels.rs)"
    )]
    UnknownParts {
        /// The plan file.
        file: String,
        /// The first of them, each with its time span.
        parts: String,
        /// How many runs of samples carry such a label.
        count: usize,
    },
    /// A rotating segment given to [`Ferraris::segment_truth`] is not a full turn about one
    /// axis (segments must come from [`Ferraris::segmentation`]).
    #[error(
        "{file}: segment at {start_s:.1}-{end_s:.1} s is not a full turn about one sensor axis"
    )]
    NotATurn {
        /// The plan file.
        file: String,
        /// Start of the segment, s.
        start_s: f64,
        /// End of the segment, s.
        end_s: f64,
    },
}

/// The sensor axis (0-2) and sign nearest to `v`, and the angle to it, degrees.
fn nearest_axis(v: Vec3) -> (usize, f64, f64) {
    let a = v.iamax();
    let sign = v[a].signum();
    let angle_deg = (v[a].abs() / v.norm()).clamp(-1.0, 1.0).acos().to_degrees();
    (a, sign, angle_deg)
}

/// A full turn found between two still faces.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Turn {
    axis: usize,
    sign: f64,
}

impl Ferraris {
    /// The procedure from a plan file's text, or None if the file is not a Ferraris plan (or
    /// not valid TOML: the plan reader then reports it).
    pub fn from_toml_str(text: &str, file: &str) -> Option<Result<Ferraris, String>> {
        let value: toml::Table = text.parse().ok()?;
        if value.get("procedure").and_then(|p| p.as_str()) != Some("ferraris") {
            return None;
        }
        Some(
            toml::from_str::<Ferraris>(text)
                .map(|f| Ferraris {
                    file: file.to_string(),
                    ..f
                })
                .map_err(|e| format!("{file}: {}", e.message())),
        )
    }

    /// Local gravity, m/s^2.
    pub fn gravity_m_s2(&self) -> f64 {
        self.gravity_m_s2.unwrap_or_else(|| {
            self.latitude_deg
                .map_or(STANDARD_GRAVITY_M_S2, |l| normal_gravity_m_s2(l, 0.0))
        })
    }

    /// The still faces (as detected) and one segment per full turn (the motion between two
    /// still faces, or before the first or after the last, from its first to its last moving
    /// sample with a little rest around it, kind [`SegmentKind::Plateau`]), in time order.
    /// Detected rate plateaus inside a turn are replaced by the turn; quiet runs are reported as
    /// detection reports them. A session labelled with faces and turns (module `labels`) takes
    /// them from its labels.
    pub fn segmentation(
        &self,
        series: &ImuSeries,
        opts: &SegmentOptions,
    ) -> Result<Segmentation, FerrarisError> {
        let detected = crate::segment::detect(series, opts)?;
        let seg = match self.labelled_segmentation(series, &detected)? {
            Some(labelled) => labelled,
            None => self.recognised_segmentation(series, detected)?,
        };
        self.check_gyro_sign(series, &seg)?;
        Ok(seg)
    }

    /// Refuses a gyro whose sign gravity says is flipped on some axis (module `sign`): the
    /// turns' sense would be taken from it and every rotation calibrated backwards.
    fn check_gyro_sign(&self, series: &ImuSeries, seg: &Segmentation) -> Result<(), FerrarisError> {
        let statics: Vec<Segment> = seg.of_kind(SegmentKind::Static).cloned().collect();
        let mut moving = Vec::new();
        let mut from = 0;
        for s in &statics {
            moving.push(from..s.first_sample);
            from = s.range().end;
        }
        moving.push(from..series.len());
        let check = check_sign(
            series,
            &moving,
            crate::segment::rest_rate(&statics),
            accel_offset(&statics),
        );
        let flipped = check.flipped();
        if flipped.is_empty() {
            return Ok(());
        }
        let axes = flipped
            .iter()
            .map(|&a| {
                let (k, se) = check.coefficient[a].unwrap_or((f64::NAN, f64::NAN));
                format!("{} ({k:+.2} +/- {se:.2})", ["x", "y", "z"][a])
            })
            .collect::<Vec<_>>()
            .join(", ");
        let per_axis = if flipped.len() == 3 {
            "-S".to_string()
        } else {
            (0..3)
                .map(|a| if flipped.contains(&a) { "-S" } else { "S" })
                .collect::<Vec<_>>()
                .join(",")
        };
        Err(FerrarisError::GyroSign {
            file: self.file.clone(),
            axes,
            per_axis,
        })
    }

    /// [`Ferraris::segmentation`] by recognition: faces from gravity, turns from the rate.
    fn recognised_segmentation(
        &self,
        series: &ImuSeries,
        mut seg: Segmentation,
    ) -> Result<Segmentation, FerrarisError> {
        let statics: Vec<Segment> = seg.of_kind(SegmentKind::Static).cloned().collect();
        for s in &statics {
            let (_, _, angle_deg) = nearest_axis(s.mean_accel());
            if angle_deg > self.face_tolerance_deg {
                return Err(FerrarisError::NotOnAFace {
                    file: self.file.clone(),
                    start_s: s.start_s,
                    end_s: s.end_s,
                    angle_deg,
                    tolerance_deg: self.face_tolerance_deg,
                });
            }
        }
        let rest = crate::segment::rest_rate(&statics);
        let noise = rest_noise_rad_s(&statics);
        let mut segments = statics.clone();
        // Between two rests, and before the first and after the last (a session cut into
        // parts may start or end with a turn whose rest after it is too short to be one).
        let mut bounds: Vec<usize> = vec![0];
        for s in &statics {
            bounds.extend([s.first_sample, s.range().end]);
        }
        bounds.push(series.len());
        for pair in bounds.chunks(2) {
            let window = pair[0]..pair[1];
            // The turn is the motion in the window, not the window: parts concatenated with no
            // motion between them put another face's samples beside it, whose gravity is not
            // the turn's.
            let Some(motion) = motion_extent(series, window, rest, noise) else {
                continue;
            };
            let mut turn = Segment::from_samples(series, motion.clone(), SegmentKind::Plateau);
            if self.turn_of(series, &turn, rest).is_some() {
                // The rate varies through a turn by hand: the error of its mean is the sensor's
                // noise, not the spread of the rate (which would make the turn worthless).
                turn.std_gyro_rad_s = noise_std(&series.gyro_rad_s[motion.clone()]);
                turn.std_accel_m_s2 = noise_std(&series.accel_m_s2[motion]);
                segments.push(turn);
            }
        }
        segments.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
        seg.segments = segments;
        Ok(seg)
    }

    /// The full turn `s` is, if it is one: its integrated angle (rate minus the reading at
    /// rest `rest`) within [`TURN_TOLERANCE_DEG`] of 360 degrees, [`TURN_AXIS_SHARE`] of it
    /// about one sensor axis.
    fn turn_of(&self, series: &ImuSeries, s: &Segment, rest: Vec3) -> Option<Turn> {
        let duration_s = span_s(series, s);
        let angle = (s.mean_gyro() - rest) * duration_s;
        let (axis, sign, _) = nearest_axis(angle);
        let full = (angle.norm().to_degrees() - 360.0).abs() <= TURN_TOLERANCE_DEG;
        let about_one_axis = angle[axis].abs() >= TURN_AXIS_SHARE * angle.norm();
        (full && about_one_axis).then_some(Turn { axis, sign })
    }

    /// The true input of each of `segments` (from [`Ferraris::segmentation`]).
    pub fn segment_truth(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<Vec<SegmentTruth>, FerrarisError> {
        let g = self.gravity_m_s2();
        let statics: Vec<Segment> = segments
            .iter()
            .filter(|s| s.kind == SegmentKind::Static)
            .cloned()
            .collect();
        let rest = crate::segment::rest_rate(&statics);
        let up_before = |s: &Segment| {
            statics
                .iter()
                .rev()
                .find(|f| f.start_s < s.start_s)
                .or(statics.first())
                .map_or(Vec3::z(), face_up)
        };
        segments
            .iter()
            .map(|s| {
                let (temp_c, time_since_power_on_s) =
                    recording_conditions(series, s, self.temp_c, 0.0);
                let (force, rate) = match s.kind {
                    SegmentKind::Static => {
                        let up = face_up(s);
                        (up * g, up * self.vertical_earth_rate_rad_s())
                    }
                    SegmentKind::Plateau => {
                        let up = up_before(s);
                        let turn = self.turn_of(series, s, rest).ok_or_else(|| {
                            FerrarisError::NotATurn {
                                file: self.file.clone(),
                                start_s: s.start_s,
                                end_s: s.end_s,
                            }
                        })?;
                        let mut axis = Vec3::zeros();
                        axis[turn.axis] = turn.sign;
                        // Over a full turn only Earth's rate along the turn axis stays; its
                        // vertical part is known when the axis is the up axis.
                        let earth = axis * axis.dot(&up) * self.vertical_earth_rate_rad_s();
                        // Gravity along the turn axis stays; across it, it averages out.
                        let force = axis * axis.dot(&up) * g;
                        (
                            force,
                            axis * (std::f64::consts::TAU / span_s(series, s)) + earth,
                        )
                    }
                };
                Ok(SegmentTruth {
                    specific_force_m_s2: force.into(),
                    angular_rate_rad_s: rate.into(),
                    temp_c,
                    time_since_power_on_s,
                })
            })
            .collect()
    }

    /// Earth's vertical rate at the latitude (0 without one: then all of it is unknown).
    fn vertical_earth_rate_rad_s(&self) -> f64 {
        self.latitude_deg
            .map_or(0.0, |l| earth_rate_split_rad_s(l).0)
    }

    /// What the procedure leaves unknown (Earth's rate a heading would fix) and notes.
    pub fn caveats(&self, segments: &[Segment]) -> ReferenceCaveats {
        use crate::note::Note;
        let faces: Vec<String> = segments
            .iter()
            .filter(|s| s.kind == SegmentKind::Static)
            .map(|s| crate::reference::direction::format_direction(&face_up(s)))
            .collect();
        let mut distinct = faces.clone();
        distinct.sort();
        distinct.dedup();
        let turns = segments
            .iter()
            .filter(|s| s.kind == SegmentKind::Plateau)
            .count();
        let seen = distinct.len();
        let mut notes = vec![Note::FerrarisSummary {
            file: self.file.clone(),
            faces: faces.len(),
            distinct,
            turns,
            gravity_m_s2: self.gravity_m_s2(),
        }];
        if seen < 6 {
            notes.push(Note::MissingFaces { seen });
        }
        if turns < 3 {
            notes.push(Note::TooFewTurns { turns });
        }
        // Each axis is up on some face and horizontal on others: the worst case is horizontal.
        let std = unknown_heading_variance_rad2_s2(self.latitude_deg, 0.0).sqrt();
        if self.latitude_deg.is_none() {
            notes.push(Note::NoLatitude);
        }
        ReferenceCaveats {
            gyro_bias_std_rad_s: Some([std; 3]),
            notes,
        }
    }

    /// One-line description.
    pub fn describe(&self) -> String {
        format!(
            "Ferraris procedure {} (six faces and a full turn about each axis)",
            self.name.as_deref().unwrap_or(&self.file)
        )
    }
}

/// The accelerometer's offset, m/s^2: the mean of the six faces' mean readings, in which
/// gravity cancels (zero unless all six faces were seen).
fn accel_offset(statics: &[Segment]) -> Vec3 {
    let mut faces: Vec<(Vec3, Vec3, usize)> = Vec::new();
    for s in statics {
        let up = face_up(s);
        match faces.iter_mut().find(|(u, _, _)| *u == up) {
            Some((_, sum, n)) => {
                *sum += s.mean_accel();
                *n += 1;
            }
            None => faces.push((up, s.mean_accel(), 1)),
        }
    }
    if faces.len() < 6 {
        return Vec3::zeros();
    }
    faces
        .iter()
        .map(|(_, sum, n)| sum / *n as f64)
        .sum::<Vec3>()
        / 6.0
}

/// The sensor axis pointing up on the still face `s`, as a signed unit vector.
fn face_up(s: &Segment) -> Vec3 {
    let (axis, sign, _) = nearest_axis(s.mean_accel());
    let mut up = Vec3::zeros();
    up[axis] = sign;
    up
}

/// The time the samples of `s` span, s: one sample interval per sample.
fn span_s(series: &ImuSeries, s: &Segment) -> f64 {
    let r = s.range();
    let dt = (series.t_s[r.end - 1] - series.t_s[r.start]) / (r.len() - 1).max(1) as f64;
    dt * r.len() as f64
}

/// The gyro's noise at rest, rad/s: the root of the summed per-axis variances, the
/// sample-weighted mean over `statics` (0 without any).
fn rest_noise_rad_s(statics: &[Segment]) -> f64 {
    let (sum, n) = statics.iter().fold((0.0, 0usize), |(sum, n), s| {
        let var: f64 = s.std_gyro_rad_s.iter().map(|x| x * x).sum();
        (sum + var * s.n as f64, n + s.n)
    });
    (sum / n.max(1) as f64).sqrt()
}

/// Samples of smoothing (each side) of the rate whose excess over the rest finds a motion, s.
const MOTION_SMOOTH_S: f64 = 0.025;
/// Samples kept before and after a motion's first and last moving sample, s: the rate there is
/// within a few noise sigmas of the rest, so the angle it adds is below the noise's.
const MOTION_PAD_S: f64 = 0.1;

/// The samples of `window` from its first to its last moving one (the rate, smoothed over
/// [`MOTION_SMOOTH_S`], more than 5 noise sigmas from `rest`), widened by [`MOTION_PAD_S`] at
/// each end within the window; None if nothing moves in it.
fn motion_extent(
    series: &ImuSeries,
    window: std::ops::Range<usize>,
    rest: Vec3,
    noise_rad_s: f64,
) -> Option<std::ops::Range<usize>> {
    if window.len() < 2 {
        return None;
    }
    let rate_hz = series.sample_rate_hz();
    let h = ((MOTION_SMOOTH_S * rate_hz).round() as usize).max(1);
    let pad = (MOTION_PAD_S * rate_hz).round() as usize;
    let threshold = 5.0 * noise_rad_s / ((2 * h + 1) as f64).sqrt();
    let excess: Vec<Vec3> = series.gyro_rad_s[window.clone()]
        .iter()
        .map(|g| Vec3::from(*g) - rest)
        .collect();
    let moving = |k: usize| {
        let lo = k.saturating_sub(h);
        let hi = (k + h + 1).min(excess.len());
        let mean = excess[lo..hi].iter().sum::<Vec3>() / (hi - lo) as f64;
        mean.norm() > threshold
    };
    let first = (0..excess.len()).find(|&k| moving(k))?;
    let last = (0..excess.len()).rev().find(|&k| moving(k))?;
    Some(
        window.start + first.saturating_sub(pad)..window.start + (last + pad + 1).min(excess.len()),
    )
}

/// Per-axis standard deviation of the white noise of a smoothly varying signal, from its second
/// differences (`x[k+1] - 2 x[k] + x[k-1]` has variance `6 sigma^2` for white noise, and a motion
/// smooth over a few samples contributes little).
fn noise_std(x: &[[f64; 3]]) -> [f64; 3] {
    let n = x.len().saturating_sub(2).max(1) as f64;
    std::array::from_fn(|a| {
        let sum_sq: f64 = x
            .windows(3)
            .map(|w| (w[2][a] - 2.0 * w[1][a] + w[0][a]).powi(2))
            .sum();
        (sum_sq / (6.0 * n)).sqrt()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan() -> Ferraris {
        Ferraris::from_toml_str(
            "format = \"imud-plan/1\"\nprocedure = \"ferraris\"\nlatitude-deg = 40.0\n",
            "f.toml",
        )
        .unwrap()
        .unwrap()
    }

    /// `n` samples at 100 Hz of a constant specific force and rate.
    fn series(n: usize, accel: [f64; 3], gyro: [f64; 3]) -> ImuSeries {
        ImuSeries {
            t_s: (0..n).map(|k| k as f64 / 100.0).collect(),
            accel_m_s2: vec![accel; n],
            gyro_rad_s: vec![gyro; n],
            origin: "synthetic".into(),
            ..ImuSeries::default()
        }
    }

    #[test]
    fn a_turn_is_true_to_360_degrees_and_a_part_turn_is_refused() {
        let g = [0.0, 0.0, 9.8];
        // 4 s at 90 deg/s about z: one full turn, its truth 2 pi over the samples' span.
        let mut turn = series(500, g, [0.0, 0.0, 90f64.to_radians()]);
        turn.gyro_rad_s[..100].fill([0.0; 3]);
        let rest = Segment::from_samples(&turn, 0..100, SegmentKind::Static);
        let spin = Segment::from_samples(&turn, 100..500, SegmentKind::Plateau);
        let truth = plan().segment_truth(&turn, &[rest.clone(), spin]).unwrap();
        let w = truth[1].angular_rate_rad_s;
        assert!((w[2] - std::f64::consts::TAU / 4.0).abs() < 1e-4, "{w:?}");
        assert!(w[0] == 0.0 && w[1] == 0.0, "{w:?}");
        // 1 s of it is a quarter turn: an error, never a guessed axis.
        let part = Segment::from_samples(&turn, 100..200, SegmentKind::Plateau);
        let e = plan()
            .segment_truth(&turn, &[rest, part])
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a full turn"), "{e}");
    }
}
