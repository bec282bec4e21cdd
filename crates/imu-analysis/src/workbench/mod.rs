//! The model workbench: hold an error model against a recording, see where it fails, find which
//! physical effect of the library is missing, add it, and watch the error fall to the noise
//! floor.
//!
//! Observations are segment means (static positions and rate plateaus) with their true input
//! from a reference, exactly as for calibration ([`crate::calibrate::Observations`]). What is new here:
//!
//! - **Noise floor from the data.** Real MEMS noise is coloured: a segment mean scatters by more
//!   than white noise predicts. The floor comes from the overlapping Allan deviation of the
//!   static segments themselves, pooled over segments: each segment mean gets the Allan
//!   variance at its own duration (for white noise exactly the variance of the mean; for
//!   bias instability the scatter of adjacent means), read off or extrapolated from the pooled
//!   curve. The IEEE terms fitted to the curve ([`imu_stats::noise_terms::fit_terms`]) are reported. A
//!   noise characterisation of a long static run (imu-noise's `[noise]` tables) may be given
//!   instead.
//! - **Goodness of fit.** The generalised chi-square of the residuals against that covariance,
//!   with the degrees of freedom the fit left, gives a p-value per triad and axis.
//! - **Candidates.** Every library effect not in the model is added in turn and the model
//!   refitted. Segments are often too short to resolve a slow wander of the bias (random walk,
//!   or bias instability whose flicker shows only beyond the segment length), and a wander
//!   between segments must not pass for an effect, so every fit profiles out, per axis, the
//!   residuals' white scale and a bias wander (maximum likelihood, alternated with the
//!   parameter fit): a random walk or extra flicker, the likelier for the model under test, the
//!   same family for all its candidates; nested models are compared by the likelihood ratio, expressed as an F
//!   statistic (exact for a linear model with one profiled scale), by AIC, and by the share of
//!   the excess chi-square (against the floor) the effect explains. Parameters the recording cannot determine are named and not
//!   counted. An effect is *claimed* only when it is significant, explains a substantial share
//!   of the excess, and the recording can tell it apart from the runner-up.
//! - **Structure.** Residuals against every candidate explanatory signal, lag-1 autocorrelation,
//!   a periodogram of the segment residuals in time, and spectral lines inside the static
//!   segments: what remains when nothing in the library explains it.
//! - **Ladder.** From a base model, add the best claimed effect and refit until the residual is
//!   consistent with the noise floor or nothing more is claimed.

use imu_model::nalgebra::{DMatrix, DVector};
use imu_model::{EffectKind, NoiseModel, Triad, TriadModel, Vec3};
use serde::Serialize;

use crate::ImuSeries;
use crate::calibrate::{
    CalibrateError, FitError, FitOptions, FitPoint, FitResult, FittedParam, NotFitted,
    Observations, Reference, SharedNoise, Unobservable, fit_triad, segment_covariance,
};
use crate::segment::{SegmentKind, SegmentOptions};
use imu_stats::allan::{self, Kind, TauSet};
use imu_stats::noise_terms as noise;
use imu_stats::noise_terms::NoiseTerms;
use imu_stats::spectral::{Periodogram, lomb_scargle_peak};
use imu_stats::{descriptive, distributions};

mod candidates;
mod crossval;
mod diagnose;
mod explain;
mod fit;
mod floor;
mod ladder;
mod magnitude;
mod moves;
mod observations;
mod profile;
mod structure;
mod words;

use candidates::*;
use crossval::*;
pub use crossval::{FoldScheme, HeldOut, HeldOutUnit};
use diagnose::CandidateBase;
use explain::*;
pub use floor::*;
use magnitude::*;
use observations::MovesSetup;
use profile::*;
pub use structure::*;
use words::{AXES, fmt3};
pub use words::{
    AxisWander, CandidateFacts, Explanation, Finding, MovesFinding, MovesOutcome, NotObservable,
    NotObservables, Separation, Unexplained, Verdict,
};

/// Settings of the workbench.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    /// Segmentation settings.
    pub segment: SegmentOptions,
    /// Fit settings (`fixed`, `mean_noise` and `excess_scatter` are set here).
    pub fit: FitOptions,
    /// Significance level of the candidate tests and of the goodness-of-fit verdict.
    pub alpha: f64,
    /// Smallest share of the excess chi-square (chi2 - dof) a claimed effect must explain.
    pub min_share: f64,
    /// Two candidates whose explained residual patterns correlate above this, with comparable
    /// improvement, are reported as indistinguishable in this recording.
    pub ambiguity_correlation: f64,
    /// At most this many ladder steps.
    pub max_steps: usize,
    /// Noise characterisation of the accel (e.g. from imu-noise); default: from the data.
    pub accel_noise: Option<NoiseModel>,
    /// Noise characterisation of the gyro; default: from the data.
    pub gyro_noise: Option<NoiseModel>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            segment: SegmentOptions::default(),
            fit: FitOptions::default(),
            alpha: 1e-3,
            min_share: 0.3,
            ambiguity_correlation: 0.9,
            max_steps: 6,
            accel_noise: None,
            gyro_noise: None,
        }
    }
}

/// Failures of the workbench.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// Segmentation or reference failed.
    #[error(transparent)]
    Observations(#[from] CalibrateError),
    /// The base fit failed.
    #[error(transparent)]
    Fit(#[from] FitError),
    /// Not enough static data for a noise floor.
    #[error(
        "{triad}: no static segment of at least {min_s} s to measure the noise floor from; record \
         the sensor still for a while (or give a noise characterisation)"
    )]
    NoStaticData {
        /// Triad.
        triad: Triad,
        /// Shortest usable duration, s.
        min_s: f64,
    },
}

// ------------------------------------------------------------------------------ results

/// Per-axis verdict.
#[derive(Clone, Debug, Serialize)]
pub struct AxisVerdict {
    /// RMS of the residuals, U.
    pub residual_rms: f64,
    /// RMS the residuals would have if the model were right (noise floor and the fit's
    /// degrees of freedom), U.
    pub noise_floor_rms: f64,
    /// The same with the bias wander between segments the residuals show (maximum-likelihood
    /// random walk; equal to `noise_floor_rms` when no wander is found), U.
    pub noise_floor_with_drift_rms: f64,
    /// Generalised chi-square of this axis.
    pub chi2: f64,
    /// Its degrees of freedom.
    pub dof: f64,
    /// P(chi-square > chi2) if the model were right.
    pub p_value: f64,
}

/// One observation's residual.
#[derive(Clone, Debug, Serialize)]
pub struct SegmentResidual {
    /// Index into the segmentation.
    pub segment: usize,
    /// Static or plateau.
    pub kind: SegmentKind,
    /// Start and end time, s.
    pub start_s: f64,
    /// End time, s.
    pub end_s: f64,
    /// model(true input) - measured, U.
    pub residual: [f64; 3],
    /// Noise floor (standard deviation) of this mean, U.
    pub floor: [f64; 3],
    /// Residual in units of the floor.
    pub z: [f64; 3],
}

/// Correlation of an axis's residual with an explanatory signal.
#[derive(Clone, Debug, Serialize)]
pub struct Correlate {
    /// Signal name (with unit).
    pub signal: String,
    /// Pearson correlation.
    pub r: f64,
}

/// The structure left in one axis's residual.
#[derive(Clone, Debug, Serialize)]
pub struct Structure {
    /// Signals sorted by |r| (strongest first).
    pub correlates: Vec<Correlate>,
    /// Lag-1 autocorrelation of the floor-normalised residuals in time order.
    pub lag1_autocorrelation: f64,
    /// Dominant period of the residuals in time (Lomb-Scargle), s, and its share of variance.
    pub dominant_period_s: Option<(f64, f64)>,
}

/// A periodic component found inside the static segments.
#[derive(Clone, Debug, Serialize)]
pub struct SpectralLine {
    /// Axis (0 = x).
    pub axis: usize,
    /// Frequency, Hz.
    pub frequency_hz: f64,
    /// Amplitude of the sinusoid, U.
    pub amplitude: f64,
    /// Line power over the local noise level.
    pub ratio: f64,
}

/// One parameter of a candidate effect.
pub type ParamValue = crate::calibrate::FittedParam;

/// A library effect tried on top of the model.
#[derive(Clone, Debug, Serialize)]
pub struct Candidate {
    /// The effect.
    pub effect: EffectKind,
    /// Triad.
    pub triad: Triad,
    /// Parameters the recording determines (0: not observable here).
    pub new_params: usize,
    /// Why not observable (or which of its parameters are not); JSON `not_observable` (the
    /// sentences) and `not_observable_codes`.
    #[serde(flatten)]
    pub not_observable: NotObservables,
    /// Generalised chi-square with the effect.
    pub chi2: f64,
    /// Degrees of freedom with the effect.
    pub dof: usize,
    /// F statistic of the nested comparison.
    pub f: f64,
    /// Its p-value.
    pub p_value: f64,
    /// AIC improvement (positive = better).
    pub delta_aic: f64,
    /// Share of the model's excess chi-square (chi2 - dof) the effect explains, in [0, 1] (an
    /// effect can lower the chi-square by more than the excess: that is all of it); None when
    /// the model has no excess (chi2 <= dof), so there is nothing to share.
    pub share_of_excess: Option<f64>,
    /// Residual RMS per axis with the effect, U.
    pub residual_rms: [f64; 3],
    /// p < alpha.
    pub significant: bool,
    /// Significant, explains enough, is not confused with another candidate, and lowers the
    /// error on held-out observations too ([`HeldOut::confirmed`]).
    pub claimed: bool,
    /// The cross-validation of a candidate that wins in-sample (the one the workbench would
    /// claim): held-out RMS before and after, next to the in-sample figures.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out: Option<HeldOut>,
    /// What it means (its `Display` is the plain words); JSON `explanation` and
    /// `explanation_code`.
    #[serde(flatten)]
    pub explanation: Explanation,
    /// The effect's fitted parameters.
    pub params: Vec<ParamValue>,
    /// The lines to add to the model file.
    pub model_change: String,
    /// The whole model refitted with the effect (None when not observable).
    #[serde(skip)]
    pub model: Option<TriadModel>,
    /// Explained pattern (base residual - residual with the effect, floor-normalised).
    #[serde(skip)]
    pattern: Vec<f64>,
}

impl Candidate {
    /// `explains 62 % of the excess`, or that there was none, for verdicts.
    pub fn share_of_excess_text(&self) -> String {
        words::share_of_excess_text(self.share_of_excess)
    }

    /// The share as a table cell: two decimals, or `-` without an excess.
    pub fn share_of_excess_cell(&self) -> String {
        self.share_of_excess
            .map_or_else(|| "-".into(), |s| format!("{s:.2}"))
    }
}

/// The share of `excess_chi2` that `explained_chi2` is, bounded to [0, 1]; None when there is
/// no excess.
pub(crate) fn share_of(explained_chi2: f64, excess_chi2: f64) -> Option<f64> {
    (excess_chi2 > 0.0 && explained_chi2.is_finite())
        .then(|| (explained_chi2 / excess_chi2).clamp(0.0, 1.0))
}

/// Two candidates this recording cannot tell apart.
#[derive(Clone, Debug, Serialize)]
pub struct Ambiguity {
    /// Triad.
    pub triad: Triad,
    /// The two effects.
    pub effects: [EffectKind; 2],
    /// Correlation of what they explain.
    pub correlation: f64,
    /// The recording that would separate them; JSON `separating_recording` (the sentence) and
    /// `separating_recording_code`.
    #[serde(flatten)]
    pub separating_recording: Separation,
}

/// What a triad's verdict says, decided once: its words and a report's heading follow it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum VerdictState {
    /// The residuals are consistent with the noise floor.
    Consistent,
    /// Consistent in the chi-square test, but a periodic component (a spectral line) sits in
    /// the static segments.
    PeriodicComponent,
    /// Not consistent with the floor alone; a slow wander of the bias between segments explains
    /// the excess (and no library effect does significantly).
    BiasWander,
    /// Not consistent; a library effect is missing (the claimed candidate).
    MissingEffect,
    /// Not consistent; the best candidate explains the excess in these data but does not
    /// lower the error on held-out observations: not confirmed, not claimed.
    NotConfirmed,
    /// Not consistent; two effects explain the excess alike.
    Ambiguous,
    /// Not consistent, and nothing in the library explains it.
    Unexplained,
    /// Reference-free gyro: the gains do not match the rotations over the moves.
    GainsInconsistent,
}

/// The model held against one triad's observations.
#[derive(Clone, Debug, Serialize)]
pub struct TriadDiagnosis {
    /// Triad.
    pub triad: Triad,
    /// The model's effects.
    pub effects: Vec<EffectKind>,
    /// Ratio of the residual variance to the noise floor's, per axis (maximum likelihood, with
    /// the drift below).
    pub noise_scale: [f64; 3],
    /// Random walk of the bias between segments that the residuals show, per axis, U sqrt(Hz)
    /// (maximum likelihood; 0 where extra bias instability explains the wander better).
    pub drift_random_walk: [f64; 3],
    /// Bias instability beyond the floor's that the residuals show, per axis, U (maximum
    /// likelihood: flicker the segments are too short to show; 0 where a random walk explains
    /// the wander better).
    pub drift_bias_instability: [f64; 3],
    /// Generalised chi-square against the noise floor.
    pub chi2: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// P(chi-square > chi2) if the model were right.
    pub p_value: f64,
    /// The model is consistent with the noise floor (p >= alpha, no spectral line).
    pub consistent: bool,
    /// The residuals are consistent with the noise floor once a slow wander of the bias between
    /// segments (`drift_random_walk` or `drift_bias_instability`, maximum likelihood) is
    /// allowed: what is left
    /// is drift of the sensor, not a missing effect (p of that test >= alpha).
    pub consistent_with_drift: bool,
    /// p-value of that test.
    pub p_value_with_drift: f64,
    /// Per axis.
    pub axes: [AxisVerdict; 3],
    /// Per observation, in time order.
    pub segments: Vec<SegmentResidual>,
    /// Indices into `segments` of the worst observations (largest |z|).
    pub worst: Vec<usize>,
    /// Residual structure per axis.
    pub structure: [Structure; 3],
    /// Periodic components inside the static segments.
    pub spectral_lines: Vec<SpectralLine>,
    /// Candidates, best first (observable ones ranked by AIC improvement).
    pub candidates: Vec<Candidate>,
    /// Candidates the recording cannot separate.
    pub ambiguities: Vec<Ambiguity>,
    /// The verdict (its `Display` is the words); JSON `verdict` (the words) and
    /// `verdict_codes`.
    #[serde(flatten)]
    pub verdict: Verdict,
    /// What the verdict says (the heading of a report follows it).
    pub state: VerdictState,
    /// The fit.
    pub fit: FitResult,
    /// The noise floor used.
    pub noise_floor: NoiseFloor,
    /// Reference-free gyro: the gains held against the moves between poses.
    pub moves: Option<MovesVerdict>,
}

/// The gyro gains held against the rotations integrated over the moves between still poses
/// (reference-free workbench).
#[derive(Clone, Debug, Serialize)]
pub struct MovesVerdict {
    /// Moves used.
    pub n_moves: usize,
    /// Moves skipped (lost samples).
    pub skipped: usize,
    /// Gain effects of the model.
    pub effects: Vec<EffectKind>,
    /// RMS of the gravity-direction error after each move (per component), rad.
    pub residual_rms_rad: f64,
    /// RMS expected from the noise (white gyro noise over the move, the pose means), rad.
    pub expected_rms_rad: f64,
    /// Chi-square of the whitened errors.
    pub chi2: f64,
    /// Its degrees of freedom.
    pub dof: usize,
    /// P(chi-square > chi2) if the model were right.
    pub p_value: f64,
    /// p >= alpha.
    pub consistent: bool,
}

/// What [`Workbench::diagnose_moves`] finds.
struct MovesDiagnosis {
    verdict: MovesVerdict,
    candidates: Vec<Candidate>,
    ambiguities: Vec<Ambiguity>,
    /// The fitted gain model.
    gains: TriadModel,
    /// What the verdict says of the moves.
    finding: MovesFinding,
}

/// What a workbench holds the model against.
#[derive(Clone, Debug)]
enum Mode {
    /// Segment means against a reference's true inputs (plan, log or truth).
    Reference,
    /// Hand-held still poses: the accel against the gravity magnitude, the gyro offsets against
    /// Earth's rate, the gyro gains against the rotations integrated over the moves.
    ReferenceFree {
        magnitude: Magnitude,
        /// What the moves are prepared from (again for a model whose offsets vary along a
        /// move).
        setup: Box<MovesSetup>,
        /// The moves between consecutive still poses (the rate corrected by the poses' rates).
        moves: Vec<crate::calibrate::reference_free::MoveData>,
        /// Moves skipped (lost samples).
        moves_skipped: usize,
    },
}

/// The workbench's state: a recording's observations and noise floors.
pub struct Workbench<'a> {
    series: &'a ImuSeries,
    /// Segments, truth and points.
    pub obs: Observations,
    /// Accel noise floor.
    pub accel_floor: NoiseFloor,
    /// Gyro noise floor.
    pub gyro_floor: NoiseFloor,
    accel_points: Vec<FitPoint>,
    gyro_points: Vec<FitPoint>,
    accel_index: Vec<usize>,
    gyro_index: Vec<usize>,
    opts: DiagnoseOptions,
    spectral: [Vec<SpectralLine>; 2],
    /// What the model is held against.
    mode: Mode,
    /// Conventions and decisions (reference-free: gravity, Earth rate, gyro gains).
    pub notes: crate::note::Notes,
}

/// `f` of every item, in the items' order, the items spread over the cores (round robin, so
/// that costly and cheap items mix). The items must be independent (the workbench's candidates,
/// its cross-validation folds): each result is then exactly what a sequential call gives, and
/// so is everything computed from them in order.
pub(crate) fn parallel_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(items.len());
    if threads <= 1 {
        return items.iter().map(f).collect();
    }
    let f = &f;
    let mut done: Vec<(usize, R)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                s.spawn(move || {
                    (t..items.len())
                        .step_by(threads)
                        .map(|i| (i, f(&items[i])))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, r)| r).collect()
}

/// Effects whose time constant or shape a neutral start cannot find: fitted from several
/// starting points.
fn start_values(kind: EffectKind, span_s: f64) -> Vec<f64> {
    match kind {
        EffectKind::Warmup => [0.03, 0.1, 0.3, 1.0]
            .iter()
            .map(|f| (f * span_s).max(1.0))
            .collect(),
        _ => Vec::new(),
    }
}

/// One rung of the ladder.
#[derive(Clone, Debug, Serialize)]
pub struct LadderStep {
    /// The effect added at this step (None for the base model).
    pub added: Option<(Triad, EffectKind)>,
    /// The held-out check that confirmed its claim.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out: Option<HeldOut>,
    /// Accel summary after the step.
    pub accel: StepSummary,
    /// Gyro summary after the step.
    pub gyro: StepSummary,
}

/// Residual and floor of one triad at one ladder step.
#[derive(Clone, Debug, Serialize)]
pub struct StepSummary {
    /// Effects in the model.
    pub effects: Vec<EffectKind>,
    /// Residual RMS per axis, U.
    pub residual_rms: [f64; 3],
    /// Noise floor RMS per axis, U.
    pub noise_floor_rms: [f64; 3],
    /// Noise floor RMS with the bias wander the residuals show, per axis, U.
    pub noise_floor_with_drift_rms: [f64; 3],
    /// Generalised chi-square and dof.
    pub chi2: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// p-value of the goodness of fit.
    pub p_value: f64,
    /// Consistent with the noise floor.
    pub consistent: bool,
    /// Consistent once a slow bias wander is allowed.
    pub consistent_with_drift: bool,
    /// Reference-free gyro: the gains against the moves between poses.
    pub moves: Option<MovesVerdict>,
}

impl StepSummary {
    fn of(d: &TriadDiagnosis) -> StepSummary {
        StepSummary {
            effects: d.effects.clone(),
            residual_rms: d.axes.each_ref().map(|a| a.residual_rms),
            noise_floor_rms: d.axes.each_ref().map(|a| a.noise_floor_rms),
            noise_floor_with_drift_rms: d.axes.each_ref().map(|a| a.noise_floor_with_drift_rms),
            chi2: d.chi2,
            dof: d.dof,
            p_value: d.p_value,
            consistent: d.consistent,
            consistent_with_drift: d.consistent_with_drift,
            moves: d.moves.clone(),
        }
    }
}

/// The ladder's result.
#[derive(Clone, Debug, Serialize)]
pub struct Ladder {
    /// Base model first, then one step per added effect.
    pub steps: Vec<LadderStep>,
    /// The base model's diagnoses (accel, gyro): what the ladder started from.
    #[serde(skip)]
    pub base_diagnoses: [TriadDiagnosis; 2],
    /// The final model's diagnoses (accel, gyro).
    pub final_diagnoses: [TriadDiagnosis; 2],
    /// The final model as a calibration.
    #[serde(skip)]
    pub calibration: imu_model::Calibration,
    /// Conventions and decisions behind it (reference-free: gravity, Earth rate, gyro gains);
    /// `--json` has the sentences (`notes`) and codes (`note_codes`).
    #[serde(flatten)]
    pub notes: crate::note::Notes,
}

#[cfg(test)]
mod tests {
    use super::share_of;

    #[test]
    fn the_share_of_excess_is_a_share_or_absent() {
        assert_eq!(share_of(3.0, 12.0), Some(0.25));
        // An effect can lower chi2 by more than the excess (it also fits noise): all of it.
        assert_eq!(share_of(31.0, 12.0), Some(1.0));
        // A worse fit explains none of it.
        assert_eq!(share_of(-2.0, 12.0), Some(0.0));
        // No excess (chi2 <= dof), or next to none: nothing to share, not 5e12.
        assert_eq!(share_of(3.0, 0.0), None);
        assert_eq!(share_of(3.0, -4.0), None);
        assert_eq!(share_of(f64::NAN, 12.0), None);
        assert!(share_of(3.0, 6e-13).unwrap() <= 1.0);
    }
}
