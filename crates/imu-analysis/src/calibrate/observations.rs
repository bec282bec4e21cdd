//! From a recording and a reference to fit points: segments detected or taken from a plan, each
//! segment's mean, standard error, conditions and true input; which gain effects need rate
//! plateaus.

use super::*;

pub(super) fn point(
    true_input: [f64; 3],
    mean: [f64; 3],
    std: [f64; 3],
    seg: &crate::segment::Segment,
    t: &SegmentTruth,
) -> FitPoint {
    // A floor on the standard error keeps a quantised, noiseless axis from taking all weight.
    let se = std.map(|s| (s / (seg.n as f64).sqrt()).max(1e-12));
    FitPoint {
        true_input: Vec3::from(true_input),
        measured: Vec3::from(mean),
        std_error: Vec3::from(se),
        conditions: Conditions {
            temp_c: t.temp_c,
            time_since_power_on_s: t.time_since_power_on_s,
            specific_force_m_s2: Vec3::from(t.specific_force_m_s2),
            angular_rate_rad_s: Vec3::from(t.angular_rate_rad_s),
            angular_accel_rad_s2: Vec3::zeros(),
        },
        t_s: 0.5 * (seg.start_s + seg.end_s),
        duration_s: seg.end_s - seg.start_s,
    }
}

/// A recording turned into fit observations: its segments, the true input of each, and the
/// accel and gyro points built from them.
#[derive(Clone, Debug)]
pub struct Observations {
    /// The detected segments and thresholds.
    pub segmentation: crate::segment::Segmentation,
    /// Truth per segment (parallel to `segmentation.segments`).
    pub segment_truth: Vec<SegmentTruth>,
    /// Accel points and the index of the segment each came from.
    pub accel: Vec<(usize, FitPoint)>,
    /// Gyro points (every segment) and their segment indices.
    pub gyro: Vec<(usize, FitPoint)>,
}

impl Observations {
    /// Detect segments in `series` (or take a plan's time ranges) and take the true input of
    /// each from `reference`. Accel
    /// points come from the static segments, plus, with `accel_on_plateaus`, from the rate
    /// plateaus whose accel is as steady as at rest (a table turning about the vertical: the
    /// centripetal term of a lever arm shows there); gyro points from every segment. A
    /// Ferraris turn is no such plateau (a hand's turn: its rate and the centripetal term vary
    /// through it, and its accel std is the sensor's noise, not the spread), so a Ferraris
    /// plan's accel comes from its rests alone, as imu-calibrate fits it.
    pub fn from_recording(
        series: &crate::ImuSeries,
        reference: &Reference,
        segment: &crate::segment::SegmentOptions,
        accel_on_plateaus: bool,
    ) -> Result<Observations, CalibrateError> {
        use crate::segment::SegmentKind;
        let accel_on_plateaus = accel_on_plateaus && !matches!(reference, Reference::Ferraris(_));
        let segmentation = reference.segmentation(series, segment)?;
        let segment_truth = reference.segment_truth(series, &segmentation.segments)?;
        // Steadiness bound for plateau accel: 3x the largest per-axis accel std at rest.
        let static_std = segmentation
            .of_kind(SegmentKind::Static)
            .flat_map(|s| s.std_accel_m_s2)
            .fold(0.0, f64::max);
        let segs = segmentation.segments.iter().zip(&segment_truth).enumerate();
        let accel = segs
            .clone()
            .filter(|(_, (s, _))| {
                s.kind == SegmentKind::Static
                    || (accel_on_plateaus
                        && s.std_accel_m_s2.iter().all(|v| *v <= 3.0 * static_std))
            })
            .map(|(i, (s, t))| {
                (
                    i,
                    point(
                        t.specific_force_m_s2,
                        s.mean_accel_m_s2,
                        s.std_accel_m_s2,
                        s,
                        t,
                    ),
                )
            })
            .collect();
        let gyro = segs
            .map(|(i, (s, t))| {
                (
                    i,
                    point(
                        t.angular_rate_rad_s,
                        s.mean_gyro_rad_s,
                        s.std_gyro_rad_s,
                        s,
                        t,
                    ),
                )
            })
            .collect();
        Ok(Observations {
            segmentation,
            segment_truth,
            accel,
            gyro,
        })
    }

    /// The points of one triad (accel or gyro).
    pub fn points(&self, triad: Triad) -> Vec<FitPoint> {
        let v = if triad == Triad::Gyro {
            &self.gyro
        } else {
            &self.accel
        };
        v.iter().map(|(_, p)| p.clone()).collect()
    }

    /// `model` without the gyro gain effects when the recording has no rate plateaus (Earth
    /// rate is too small to excite them), and the note saying so (None if nothing was held).
    pub fn gyro_model_for(&self, model: &TriadModel) -> (TriadModel, Option<crate::note::Note>) {
        use crate::segment::SegmentKind;
        gyro_model_with_plateaus(model, self.segmentation.count(SegmentKind::Plateau) > 0)
    }
}

/// `model` without the gyro gain effects unless some recording has rate plateaus, and the note
/// saying what was held.
pub(super) fn gyro_model_with_plateaus(
    model: &TriadModel,
    plateaus: bool,
) -> (TriadModel, Option<crate::note::Note>) {
    if plateaus {
        return (model.clone(), None);
    }
    // Gains: only a large input excites them, so they are held without rate plateaus.
    let held: Vec<EffectKind> = model.kinds().into_iter().filter(|k| k.is_gain()).collect();
    if held.is_empty() {
        return (model.clone(), None);
    }
    let mut m = model.clone();
    for k in &held {
        m.remove(*k);
    }
    (
        m,
        Some(crate::note::Note::GainsNeedPlateaus { effects: held }),
    )
}

/// Error unless the recordings together hold `needed` segments of `kind` (the first
/// recording's thresholds and hint say what is short).
pub(super) fn require_segments(
    obs: &[Observations],
    kind: crate::segment::SegmentKind,
    needed: usize,
    what: &str,
) -> Result<(), crate::segment::TooFewSegments> {
    let found: usize = obs.iter().map(|o| o.segmentation.count(kind)).sum();
    if found >= needed {
        return Ok(());
    }
    for o in obs {
        if let Err(mut e) = o.segmentation.require(kind, needed, what) {
            if obs.len() > 1 {
                e.found = found;
                e.what = format!("{what} (the {} recordings together)", obs.len());
            }
            return Err(e);
        }
    }
    Ok(())
}

/// The points of one triad from every recording, in order, with the session of each.
pub(super) fn joint_points(
    obs: &[Observations],
    triad: Triad,
    turn_on: Option<[f64; 3]>,
) -> (Vec<FitPoint>, Sessions) {
    let mut points = Vec::new();
    let mut of_point = Vec::new();
    for (i, o) in obs.iter().enumerate() {
        let p = o.points(triad);
        of_point.extend(std::iter::repeat_n(i, p.len()));
        points.extend(p);
    }
    (
        points,
        Sessions {
            of_point,
            turn_on_bias: turn_on,
        },
    )
}
