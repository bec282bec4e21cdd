//! Notes on a result (what a fit assumed, decided or left out) as typed values: programs match
//! on the variant or its stable [`Note::code`]; the English sentence is the `Display`, produced
//! only when a report or `--json` is written.

use imu_model::units::{EARTH_RATE_RAD_S, STANDARD_GRAVITY_M_S2};
use imu_model::{EffectKind, Triad};
use imu_stats::lsq::Unobservable;
use serde::Serialize;
use std::fmt;

use crate::segment::{DroppedRun, SegmentOptions, SkippedSegment};

/// Where the local gravity of a gravity-magnitude fit comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GravitySource {
    /// Given by the user.
    Given,
    /// WGS-84 normal gravity at this latitude (deg), height 0.
    Latitude(f64),
    /// Standard gravity (no gravity and no latitude given).
    Standard,
}

/// What is said of the assumed temperature of a recording without temperature readings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TempAssumed {
    /// A reference log: the reference temperature.
    Log,
    /// A plan that sets `temp-c`.
    PlanTempC,
    /// A plan without `temp-c`: the reference temperature.
    PlanDefault,
}

/// One note on a fit or a reference. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub enum Note {
    /// A note on one of several recordings fitted together (1-based `number`).
    InRecording {
        /// 1-based position among the recordings.
        number: usize,
        /// The recording's origin (file).
        origin: String,
        /// The note.
        note: Box<Note>,
    },
    /// The gyro's reading at rest is not negligible: static and plateau segments are told
    /// apart relative to it.
    GyroRestRate {
        /// The reading at rest, deg/s.
        rest_deg_s: [f64; 3],
    },
    /// Quiet runs that did not become segments.
    QuietRunsDropped {
        /// Quiet intervals seen (segments, skipped and dropped).
        seen: usize,
        /// Segments used.
        used: usize,
        /// The runs dropped.
        dropped: Vec<DroppedRun>,
        /// The detection settings (for the durations the runs fell short of).
        options: Box<SegmentOptions>,
    },
    /// No rate plateaus: the gyro gains are not fitted.
    GainsNeedPlateaus {
        /// The gain effects left out.
        effects: Vec<EffectKind>,
    },
    /// Reference-free workbench: the gyro gains come from the moves, not the still poses.
    GainsFromMoves {
        /// The gain effects.
        effects: Vec<EffectKind>,
    },
    /// A detected segment a plan step skipped.
    SegmentSkipped(SkippedSegment),
    /// What a joint fit of several recordings assumes of their biases.
    JointBiases {
        /// Recordings fitted together.
        recordings: usize,
        /// Accel turn-on bias repeatability, m/s^2 (None: the same bias in all).
        accel_turn_on_m_s2: Option<[f64; 3]>,
        /// Gyro turn-on bias repeatability, rad/s (None: the same bias in all).
        gyro_turn_on_rad_s: Option<[f64; 3]>,
    },
    /// The gravity a plan uses.
    PlanGravity {
        /// The plan file.
        file: String,
        /// How the plan's gravity was found.
        gravity_source: String,
    },
    /// Earth's rate is not fully known in some segments of a plan: carried as gyro bias
    /// uncertainty.
    EarthRateUnknown {
        /// Segments where it is not known.
        unknown: usize,
        /// Segments.
        segments: usize,
        /// The largest unknown rate per axis, rad/s.
        max_std_rad_s: [f64; 3],
        /// How far a g-sensitivity can be off beyond its standard error, (rad/s)/(m/s^2).
        g_sensitivity_bound_rad_s_per_m_s2: f64,
    },
    /// The recording has no temperature readings.
    NoTemperature {
        /// The temperature assumed, deg C.
        assumed_c: f64,
        /// Where it comes from.
        source: TempAssumed,
    },
    /// How a reference log's clock was aligned to the recording's.
    LogClock {
        /// The log file.
        file: String,
        /// Log clock minus recording clock, s.
        offset_s: f64,
        /// The correlation of the rate magnitudes, when the offset was found (None: given).
        correlation: Option<f64>,
    },
    /// A rate table's log: its axis and where the specific force comes from.
    TableAxes {
        /// The log file.
        file: String,
        /// The table axis per direction line: (line, direction).
        axes: Vec<(usize, [f64; 3])>,
        /// How the table's gravity was found; None when the log gives the specific force.
        gravity_source: Option<String>,
    },
    /// How Earth's rate enters a rate table's log.
    TableEarthRate {
        /// The latitude, deg (None: not given).
        latitude_deg: Option<f64>,
    },
    /// What a Ferraris procedure saw.
    FerrarisSummary {
        /// The procedure file.
        file: String,
        /// Still faces.
        faces: usize,
        /// The distinct faces, by their up direction.
        distinct: Vec<String>,
        /// Full turns.
        turns: usize,
        /// Local gravity, m/s^2.
        gravity_m_s2: f64,
    },
    /// Fewer than six faces were seen.
    MissingFaces {
        /// Distinct faces seen.
        seen: usize,
    },
    /// Fewer than three full turns were found.
    TooFewTurns {
        /// Full turns found.
        turns: usize,
    },
    /// No latitude: all of Earth's rate is carried as gyro bias uncertainty.
    NoLatitude,
    /// The local gravity of a gravity-magnitude fit.
    LocalGravity {
        /// Gravity, m/s^2.
        g_m_s2: f64,
        /// Where it comes from.
        source: GravitySource,
    },
    /// Rate plateaus are not used by the reference-free procedure.
    PlateausIgnored {
        /// Plateaus found.
        count: usize,
    },
    /// The accel fit started from the ellipsoid through the poses.
    AccelStartEllipsoid {
        /// The ellipsoid's offset, m/s^2.
        offset_m_s2: [f64; 3],
        /// Its scale error.
        scale_error: [f64; 3],
    },
    /// The rotation gauge of the gravity-magnitude fit.
    Gauge,
    /// How Earth's rate enters the reference-free gyro bias.
    GyroBiasEarthRate {
        /// The latitude, deg (None: not given).
        latitude_deg: Option<f64>,
    },
    /// Gyro offsets that vary along a move are evaluated at every sample of it.
    MoveOffsetsVary {
        /// The varying offset effects.
        effects: Vec<EffectKind>,
    },
    /// Moves skipped for lost samples.
    MovesSkipped {
        /// Moves skipped.
        count: usize,
    },
    /// Gyro temperature and warm-up effects are fitted only as far as the recording excites
    /// them.
    FittedAsExcited {
        /// The effects.
        effects: Vec<EffectKind>,
    },
    /// How the reference-free gyro gains are found.
    GyroGainsMethod,
    /// A parameter held out of a fit.
    NotFitted {
        /// Triad.
        triad: Triad,
        /// The parameter and why.
        unobservable: Unobservable,
    },
    /// A parameter held when the workbench refitted a model imud would reject.
    RefitHeld {
        /// Triad.
        triad: Triad,
        /// The parameter and why.
        unobservable: Unobservable,
    },
    /// The workbench's refit of a model imud would reject failed.
    RefitFailed {
        /// Triad.
        triad: Triad,
        /// The fit's error message.
        error: String,
    },
    /// The reference-free calibration of the ladder's final model failed.
    FinalCalibrationFailed {
        /// The calibration's error message.
        error: String,
    },
    /// The workbench holds the accel against the gravity magnitude.
    AccelMagnitude,
    /// How the workbench counts Earth's rate at the still poses.
    EarthRateAtPoses {
        /// The latitude, deg (None: not given).
        latitude_deg: Option<f64>,
    },
    /// The workbench holds the gyro gains against the moves.
    GyroMoves,
}

impl Note {
    /// The stable code (snake case), for programs; a note on one of several recordings has
    /// the code of the note.
    pub fn code(&self) -> &'static str {
        match self {
            Note::InRecording { note, .. } => note.code(),
            Note::GyroRestRate { .. } => "gyro_rest_rate",
            Note::QuietRunsDropped { .. } => "quiet_runs_dropped",
            Note::GainsNeedPlateaus { .. } => "gains_need_plateaus",
            Note::GainsFromMoves { .. } => "gains_from_moves",
            Note::SegmentSkipped(_) => "segment_skipped",
            Note::JointBiases { .. } => "joint_biases",
            Note::PlanGravity { .. } => "plan_gravity",
            Note::EarthRateUnknown { .. } => "earth_rate_unknown",
            Note::NoTemperature { .. } => "no_temperature",
            Note::LogClock { .. } => "log_clock",
            Note::TableAxes { .. } => "table_axes",
            Note::TableEarthRate { .. } => "table_earth_rate",
            Note::FerrarisSummary { .. } => "ferraris_summary",
            Note::MissingFaces { .. } => "missing_faces",
            Note::TooFewTurns { .. } => "too_few_turns",
            Note::NoLatitude => "no_latitude",
            Note::LocalGravity { .. } => "local_gravity",
            Note::PlateausIgnored { .. } => "plateaus_ignored",
            Note::AccelStartEllipsoid { .. } => "accel_start_ellipsoid",
            Note::Gauge => "gauge",
            Note::GyroBiasEarthRate { .. } => "gyro_bias_earth_rate",
            Note::MoveOffsetsVary { .. } => "move_offsets_vary",
            Note::MovesSkipped { .. } => "moves_skipped",
            Note::FittedAsExcited { .. } => "fitted_as_excited",
            Note::GyroGainsMethod => "gyro_gains_method",
            Note::NotFitted { .. } => "not_fitted",
            Note::RefitHeld { .. } => "refit_held",
            Note::RefitFailed { .. } => "refit_failed",
            Note::FinalCalibrationFailed { .. } => "final_calibration_failed",
            Note::AccelMagnitude => "accel_magnitude",
            Note::EarthRateAtPoses { .. } => "earth_rate_at_poses",
            Note::GyroMoves => "gyro_moves",
        }
    }

    /// This note as one of several recordings' (1-based `number`, its `origin`).
    pub fn in_recording(self, number: usize, origin: &str) -> Note {
        Note::InRecording {
            number,
            origin: origin.to_string(),
            note: Box::new(self),
        }
    }
}

/// `[a, b, c]` with `{:.1e}` each.
fn e1(v: &[f64; 3]) -> String {
    format!("[{:.1e}, {:.1e}, {:.1e}]", v[0], v[1], v[2])
}

/// The effects' ids, comma separated.
fn ids(effects: &[EffectKind]) -> String {
    effects
        .iter()
        .map(|k| k.id())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The joint fit's assumption on one triad's bias.
fn joint_bias(name: &str, unit: &str, n: usize, turn_on: Option<[f64; 3]>) -> String {
    match turn_on {
        None => format!(
            "the {name} bias is taken as the same in all {n} recordings (no change between \
             power-ons)"
        ),
        Some(b) => format!(
            "the {name} bias is the mean over the {n} power-ons, each recording's own bias \
             allowed to differ from it by {} {unit} (1 sigma, turn-on repeatability)",
            e1(&b)
        ),
    }
}

impl fmt::Display for Note {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Note::InRecording {
                number,
                origin,
                note,
            } => write!(f, "recording {number} ({origin}): {note}"),
            Note::GyroRestRate { rest_deg_s: d } => write!(
                f,
                "the gyro reads [{:.2}, {:.2}, {:.2}] deg/s at rest (estimated from the still \
                 segments): static and plateau segments are told apart relative to it",
                d[0], d[1], d[2]
            ),
            Note::QuietRunsDropped {
                seen,
                used,
                dropped,
                options,
            } => write!(
                f,
                "{seen} quiet interval(s) seen, {used} used, {} dropped: {}",
                dropped.len(),
                dropped
                    .iter()
                    .map(|d| d.describe(options))
                    .collect::<Vec<_>>()
                    .join("; ")
            ),
            Note::GainsNeedPlateaus { effects } => write!(
                f,
                "no rate plateaus found: gyro {} not fitted (Earth rate cannot excite them; \
                 record a rate-table run)",
                ids(effects)
            ),
            Note::GainsFromMoves { effects } => write!(
                f,
                "gyro {} come from the moves between poses (imu-calibrate --reference-free), not \
                 from the still poses held against the model here",
                ids(effects)
            ),
            Note::SegmentSkipped(k) => {
                write!(f, "{} skipped by {}: not fitted", k.describe(), k.by)
            }
            Note::JointBiases {
                recordings: n,
                accel_turn_on_m_s2: a,
                gyro_turn_on_rad_s: g,
            } => {
                write!(
                    f,
                    "{n} recordings fitted together: {}; {}; bias wander is independent between \
                     recordings",
                    joint_bias("accel", "m/s^2", *n, *a),
                    joint_bias("gyro", "rad/s", *n, *g)
                )?;
                if a.is_none() || g.is_none() {
                    write!(
                        f,
                        "; a MEMS bias usually changes from one power-on to the next: give its \
                         turn-on repeatability (imu-calibrate --accel-turn-on-bias-m-s2, \
                         --gyro-turn-on-bias-rad-s) to fit the mean bias with that spread"
                    )?;
                }
                Ok(())
            }
            Note::PlanGravity {
                file,
                gravity_source,
            } => write!(f, "plan {file}: gravity {gravity_source}"),
            Note::EarthRateUnknown {
                unknown,
                segments,
                max_std_rad_s: sd,
                g_sensitivity_bound_rad_s_per_m_s2: bound,
            } => write!(
                f,
                "Earth's rate is not fully known in {unknown} of {segments} segments (no north \
                 in the plan, a table stopped at an unlogged angle, no latitude, or a plateau's \
                 partial turn): up to [{:.1e}, {:.1e}, {:.1e}] rad/s per axis, carried as a \
                 systematic gyro bias uncertainty; a g-sensitivity fitted from these segments \
                 can be off by up to {bound:.1e} (rad/s)/(m/s^2) more than its standard error \
                 says (give north in the plan where it matters)",
                sd[0], sd[1], sd[2],
            ),
            Note::NoTemperature { assumed_c, source } => {
                write!(
                    f,
                    "the recording has no temperature readings: {assumed_c} deg C assumed"
                )?;
                f.write_str(match source {
                    TempAssumed::Log => "; temperature effects cannot be fitted",
                    TempAssumed::PlanTempC => " (plan temp-c)",
                    TempAssumed::PlanDefault => {
                        " (give temp-c in the plan); temperature effects cannot be fitted"
                    }
                })
            }
            Note::LogClock {
                file,
                offset_s,
                correlation,
            } => match correlation {
                Some(r) => write!(
                    f,
                    "reference log {file}: log clock = recording clock {offset_s:+.3} s (found \
                     by cross-correlating rate magnitudes, correlation {r:.3})"
                ),
                None => write!(
                    f,
                    "reference log {file}: log clock = recording clock {offset_s:+.3} s (given)"
                ),
            },
            Note::TableAxes {
                file,
                axes,
                gravity_source,
            } => {
                let axes: Vec<String> = axes
                    .iter()
                    .map(|(line, a)| {
                        format!(
                            "{} from line {line}",
                            crate::reference::direction::format_direction(&(*a).into())
                        )
                    })
                    .collect();
                write!(
                    f,
                    "reference log {file}: a rate table's rate about its axis ({}); ",
                    axes.join(", ")
                )?;
                match gravity_source {
                    None => f.write_str("specific force from the log"),
                    Some(g) => write!(
                        f,
                        "the table axis is taken as vertical: specific force {g} along it, \
                         pointing up the way the measured accel says"
                    ),
                }
            }
            Note::TableEarthRate { latitude_deg } => match latitude_deg {
                Some(lat) => write!(
                    f,
                    "Earth's rate: its vertical part at latitude {lat} deg is added to the \
                     table's rate; the horizontal part, which the log cannot know, is carried \
                     as gyro bias uncertainty"
                ),
                None => f.write_str(
                    "Earth's rate is not in a table's log and no `# latitude-deg` is given: all \
                     of it (7.3e-5 rad/s) is carried as gyro bias uncertainty",
                ),
            },
            Note::FerrarisSummary {
                file,
                faces,
                distinct,
                turns,
                gravity_m_s2,
            } => write!(
                f,
                "Ferraris procedure ({file}): {faces} still faces ({} distinct: {}) and {turns} \
                 full turn(s); local gravity {gravity_m_s2:.6} m/s^2",
                distinct.len(),
                distinct.join(", "),
            ),
            Note::MissingFaces { seen } => write!(
                f,
                "only {seen} of the six faces were seen: rest the unit on every face"
            ),
            Note::TooFewTurns { turns } => write!(
                f,
                "{turns} full turn(s) found (one about each axis is needed for the gyro scale \
                 and misalignment): turn the unit once through 360 deg about each axis between \
                 two still rests"
            ),
            Note::NoLatitude => write!(
                f,
                "no latitude: Earth's rate ({EARTH_RATE_RAD_S:.3e} rad/s) is carried as a gyro \
                 bias uncertainty"
            ),
            Note::LocalGravity { g_m_s2: g, source } => match source {
                GravitySource::Given => write!(f, "local gravity {g:.6} m/s^2 (given)"),
                GravitySource::Latitude(lat) => write!(
                    f,
                    "local gravity {g:.6} m/s^2: WGS-84 normal gravity at latitude {lat} deg, \
                     height 0 (about -3.1e-6 m/s^2 per metre above the ellipsoid)"
                ),
                GravitySource::Standard => write!(
                    f,
                    "local gravity {STANDARD_GRAVITY_M_S2} m/s^2 (standard; give --gravity-m-s2 \
                     or --latitude-deg: gravity varies by 0.5 % over the Earth, and every accel \
                     scale factor absorbs the relative error of g)"
                ),
            },
            Note::PlateausIgnored { count } => write!(
                f,
                "{count} rate plateau(s) ignored: this procedure uses still poses and the moves \
                 between them"
            ),
            Note::AccelStartEllipsoid {
                offset_m_s2: b,
                scale_error: s,
            } => write!(
                f,
                "accel fit started from the ellipsoid through the poses: offset [{:.4}, {:.4}, \
                 {:.4}] m/s^2, scale error [{:.4}, {:.4}, {:.4}]",
                b[0], b[1], b[2], s[0], s[1], s[2]
            ),
            Note::Gauge => f.write_str(
                "gauge: accel misalignment xy, xz, yz held at 0 (the gravity magnitude cannot \
                 see a rotation of the whole frame): the accelerometer axes define the body \
                 frame (accel x = body x, accel y in the body x-y plane) and the gyro is \
                 calibrated into that frame",
            ),
            Note::GyroBiasEarthRate { latitude_deg } => match latitude_deg {
                Some(lat) => write!(
                    f,
                    "gyro bias: Earth's vertical rate at latitude {lat} deg removed at each pose; \
                     the horizontal part ({:.1e} rad/s, direction unknown without a heading) is \
                     carried in the bias standard errors",
                    imu_model::earth::earth_rate_split_rad_s(*lat).1
                ),
                None => write!(
                    f,
                    "gyro bias: Earth's rate (up to {EARTH_RATE_RAD_S:.2e} rad/s, unknown in the \
                     sensor frame without latitude and heading) is carried in the bias standard \
                     errors; give --latitude-deg to remove its vertical part"
                ),
            },
            Note::MoveOffsetsVary { effects } => write!(
                f,
                "gyro gains: the {} fitted to the still poses is evaluated at every sample of \
                 each move (specific force, temperature, time) and removed from the rate beyond \
                 its interpolation between the poses",
                ids(effects)
            ),
            Note::MovesSkipped { count } => write!(
                f,
                "{count} move(s) skipped: lost samples (the rate over a gap is unknown)"
            ),
            Note::FittedAsExcited { effects } => write!(
                f,
                "gyro {}: fitted only as far as this recording's temperatures and times excite \
                 them",
                ids(effects)
            ),
            Note::GyroGainsMethod => f.write_str(
                "gyro gains: the rate is corrected by the interpolated rate of the still poses \
                 around each move and integrated over straight-line-fitted sample times; the \
                 accel fit's own uncertainty is not propagated into them",
            ),
            Note::NotFitted {
                triad,
                unobservable: u,
            } => write!(f, "{triad} {} not fitted: {}", u.name, u.reason),
            Note::RefitHeld {
                triad,
                unobservable: u,
            } => write!(f, "{triad} {}: {}", u.name, u.reason),
            Note::RefitFailed { triad, error } => write!(f, "{triad}: {error}"),
            Note::FinalCalibrationFailed { error } => write!(
                f,
                "the reference-free calibration of the final model failed ({error}): the \
                 calibration holds the workbench's accel and gyro offset fits and the base \
                 model's gyro gains as given"
            ),
            Note::AccelMagnitude => f.write_str(
                "accel: held against the gravity magnitude at each still pose; misalignment xy, \
                 xz, yz held at 0 (the magnitude cannot see a rotation of the whole frame: the \
                 accelerometer axes define the frame)",
            ),
            Note::EarthRateAtPoses { latitude_deg } => match latitude_deg {
                Some(lat) => write!(
                    f,
                    "gyro: Earth's vertical rate at latitude {lat} deg is the true rate along the \
                     calibrated up direction of each pose; its horizontal part ({:.1e} rad/s, \
                     heading unknown) is counted as noise of each pose mean",
                    imu_model::earth::earth_rate_split_rad_s(*lat).1
                ),
                None => write!(
                    f,
                    "gyro: Earth's rate ({EARTH_RATE_RAD_S:.2e} rad/s, unknown in the sensor \
                     frame without latitude and heading) is counted as noise of each pose mean; \
                     give the latitude to remove its vertical part"
                ),
            },
            Note::GyroMoves => f.write_str(
                "gyro gains (scale, misalignment, asymmetry, nonlinearity, temperature scale) are \
                 held against the rotations integrated over the moves between poses, the gyro \
                 offsets against the still poses",
            ),
        }
    }
}

/// A note serializes as its sentence (the `notes` of `--json` are as they were).
impl Serialize for Note {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

/// A result's notes. Flattened into a result's JSON as `"notes"` (the sentences) and
/// `"note_codes"` (each note's [`Note::code`], in the same order).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Notes(pub Vec<Note>);

impl Notes {
    /// The codes, in order.
    pub fn codes(&self) -> Vec<&'static str> {
        self.0.iter().map(Note::code).collect()
    }

    /// Whether a note has this code.
    pub fn has(&self, code: &str) -> bool {
        self.0.iter().any(|n| n.code() == code)
    }

    /// The sentences, in order (for reports).
    pub fn sentences(&self) -> Vec<String> {
        self.0.iter().map(ToString::to_string).collect()
    }
}

impl std::ops::Deref for Notes {
    type Target = Vec<Note>;
    fn deref(&self) -> &Vec<Note> {
        &self.0
    }
}

impl std::ops::DerefMut for Notes {
    fn deref_mut(&mut self) -> &mut Vec<Note> {
        &mut self.0
    }
}

impl From<Vec<Note>> for Notes {
    fn from(v: Vec<Note>) -> Notes {
        Notes(v)
    }
}

impl FromIterator<Note> for Notes {
    fn from_iter<I: IntoIterator<Item = Note>>(iter: I) -> Notes {
        Notes(iter.into_iter().collect())
    }
}

impl IntoIterator for Notes {
    type Item = Note;
    type IntoIter = std::vec::IntoIter<Note>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter()
    }
}

impl<'a> IntoIterator for &'a Notes {
    type Item = &'a Note;
    type IntoIter = std::slice::Iter<'a, Note>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

/// `{"notes": [sentence...], "note_codes": [code...]}`: use with `#[serde(flatten)]`.
impl Serialize for Notes {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut s = serializer.serialize_struct("Notes", 2)?;
        s.serialize_field("notes", &self.0)?;
        s.serialize_field("note_codes", &self.codes())?;
        s.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notes_flatten_to_sentences_and_codes_in_order() {
        #[derive(Serialize)]
        struct Fit {
            n: u32,
            #[serde(flatten)]
            notes: Notes,
        }
        let fit = Fit {
            n: 1,
            notes: Notes(vec![
                Note::Gauge,
                Note::MovesSkipped { count: 2 }.in_recording(2, "b.mcap"),
            ]),
        };
        let v = serde_json::to_value(&fit).unwrap();
        assert_eq!(v["n"], 1);
        assert_eq!(
            v["note_codes"],
            serde_json::json!(["gauge", "moves_skipped"])
        );
        assert_eq!(
            v["notes"][1],
            "recording 2 (b.mcap): 2 move(s) skipped: lost samples (the rate over a gap is \
             unknown)"
        );
        assert_eq!(v["notes"][0], Note::Gauge.to_string());
    }

    /// One note of every kind but `SegmentSkipped` (which needs a detected segment).
    fn one_of_each() -> Vec<Note> {
        let held = Unobservable {
            name: "bias.x".into(),
            reason: imu_stats::lsq::NotFitted::ZeroJacobian,
        };
        vec![
            Note::GyroRestRate {
                rest_deg_s: [1.0, 2.0, 3.0],
            },
            Note::QuietRunsDropped {
                seen: 3,
                used: 2,
                dropped: Vec::new(),
                options: Box::default(),
            },
            Note::GainsNeedPlateaus {
                effects: vec![EffectKind::Scale],
            },
            Note::GainsFromMoves {
                effects: vec![EffectKind::Scale],
            },
            Note::JointBiases {
                recordings: 2,
                accel_turn_on_m_s2: None,
                gyro_turn_on_rad_s: None,
            },
            Note::PlanGravity {
                file: "p.toml".into(),
                gravity_source: "9.8 m/s^2 (given)".into(),
            },
            Note::EarthRateUnknown {
                unknown: 1,
                segments: 2,
                max_std_rad_s: [1e-5; 3],
                g_sensitivity_bound_rad_s_per_m_s2: 1e-6,
            },
            Note::NoTemperature {
                assumed_c: 25.0,
                source: TempAssumed::Log,
            },
            Note::LogClock {
                file: "l.csv".into(),
                offset_s: 0.5,
                correlation: None,
            },
            Note::TableAxes {
                file: "l.csv".into(),
                axes: vec![(4, [0.0, 0.0, 1.0])],
                gravity_source: None,
            },
            Note::TableEarthRate { latitude_deg: None },
            Note::FerrarisSummary {
                file: "f.toml".into(),
                faces: 6,
                distinct: vec!["+x".into()],
                turns: 3,
                gravity_m_s2: 9.8,
            },
            Note::MissingFaces { seen: 5 },
            Note::TooFewTurns { turns: 2 },
            Note::NoLatitude,
            Note::LocalGravity {
                g_m_s2: 9.8,
                source: GravitySource::Standard,
            },
            Note::PlateausIgnored { count: 1 },
            Note::AccelStartEllipsoid {
                offset_m_s2: [0.0; 3],
                scale_error: [0.0; 3],
            },
            Note::Gauge,
            Note::GyroBiasEarthRate {
                latitude_deg: Some(40.0),
            },
            Note::MoveOffsetsVary {
                effects: vec![EffectKind::GSensitivity],
            },
            Note::MovesSkipped { count: 1 },
            Note::FittedAsExcited {
                effects: vec![EffectKind::TempBias],
            },
            Note::GyroGainsMethod,
            Note::NotFitted {
                triad: Triad::Accel,
                unobservable: held.clone(),
            },
            Note::RefitHeld {
                triad: Triad::Gyro,
                unobservable: held,
            },
            Note::RefitFailed {
                triad: Triad::Gyro,
                error: "no points".into(),
            },
            Note::FinalCalibrationFailed {
                error: "too few poses".into(),
            },
            Note::AccelMagnitude,
            Note::EarthRateAtPoses {
                latitude_deg: Some(40.0),
            },
            Note::GyroMoves,
        ]
    }

    #[test]
    fn every_kind_of_note_has_its_own_code_and_a_sentence() {
        let notes = one_of_each();
        let mut codes: Vec<&str> = notes.iter().map(Note::code).collect();
        codes.push(
            Note::SegmentSkipped(SkippedSegment {
                number: 1,
                by: String::new(),
                segment: crate::segment::Segment {
                    kind: crate::segment::SegmentKind::Static,
                    start_s: 0.0,
                    end_s: 1.0,
                    first_sample: 0,
                    n: 1,
                    mean_accel_m_s2: [0.0; 3],
                    mean_gyro_rad_s: [0.0; 3],
                    std_accel_m_s2: [0.0; 3],
                    std_gyro_rad_s: [0.0; 3],
                },
            })
            .code(),
        );
        let n = codes.len();
        codes.sort_unstable();
        codes.dedup();
        assert_eq!(codes.len(), n, "a code used twice: {codes:?}");
        for note in &notes {
            let code = note.code();
            assert!(
                !code.is_empty() && code.bytes().all(|b| b.is_ascii_lowercase() || b == b'_'),
                "{code}"
            );
            assert!(note.to_string().len() > 10, "{code}: {note}");
            // A note on one of several recordings keeps its code.
            assert_eq!(note.clone().in_recording(2, "b.mcap").code(), code);
        }
    }

    #[test]
    fn a_joint_fit_without_turn_on_repeatability_says_how_to_give_it() {
        let n = Note::JointBiases {
            recordings: 2,
            accel_turn_on_m_s2: Some([0.01, 0.02, 0.03]),
            gyro_turn_on_rad_s: None,
        };
        let s = n.to_string();
        assert!(s.starts_with(
            "2 recordings fitted together: the accel bias is the mean over the 2 power-ons, \
             each recording's own bias allowed to differ from it by [1.0e-2, 2.0e-2, 3.0e-2] \
             m/s^2"
        ));
        assert!(s.ends_with("to fit the mean bias with that spread"));
        assert_eq!(n.code(), "joint_biases");
    }
}
