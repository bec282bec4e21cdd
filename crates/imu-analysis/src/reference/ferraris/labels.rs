//! A labelled Ferraris session: parts (the `part`/`label` column) named like faces or turns say
//! which face the unit rests on or which axis it turns about, so the procedure takes its
//! segments from the labels instead of recognising them, and checks each against the data.
//!
//! The grammar of a part's name (ASCII letters in any case; `-`, `_` and spaces separate words;
//! a sign is `+` or `-`, before or after the axis; `p`/`n` after it also mean `+`/`-`, and so
//! do imucal's `p`/`a`, parallel and antiparallel):
//!
//! ```text
//! face = [ ("face" | "side" | "pos" | "position") sep ] signed-axis  |  axis sep ("p" | "a")
//! turn = ("turn" | "rot" | "rotation" | "spin") sep axis [ sign ]  |  ... sep sign axis
//!      | axis sep ("turn" | "rot" | "rotation" | "spin")
//! signed-axis = sign axis | axis sign          axis = "x" | "y" | "z"
//! sep = "" | one of "-", "_", " "
//! ```
//!
//! Examples: faces `+x`, `x-`, `face-x+`, `face_+z`, `pos -y`, `side zn`; turns `turn-z`,
//! `rot_x`, `rotation y`, `turn-z-` (a turn about z, in the negative sense), `spin_+x`. A turn's
//! sense is optional (the data gives it); when written it must agree. The part names of the
//! Python package imucal (`FerrarisCalibration`: `x_p` the x axis up, its accelerometer reading
//! +1 g, `x_a` down, `x_rot` the turn about x) are faces and turns too: its turns' sense is a
//! convention of that package (clockwise seen from above), so `x_rot` leaves it to the data.
//! A part named as no part of the procedure (an empty label, or one starting with `move`,
//! `moving`, `transition`, `rest`, `setup`, `idle`, `other` or `none`: `move 3`, `rest`) is not
//! used; any other name that does not parse (`x_q`, `acc_x_p`, `face-w`) beside names that do
//! is an error that names it, never silently left out. A label column none of whose names is a
//! face or a turn (`step 3`) is no Ferraris labelling: recognition finds the faces and turns. A face part's still stretches are its rests (its gravity
//! must be along the named axis, within the plan's face tolerance), a turn part's samples are
//! its turn (its integrated rate a full turn about the named axis); a mismatch is an error
//! naming the part.

use imu_model::Vec3;

use super::{Ferraris, FerrarisError, Turn, nearest_axis, noise_std};
use crate::ImuSeries;
use crate::segment::{Segment, SegmentKind, Segmentation};

/// What a part's name says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PartName {
    /// A rest on the face whose outward normal is the signed sensor axis pointing up.
    Face {
        /// Sensor axis, 0-2.
        axis: usize,
        /// +1 or -1.
        sign: f64,
    },
    /// A full turn about a sensor axis, in the sense given if any.
    Turn {
        /// Sensor axis, 0-2.
        axis: usize,
        /// +1, -1, or None when the name leaves it to the data.
        sign: Option<f64>,
    },
}

const FACE_WORDS: [&str; 4] = ["position", "face", "side", "pos"];
const TURN_WORDS: [&str; 4] = ["rotation", "turn", "spin", "rot"];
/// First words of parts that are deliberately no face and no turn.
const OTHER_WORDS: [&str; 8] = [
    "move",
    "moving",
    "transition",
    "rest",
    "setup",
    "idle",
    "other",
    "none",
];

/// True if `name` says its part is no part of the procedure (see the module's doc).
fn is_other_part(name: &str) -> bool {
    let lower = name.trim().to_ascii_lowercase();
    lower.is_empty()
        || OTHER_WORDS.iter().any(|w| {
            lower.strip_prefix(w).is_some_and(|rest| {
                rest.is_empty() || !rest.starts_with(|c: char| c.is_ascii_alphabetic())
            })
        })
}

/// The part `name` says (see the module's grammar), or None if it is no Ferraris part.
pub fn parse_part(name: &str) -> Option<PartName> {
    let lower = name.trim().to_ascii_lowercase();
    let strip = |words: &[&str]| {
        words.iter().find_map(|w| {
            let rest = lower.strip_prefix(w)?;
            Some(
                rest.strip_prefix(['-', '_', ' '])
                    .map_or(rest, |r| r)
                    .to_string(),
            )
        })
    };
    if let Some(rest) = strip(&TURN_WORDS) {
        let (axis, sign) = signed_axis(&rest)?;
        return Some(PartName::Turn { axis, sign });
    }
    // imucal's `x_rot`: the axis first.
    if let Some((axis, word)) = lower.split_at_checked(1)
        && let Some(axis) = "xyz".find(axis)
        && TURN_WORDS.contains(&word.strip_prefix(['-', '_', ' ']).unwrap_or(word))
    {
        return Some(PartName::Turn { axis, sign: None });
    }
    let rest = strip(&FACE_WORDS).unwrap_or(lower);
    let (axis, sign) = signed_axis(&rest)?;
    Some(PartName::Face { axis, sign: sign? })
}

/// `x`, `+x`, `x+`, `-x`, `x-`, `xp`, `xn`, imucal's `x_p`, `x_a`: the axis and the sign if
/// one is written.
fn signed_axis(s: &str) -> Option<(usize, Option<f64>)> {
    let sign_of = |c: char| match c {
        '+' | 'p' => Some(1.0),
        '-' | 'n' | 'a' => Some(-1.0),
        _ => None,
    };
    let axis_of = |c: char| "xyz".find(c);
    let chars: Vec<char> = s.chars().collect();
    match chars.as_slice() {
        [a] => Some((axis_of(*a)?, None)),
        [s, a] if *s == '+' || *s == '-' => Some((axis_of(*a)?, sign_of(*s))),
        [a, s] => Some((axis_of(*a)?, Some(sign_of(*s)?))),
        [a, '-' | '_' | ' ', s @ ('p' | 'a')] => Some((axis_of(*a)?, sign_of(*s))),
        _ => None,
    }
}

/// `+x` etc.
fn axis_name(axis: usize, sign: f64) -> String {
    format!(
        "{}{}",
        if sign < 0.0 { "-" } else { "+" },
        ["x", "y", "z"][axis]
    )
}

/// One run of samples under one label.
struct Part<'a> {
    name: &'a str,
    says: PartName,
    range: std::ops::Range<usize>,
}

/// The runs of `series`' labels that name a face or a turn, and those whose names neither
/// parse nor say they are no part (with their sample ranges).
fn parts(series: &ImuSeries) -> (Vec<Part<'_>>, Vec<(&str, std::ops::Range<usize>)>) {
    let Some(labels) = &series.labels else {
        return (Vec::new(), Vec::new());
    };
    let (mut out, mut unknown) = (Vec::new(), Vec::new());
    let mut start = 0;
    for i in 1..=labels.per_sample.len() {
        if i < labels.per_sample.len() && labels.per_sample[i] == labels.per_sample[start] {
            continue;
        }
        let name = labels.of(start);
        match parse_part(name) {
            Some(says) => out.push(Part {
                name,
                says,
                range: start..i,
            }),
            None if is_other_part(name) => {}
            None => unknown.push((name, start..i)),
        }
        start = i;
    }
    (out, unknown)
}

impl Ferraris {
    /// The segmentation of a labelled session (`detected`: the detection, whose segments never
    /// span two parts), or None when no part names a face or a turn. Faces are the still
    /// segments inside face parts, turns the turn parts whole; each checked against its label.
    pub(super) fn labelled_segmentation(
        &self,
        series: &ImuSeries,
        detected: &Segmentation,
    ) -> Result<Option<Segmentation>, FerrarisError> {
        let (parts, unknown) = parts(series);
        // A label column none of whose names is a face or a turn is no Ferraris labelling.
        if parts.is_empty() {
            return Ok(None);
        }
        if !unknown.is_empty() {
            let mut named: Vec<String> = Vec::new();
            for (name, r) in &unknown {
                let run = format!(
                    "`{name}` ({:.1}-{:.1} s)",
                    series.t_s[r.start],
                    series.t_s[r.end - 1]
                );
                if named.len() < 8 {
                    named.push(run);
                }
            }
            return Err(FerrarisError::UnknownParts {
                file: self.file.clone(),
                parts: named.join(", "),
                count: unknown.len(),
            });
        }

        let statics: Vec<Segment> = detected.of_kind(SegmentKind::Static).cloned().collect();
        let mut faces = Vec::new();
        for p in parts
            .iter()
            .filter(|p| matches!(p.says, PartName::Face { .. }))
        {
            let inside: Vec<Segment> = statics
                .iter()
                .filter(|s| p.range.contains(&s.first_sample))
                .cloned()
                .collect();
            if inside.is_empty() {
                return Err(self.label_error(series, p, "no still stretch in it".into()));
            }
            for s in &inside {
                self.check_face(series, p, s)?;
            }
            faces.extend(inside);
        }
        let rest = crate::segment::rest_rate(&faces);
        let mut segments = faces;
        for p in parts
            .iter()
            .filter(|p| matches!(p.says, PartName::Turn { .. }))
        {
            let mut turn = Segment::from_samples(series, p.range.clone(), SegmentKind::Plateau);
            self.check_turn(series, p, &turn, rest)?;
            turn.std_gyro_rad_s = noise_std(&series.gyro_rad_s[p.range.clone()]);
            turn.std_accel_m_s2 = noise_std(&series.accel_m_s2[p.range.clone()]);
            segments.push(turn);
        }
        segments.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
        Ok(Some(Segmentation {
            segments,
            ..detected.clone()
        }))
    }

    /// A still stretch of face part `p`: gravity along the named axis, within the tolerance.
    fn check_face(
        &self,
        series: &ImuSeries,
        p: &Part<'_>,
        s: &Segment,
    ) -> Result<(), FerrarisError> {
        let PartName::Face { axis, sign } = p.says else {
            unreachable!("a face part");
        };
        let (a, sg, angle_deg) = nearest_axis(s.mean_accel());
        let named = Vec3::from_fn(|i, _| if i == axis { sign } else { 0.0 });
        let off_deg = named.angle(&s.mean_accel()).to_degrees();
        if (a, sg) == (axis, sign) && angle_deg <= self.face_tolerance_deg {
            return Ok(());
        }
        Err(self.label_error(
            series,
            p,
            format!(
                "gravity says the face is {} ({angle_deg:.1} deg from it), {off_deg:.1} deg from \
                 {} (tolerance {} deg)",
                axis_name(a, sg),
                axis_name(axis, sign),
                self.face_tolerance_deg
            ),
        ))
    }

    /// Turn part `p`: a full turn about the named axis, in the named sense if one is named.
    fn check_turn(
        &self,
        series: &ImuSeries,
        p: &Part<'_>,
        turn: &Segment,
        rest: Vec3,
    ) -> Result<(), FerrarisError> {
        let PartName::Turn { axis, sign } = p.says else {
            unreachable!("a turn part");
        };
        let found = self.turn_of(series, turn, rest);
        if let Some(Turn { axis: a, sign: s }) = found
            && a == axis
            && sign.is_none_or(|want| want == s)
        {
            return Ok(());
        }
        let angle = (turn.mean_gyro() - rest) * super::span_s(series, turn);
        let (a, s, _) = nearest_axis(angle);
        Err(self.label_error(
            series,
            p,
            format!(
                "the integrated rate says {:.0} deg mostly about {} ({:.0} deg about it), not a \
                 full turn about {}",
                angle.norm().to_degrees(),
                axis_name(a, s),
                angle[a].abs().to_degrees(),
                match sign {
                    Some(want) => axis_name(axis, want),
                    None => ["x", "y", "z"][axis].to_string(),
                }
            ),
        ))
    }

    fn label_error(&self, series: &ImuSeries, p: &Part<'_>, message: String) -> FerrarisError {
        FerrarisError::Label {
            file: self.file.clone(),
            part: p.name.to_string(),
            start_s: series.t_s[p.range.start],
            end_s: series.t_s[p.range.end - 1],
            message,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grammar_of_faces_and_turns() {
        let face = |axis, sign| Some(PartName::Face { axis, sign });
        let turn = |axis, sign| Some(PartName::Turn { axis, sign });
        for (name, want) in [
            ("+x", face(0, 1.0)),
            ("x-", face(0, -1.0)),
            ("face-x+", face(0, 1.0)),
            ("Face_+Z", face(2, 1.0)),
            ("pos -y", face(1, -1.0)),
            ("side zn", face(2, -1.0)),
            ("position yp", face(1, 1.0)),
            ("turn-z", turn(2, None)),
            ("rot_x", turn(0, None)),
            ("rotation y", turn(1, None)),
            ("turn-z-", turn(2, Some(-1.0))),
            ("spin_+x", turn(0, Some(1.0))),
            ("turnz", turn(2, None)),
            ("turn--y", turn(1, Some(-1.0))),
            // imucal's parts: `p` up (+1 g on the axis), `a` down, `rot` the turn about it.
            ("x_p", face(0, 1.0)),
            ("x_a", face(0, -1.0)),
            ("Y_A", face(1, -1.0)),
            ("z p", face(2, 1.0)),
            ("x_rot", turn(0, None)),
            ("y-rotation", turn(1, None)),
            ("z_turn", turn(2, None)),
            ("xrot", turn(0, None)),
        ] {
            assert_eq!(parse_part(name), want, "{name}");
        }
        // Parts that say they are none, and names that are no part (an error, not ignored).
        for name in ["move", "move 3", "Rest", "transition_2", "", "setup-1"] {
            assert!(is_other_part(name), "{name}");
        }
        for name in ["x_q", "acc_x_p", "movement", "rested", "x"] {
            assert!(!is_other_part(name), "{name}");
        }
        // A bare axis has no sign: no face; words that are not the grammar's are no part.
        for name in [
            "x", "face-x", "rest", "move 3", "turn", "turn-w", "+x2", "setup", "", "x_q", "w_p",
            "x_rotx", "x__rot", "x__p",
        ] {
            assert_eq!(parse_part(name), None, "{name}");
        }
    }
}
