//! Calibration fits: from recordings and their references (a test plan, a reference log or the
//! simulator's truth) to a calibration file imud loads.
//!
//! - `observations.rs`: segments -> fit points (true input, measured mean, standard error).
//! - `covariance.rs`: the segment means' shared bias wander and the per-recording sessions.
//! - `triad_fit.rs`: the weighted fit of one triad on the `imu_stats::lsq` engine, standard
//!   errors, unobservable parameters, the loadable-model refit.
//! - `reference_free/`: calibration from hand-held still poses without a reference.
//! - this file: `calibrate` and `calibrate_recordings`, which put them together for one or
//!   several recordings.

use imu_model::nalgebra::{DMatrix, DVector};
use imu_model::{Conditions, EffectKind, Triad, TriadModel, Vec3};
use imu_stats::lsq::{
    LsqOptions, Residuals, covariance, find_unobservable, jacobian, minimize, refit_holding,
};

pub use crate::reference::{Reference, ReferenceError, SegmentTruth};

mod covariance;
mod observations;
pub mod reference_free;
mod triad_fit;
mod warning;

pub use covariance::*;
pub use observations::*;
pub use triad_fit::*;
pub use warning::{Evidence, FitWarning, FitWarningKind, WarningScope, Warnings};

/// What [`calibrate`] fits and how.
#[derive(Clone, Debug)]
pub struct CalibrateOptions {
    /// Accel model to fit (its effects and starting values).
    pub accel: TriadModel,
    /// Gyro model to fit.
    pub gyro: TriadModel,
    /// Segmentation settings.
    pub segment: crate::segment::SegmentOptions,
    /// Fit settings (the `fixed` mask is ignored here, and `mean_noise` is set from the models'
    /// noise and the drift below unless it gives shared noise).
    pub fit: FitOptions,
    /// Accel bias wander over the recording (m/s^2), see [`MeanNoise::White`].
    pub accel_bias_drift_m_s2: Option<[f64; 3]>,
    /// Gyro bias wander over the recording (rad/s), see [`MeanNoise::White`].
    pub gyro_bias_drift_rad_s: Option<[f64; 3]>,
    /// Accel noise for the weights of the segment means, see [`FitOptions::noise`].
    pub accel_noise: Option<imu_model::NoiseModel>,
    /// Gyro noise for the weights of the segment means, see [`FitOptions::noise`].
    pub gyro_noise: Option<imu_model::NoiseModel>,
    /// Accel turn-on to turn-on bias repeatability (m/s^2, 1 sigma per axis), see
    /// [`Sessions::turn_on_bias`]; None: the bias is common to all recordings.
    pub accel_turn_on_bias_m_s2: Option<[f64; 3]>,
    /// Gyro turn-on to turn-on bias repeatability (rad/s, 1 sigma per axis).
    pub gyro_turn_on_bias_rad_s: Option<[f64; 3]>,
}

impl CalibrateOptions {
    /// The defaults, with what a model file gives (`imu-calibrate --model`, `imud.calibrate`):
    /// the effects of each triad that lists any, and, from the file's noise tables (a noise
    /// characterisation such as imu-noise's), the bias wander over a recording of `duration_s`
    /// that no residual can show and the noise that weighs the segment means.
    pub fn from_model(model: &imu_model::Calibration, duration_s: f64) -> Self {
        let mut opts = CalibrateOptions::default();
        if !model.accel.kinds().is_empty() {
            opts.accel = model.accel.effects_only();
        }
        if !model.gyro.kinds().is_empty() {
            opts.gyro = model.gyro.effects_only();
        }
        let drift = |t: &TriadModel| {
            t.noise
                .as_ref()
                .map(|n| bias_drift_from_noise(n, duration_s))
        };
        opts.accel_bias_drift_m_s2 = drift(&model.accel);
        opts.gyro_bias_drift_rad_s = drift(&model.gyro);
        opts.accel_noise = model.accel.noise.clone();
        opts.gyro_noise = model.gyro.noise.clone();
        opts
    }
}

impl Default for CalibrateOptions {
    /// Accel and gyro: bias + scale + misalignment.
    fn default() -> Self {
        let accel = TriadModel::with_effects(&TriadModel::PAPER_BASE);
        CalibrateOptions {
            gyro: accel.clone(),
            accel,
            segment: Default::default(),
            fit: FitOptions::default(),
            accel_bias_drift_m_s2: None,
            gyro_bias_drift_rad_s: None,
            accel_noise: None,
            gyro_noise: None,
            accel_turn_on_bias_m_s2: None,
            gyro_turn_on_bias_rad_s: None,
        }
    }
}

/// One recording's part in a [`calibrate_recordings`] fit.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RecordingFit {
    /// Where the data came from ([`crate::ImuSeries::origin`]).
    pub origin: String,
    /// The reference it was fitted against (one line).
    pub reference: String,
    /// The segments fitted and the detection thresholds.
    pub segmentation: crate::segment::Segmentation,
    /// Truth per segment (parallel to `segmentation.segments`).
    pub segment_truth: Vec<SegmentTruth>,
    /// This recording's accel points: their rows in the accel fit's `residuals`.
    pub accel_points: std::ops::Range<usize>,
    /// This recording's gyro points: their rows in the gyro fit's `residuals`.
    pub gyro_points: std::ops::Range<usize>,
}

/// Result of [`calibrate`] and [`calibrate_recordings`].
#[derive(Clone, Debug, serde::Serialize)]
pub struct CalibrationFit {
    /// The first recording's segments and thresholds (as in `recordings[0]`: the field of
    /// one-recording fits, kept for the scripts that read it).
    pub segmentation: crate::segment::Segmentation,
    /// The first recording's truth per segment (as in `recordings[0]`).
    pub segment_truth: Vec<SegmentTruth>,
    /// Each recording fitted, in the order given.
    pub recordings: Vec<RecordingFit>,
    /// The accel fit (static segments).
    pub accel: FitResult,
    /// The gyro fit (static segments and rate plateaus).
    pub gyro: FitResult,
    /// The fitted calibration (accel and gyro; no provenance yet).
    #[serde(skip)]
    pub calibration: imu_model::Calibration,
    /// Decisions taken (held parameters, ...); `--json` has the sentences (`notes`) and codes
    /// (`note_codes`).
    #[serde(flatten)]
    pub notes: crate::note::Notes,
}

impl CalibrationFit {
    /// Number of fitted segments of one kind over all recordings.
    pub fn count(&self, kind: crate::segment::SegmentKind) -> usize {
        self.recordings
            .iter()
            .map(|r| r.segmentation.count(kind))
            .sum()
    }
}

/// Failures of [`calibrate`].
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// Segmentation failed.
    #[error(transparent)]
    Segment(#[from] crate::segment::SegmentError),
    /// Too few segments.
    #[error(transparent)]
    TooFew(#[from] crate::segment::TooFewSegments),
    /// Reference alignment failed.
    #[error(transparent)]
    Reference(#[from] ReferenceError),
    /// A fit failed.
    #[error(transparent)]
    Fit(#[from] FitError),
    /// No recording was given.
    #[error("no recording to calibrate")]
    NoRecording,
    /// One of several recordings could not be used.
    #[error("recording {number} ({origin})")]
    Recording {
        /// 1-based position among the recordings.
        number: usize,
        /// Where its data came from.
        origin: String,
        /// Why.
        #[source]
        source: Box<CalibrateError>,
    },
    /// The fitted model cannot be inverted over the validation range, so imud would reject it.
    #[error("the fitted {triad} model is not valid at `{key}`: {message}; fit fewer effects")]
    InvalidModel {
        /// Triad.
        triad: Triad,
        /// The offending key.
        key: String,
        /// What validation said.
        message: String,
    },
}
/// Detect segments in `series` (or take them from `reference`: a plan's time ranges), take the
/// true input of each from `reference` (its unknown part widens the gyro bias errors), and fit
/// the accel model to the static segments and the gyro model to the static segments and rate
/// plateaus. Without plateaus the gyro gain effects (scale, misalignment, asymmetry,
/// nonlinearity) are left out of the gyro fit (a note says so): Earth rate is too small to
/// excite them.
pub fn calibrate(
    series: &crate::ImuSeries,
    reference: &Reference,
    opts: &CalibrateOptions,
) -> Result<CalibrationFit, CalibrateError> {
    calibrate_recordings(&[(series, reference)], opts)
}

/// [`calibrate`] over several recordings of one unit, each with its own reference (e.g. an
/// index-table run and a rate-table run): one accel and one gyro model fitted to the segments
/// of all of them. Each recording keeps its own conditions (temperature, time since power-on);
/// the bias wander of different recordings is independent (zero covariance between them, see
/// [`session_covariance`]); the gyro gains are held only when no recording has rate plateaus.
/// The biases are common to the recordings unless a turn-on repeatability is given
/// ([`CalibrateOptions::accel_turn_on_bias_m_s2`]); a note says which. Errors name the
/// recording when there are several.
pub fn calibrate_recordings(
    recordings: &[(&crate::ImuSeries, &Reference)],
    opts: &CalibrateOptions,
) -> Result<CalibrationFit, CalibrateError> {
    use crate::segment::SegmentKind;
    if recordings.is_empty() {
        return Err(CalibrateError::NoRecording);
    }
    let Observed {
        obs,
        mut notes,
        gyro_bias_std_rad_s,
    } = observe_recordings(recordings, opts)?;
    if recordings.len() > 1 {
        notes.push(crate::note::Note::JointBiases {
            recordings: recordings.len(),
            accel_turn_on_m_s2: opts.accel_turn_on_bias_m_s2,
            gyro_turn_on_rad_s: opts.gyro_turn_on_bias_rad_s,
        });
    }
    let caveats = crate::reference::ReferenceCaveats {
        gyro_bias_std_rad_s,
        notes: Vec::new(),
    };

    let needed = |m: &TriadModel| m.n_params() / 3 + 1;
    require_segments(
        &obs,
        SegmentKind::Static,
        needed(&opts.accel).max(2),
        "accel fit",
    )?;
    let (points, sessions) = joint_points(&obs, Triad::Accel, opts.accel_turn_on_bias_m_s2);
    let accel = fit_loadable(
        &opts.accel,
        Triad::Accel,
        &points,
        &sessions,
        &fit_options(opts, opts.accel_bias_drift_m_s2, None, &opts.accel_noise),
    )?;

    let plateaus = obs
        .iter()
        .any(|o| o.segmentation.count(SegmentKind::Plateau) > 0);
    let (gyro_model, note) = gyro_model_with_plateaus(&opts.gyro, plateaus);
    notes.extend(note);
    require_segments(&obs, SegmentKind::Static, 1, "gyro fit")?;
    let (points, sessions) = joint_points(&obs, Triad::Gyro, opts.gyro_turn_on_bias_rad_s);
    let gyro = fit_loadable(
        &gyro_model,
        Triad::Gyro,
        &points,
        &sessions,
        &fit_options(
            opts,
            opts.gyro_bias_drift_rad_s,
            caveats.gyro_bias_std_rad_s,
            &opts.gyro_noise,
        ),
    )?;

    let mut calibration = imu_model::Calibration::identity();
    calibration.accel = accel.model.clone();
    calibration.gyro = gyro.model.clone();
    let recordings = recording_fits(obs, recordings);
    Ok(CalibrationFit {
        segmentation: recordings[0].segmentation.clone(),
        segment_truth: recordings[0].segment_truth.clone(),
        recordings,
        accel,
        gyro,
        calibration,
        notes,
    })
}

/// `e` naming recording `i` when there are several.
fn in_recording(
    recordings: &[(&crate::ImuSeries, &Reference)],
    i: usize,
    e: CalibrateError,
) -> CalibrateError {
    if recordings.len() > 1 {
        CalibrateError::Recording {
            number: i + 1,
            origin: recordings[i].0.origin.clone(),
            source: Box::new(e),
        }
    } else {
        e
    }
}

/// Each recording's fit points, the notes of their references and segmentations (prefixed with
/// the recording when there are several), and the largest unknown gyro bias of the references.
fn observe_recordings(
    recordings: &[(&crate::ImuSeries, &Reference)],
    opts: &CalibrateOptions,
) -> Result<Observed, CalibrateError> {
    let several = recordings.len() > 1;
    let mut notes = crate::note::Notes::default();
    let mut obs = Vec::with_capacity(recordings.len());
    let mut gyro_bias_std_rad_s: Option<[f64; 3]> = None;
    for (i, (series, reference)) in recordings.iter().enumerate() {
        let o = Observations::from_recording(series, reference, &opts.segment, false)
            .map_err(|e| in_recording(recordings, i, e))?;
        let caveats = reference
            .caveats(series, &o.segmentation.segments)
            .map_err(|e| in_recording(recordings, i, e.into()))?;
        let tag = |n: crate::note::Note| {
            if several {
                n.in_recording(i + 1, &series.origin)
            } else {
                n
            }
        };
        notes.extend(caveats.notes.iter().cloned().map(tag));
        notes.extend(o.segmentation.notes().into_iter().map(tag));
        notes.extend(
            o.segmentation
                .skipped
                .iter()
                .map(|k| tag(crate::note::Note::SegmentSkipped(k.clone()))),
        );
        // Each reference's unknown is common to its own segments; the largest bounds what it
        // can do to the bias fitted from all of them.
        if let Some(sd) = caveats.gyro_bias_std_rad_s {
            let m = gyro_bias_std_rad_s.get_or_insert([0.0; 3]);
            for (m, x) in m.iter_mut().zip(sd) {
                *m = m.max(x);
            }
        }
        obs.push(o);
    }
    Ok(Observed {
        obs,
        notes,
        gyro_bias_std_rad_s,
    })
}

/// What [`observe_recordings`] found.
struct Observed {
    /// Fit points per recording.
    obs: Vec<Observations>,
    /// Notes of the references and segmentations.
    notes: crate::note::Notes,
    /// The largest unknown gyro bias of the references (rad/s, 1 sigma per axis).
    gyro_bias_std_rad_s: Option<[f64; 3]>,
}

/// The fit options of one triad. A characterised noise carries the bias wander in the
/// covariance of the means; without one, the wander is added to the bias standard errors.
/// Known shared noise is kept.
fn fit_options(
    opts: &CalibrateOptions,
    drift: Option<[f64; 3]>,
    input: Option<[f64; 3]>,
    noise: &Option<imu_model::NoiseModel>,
) -> FitOptions {
    FitOptions {
        fixed: Vec::new(),
        bias_input_uncertainty: input,
        mean_noise: match (&opts.fit.mean_noise, noise) {
            (MeanNoise::Shared(s), _) => MeanNoise::Shared(*s),
            (_, Some(n)) => MeanNoise::Characterised(n.clone()),
            (_, None) => MeanNoise::White { bias_drift: drift },
        },
        ..opts.fit.clone()
    }
}

/// Each recording's part of the joint fit: its segments and its ranges of the fit points.
fn recording_fits(
    obs: Vec<Observations>,
    recordings: &[(&crate::ImuSeries, &Reference)],
) -> Vec<RecordingFit> {
    let (mut a0, mut g0) = (0, 0);
    obs.into_iter()
        .zip(recordings)
        .map(|(o, (series, reference))| {
            let (na, ng) = (o.accel.len(), o.gyro.len());
            let r = RecordingFit {
                origin: series.origin.clone(),
                reference: reference.describe(),
                segmentation: o.segmentation,
                segment_truth: o.segment_truth,
                accel_points: a0..a0 + na,
                gyro_points: g0..g0 + ng,
            };
            (a0, g0) = (a0 + na, g0 + ng);
            r
        })
        .collect()
}

#[cfg(test)]
mod tests;
