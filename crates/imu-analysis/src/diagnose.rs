//! The model workbench: hold an error model against a recording, see where it fails, find which
//! physical effect of the library is missing, add it, and watch the error fall to the noise
//! floor.
//!
//! Observations are segment means (static positions and rate plateaus) with their true input
//! from a reference, exactly as for calibration ([`crate::fit::Observations`]). What is new here:
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

use std::fmt::Write as _;

use imu_model::nalgebra::{DMatrix, DVector};
use imu_model::{EffectKind, NoiseModel, Triad, TriadModel, Vec3};
use serde::Serialize;

use crate::ImuSeries;
use crate::fit::{
    CalibrateError, FitError, FitOptions, FitPoint, FitResult, Observations, Reference,
    SharedNoise, Unobservable, fit_triad, segment_covariance,
};
use crate::segment::{SegmentKind, SegmentOptions};
use imu_stats::allan::{self, Kind, TauSet};
use imu_stats::noise_terms as noise;
use imu_stats::noise_terms::NoiseTerms;
use imu_stats::spectral::{Periodogram, lomb_scargle_peak};
use imu_stats::{descriptive, distributions};

/// Settings of the workbench.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    /// Segmentation settings.
    pub segment: SegmentOptions,
    /// Fit settings (`fixed`, `bias_drift` and `random_walk_q` are set here).
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

// ------------------------------------------------------------------------------ noise floor

/// The noise floor of one triad: the noise terms per axis and where they came from.
#[derive(Clone, Debug, Serialize)]
pub struct NoiseFloor {
    /// Triad.
    pub triad: Triad,
    /// Where the terms came from.
    pub source: String,
    /// White noise density per axis, U/sqrt(Hz).
    pub white_per_sqrt_hz: [f64; 3],
    /// Bias instability per axis, U (the Allan floor is 0.664 of it).
    pub bias_instability: [f64; 3],
    /// Random walk fitted to the pooled Allan deviation per axis, U sqrt(Hz) (reported; the
    /// floor itself uses the Allan variance at each segment's length).
    pub random_walk_sqrt_hz: [f64; 3],
    /// True where the data do not resolve the random walk (the value is then the fit's, possibly
    /// 0; the candidate tests profile the drift from the residuals instead).
    pub random_walk_unresolved: [bool; 3],
    /// Quantization per axis, U s.
    pub quantization_s: [f64; 3],
    /// Flicker Allan variance floor per axis, U^2 (`(0.664 B)^2`): its long-range correlation
    /// is part of the segment means' covariance.
    pub flicker_var: [f64; 3],
    /// Pooled overlapping Allan deviation of the static segments per axis: (tau s, dev U).
    pub allan: [Vec<(f64, f64)>; 3],
}

impl NoiseFloor {
    /// Variance of the mean of a segment of `duration_s` on `axis`: the Allan variance at the
    /// segment's duration (equal to the variance of the mean for white noise, and the scatter
    /// of adjacent means for coloured noise), read off the pooled curve (log-log
    /// interpolation) or extrapolated beyond its longest tau with the slope of its last
    /// points (clamped between white noise and random walk).
    pub fn segment_mean_variance(&self, axis: usize, duration_s: f64) -> f64 {
        let c = &self.allan[axis];
        let t = duration_s.max(1e-9);
        if c.is_empty() {
            return 0.0;
        }
        let ln = |v: (f64, f64)| (v.0.ln(), v.1.max(1e-300).ln());
        let dev = if t <= c[0].0 {
            c[0].1 * (c[0].0 / t).sqrt()
        } else if let Some(i) = c.iter().position(|p| p.0 >= t) {
            let ((x0, y0), (x1, y1)) = (ln(c[i - 1]), ln(c[i]));
            (y0 + (y1 - y0) * (t.ln() - x0) / (x1 - x0)).exp()
        } else {
            let tail: Vec<(f64, f64)> = c.iter().rev().take(3).map(|p| ln(*p)).collect();
            let slope = if tail.len() < 2 {
                -0.5
            } else {
                let n = tail.len() as f64;
                let mx = tail.iter().map(|p| p.0).sum::<f64>() / n;
                let my = tail.iter().map(|p| p.1).sum::<f64>() / n;
                let sxy: f64 = tail.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
                let sxx: f64 = tail.iter().map(|p| (p.0 - mx).powi(2)).sum();
                (sxy / sxx.max(1e-300)).clamp(-0.5, 0.5)
            };
            let last = c[c.len() - 1];
            last.1 * (t / last.0).powf(slope)
        };
        dev * dev
    }

    /// From a noise characterisation (white density, bias instability, random walk,
    /// quantization step -> Q = lsb / sqrt(12) x sample period); its Allan curve is the
    /// model's, at octave taus from the sample period to a day.
    pub fn from_model(triad: Triad, m: &NoiseModel, rate_hz: f64) -> NoiseFloor {
        let tau0 = 1.0 / rate_hz.max(1e-9);
        let taus: Vec<f64> = (0..)
            .map(|k| tau0 * 2f64.powi(k))
            .take_while(|t| *t < 86_400.0)
            .collect();
        NoiseFloor {
            triad,
            source: "the given noise characterisation".into(),
            white_per_sqrt_hz: m.white_density,
            bias_instability: m.bias_instability,
            random_walk_sqrt_hz: m.random_walk,
            random_walk_unresolved: [false; 3],
            quantization_s: m.quantization_lsb.map(|q| q / 12f64.sqrt() * tau0),
            flicker_var: m
                .bias_instability
                .map(|b| (imu_stats::noise_terms::BIAS_INSTABILITY_FACTOR * b).powi(2)),
            allan: std::array::from_fn(|a| {
                taus.iter().map(|&t| (t, m.allan_deviation(t)[a])).collect()
            }),
        }
    }
}

/// Two candidates whose AIC improvements differ by less than this are not told apart.
const AMBIGUOUS_AIC: f64 = 10.0;

/// Shortest static segment used for the noise floor, s.
const MIN_NOISE_SEGMENT_S: f64 = 2.0;

/// Measures the noise floor of `triad` from the static segments of `series`: the overlapping
/// Allan variance of each segment at octave taus, pooled over segments by their number of terms,
/// and the IEEE terms fitted to it.
pub fn measure_noise_floor(
    series: &ImuSeries,
    obs: &Observations,
    triad: Triad,
) -> Result<NoiseFloor, DiagnoseError> {
    let rate = series.sample_rate_hz();
    let tau0 = 1.0 / rate;
    let data = if triad == Triad::Gyro {
        &series.gyro_rad_s
    } else {
        &series.accel_m_s2
    };
    let statics: Vec<_> = obs
        .segmentation
        .of_kind(SegmentKind::Static)
        .filter(|s| s.n as f64 * tau0 >= MIN_NOISE_SEGMENT_S)
        .collect();
    if statics.is_empty() {
        return Err(DiagnoseError::NoStaticData {
            triad,
            min_s: MIN_NOISE_SEGMENT_S,
        });
    }
    let total_s: f64 = statics.iter().map(|s| s.n as f64 * tau0).sum();
    let opts = allan::Options {
        taus: TauSet::Octave,
        ..Default::default()
    };
    let mut floor = NoiseFloor {
        triad,
        source: format!(
            "overlapping Allan deviation of {} static segments ({total_s:.0} s in all), IEEE \
             terms fitted",
            statics.len()
        ),
        white_per_sqrt_hz: [0.0; 3],
        bias_instability: [0.0; 3],
        random_walk_sqrt_hz: [0.0; 3],
        random_walk_unresolved: [false; 3],
        quantization_s: [0.0; 3],
        flicker_var: [0.0; 3],
        allan: Default::default(),
    };
    for axis in 0..3 {
        // m -> (sum of var x terms, terms, edf)
        let mut pooled: std::collections::BTreeMap<usize, (f64, f64, f64)> = Default::default();
        for s in &statics {
            let y: Vec<f64> = data[s.range()].iter().map(|v| v[axis]).collect();
            let Ok(curve) = allan::deviation(Kind::Oadev, &y, tau0, &opts) else {
                continue;
            };
            for p in curve.points {
                let e = pooled.entry(p.m).or_default();
                e.0 += p.dev * p.dev * p.n_terms as f64;
                e.1 += p.n_terms as f64;
                e.2 += p.edf;
            }
        }
        let points: Vec<allan::DevPoint> = pooled
            .iter()
            .filter(|(_, v)| v.1 > 0.0)
            .map(|(&m, &(sv, n, edf))| {
                let dev = (sv / n).sqrt();
                let (lo, hi) = allan::confidence_interval(dev, edf, 0.683);
                allan::DevPoint {
                    m,
                    tau_s: m as f64 * tau0,
                    dev,
                    n_terms: n as usize,
                    edf,
                    dev_lo: lo,
                    dev_hi: hi,
                }
            })
            .collect();
        floor.allan[axis] = points.iter().map(|p| (p.tau_s, p.dev)).collect();
        let curve = allan::DevCurve {
            kind: Kind::Oadev,
            tau0_s: tau0,
            confidence: 0.683,
            points,
        };
        match noise::fit_terms(&curve) {
            Ok(t) => apply_terms(&mut floor, axis, &t),
            Err(_) => {
                // Too few taus: the segment means' own scatter is all there is.
                let y: Vec<f64> = statics
                    .iter()
                    .flat_map(|s| data[s.range()].iter().map(|v| v[axis]))
                    .collect();
                let m = y.iter().sum::<f64>() / y.len() as f64;
                let var = y.iter().map(|v| (v - m).powi(2)).sum::<f64>() / y.len() as f64;
                floor.white_per_sqrt_hz[axis] = (var * tau0).sqrt();
            }
        }
    }
    Ok(floor)
}

/// The accel and gyro noise floors: the given noise characterisations, else measured from the
/// static segments of `obs`.
fn floors(
    series: &ImuSeries,
    obs: &Observations,
    opts: &DiagnoseOptions,
) -> Result<(NoiseFloor, NoiseFloor), DiagnoseError> {
    let rate = series.sample_rate_hz();
    let floor = |t: Triad, given: &Option<NoiseModel>| match given {
        Some(m) => Ok(NoiseFloor::from_model(t, m, rate)),
        None => measure_noise_floor(series, obs, t),
    };
    Ok((
        floor(Triad::Accel, &opts.accel_noise)?,
        floor(Triad::Gyro, &opts.gyro_noise)?,
    ))
}

fn apply_terms(floor: &mut NoiseFloor, axis: usize, t: &NoiseTerms) {
    floor.white_per_sqrt_hz[axis] = t.n_u_per_sqrt_hz.value;
    floor.bias_instability[axis] = t.b_u.value;
    floor.flicker_var[axis] =
        (imu_stats::noise_terms::BIAS_INSTABILITY_FACTOR * t.b_u.value).powi(2);
    floor.quantization_s[axis] = t.q_u_s.value;
    // The random walk as fitted; when the segments are too short to resolve it the value is
    // marked as such (the candidate tests profile the drift from the residuals anyway).
    let k = &t.k_u_sqrt_hz;
    floor.random_walk_sqrt_hz[axis] = k.value;
    floor.random_walk_unresolved[axis] = !k.significant;
}

/// The observations of one triad with the noise floor as their standard errors.
/// The observations of one triad with the noise floor's independent part (the Allan variance
/// at the segment's duration less the flicker floor, whose correlation between segments is
/// modelled separately) as their standard errors.
fn floored_points(
    points: &[FitPoint],
    floor: &NoiseFloor,
    rate_hz: f64,
    n: &[usize],
) -> Vec<FitPoint> {
    points
        .iter()
        .zip(n)
        .map(|(p, &n)| {
            let duration_s = n as f64 / rate_hz;
            let mut q = p.clone();
            for a in 0..3 {
                let v = floor.segment_mean_variance(a, duration_s);
                let independent = (v - floor.flicker_var[a]).max(0.1 * v);
                q.std_error[a] = independent.sqrt().max(p.std_error[a]);
            }
            q
        })
        .collect()
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
#[derive(Clone, Debug, Serialize)]
pub struct ParamValue {
    /// `<effect>.<param>`.
    pub name: String,
    /// Fitted value.
    pub value: f64,
    /// Standard error.
    pub std_error: Option<f64>,
    /// Unit.
    pub unit: String,
}

/// A library effect tried on top of the model.
#[derive(Clone, Debug, Serialize)]
pub struct Candidate {
    /// The effect.
    pub effect: EffectKind,
    /// Triad.
    pub triad: Triad,
    /// Parameters the recording determines (0: not observable here).
    pub new_params: usize,
    /// Why not observable (or which of its parameters are not).
    pub not_observable: Vec<String>,
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
    /// Share of the model's excess chi-square (chi2 - dof) the effect explains.
    pub share_of_excess: f64,
    /// Residual RMS per axis with the effect, U.
    pub residual_rms: [f64; 3],
    /// p < alpha.
    pub significant: bool,
    /// Significant, explains enough and is not confused with another candidate.
    pub claimed: bool,
    /// Plain-words explanation.
    pub explanation: String,
    /// The effect's fitted parameters.
    pub params: Vec<ParamValue>,
    /// The lines to add to the model file.
    pub model_change: String,
    /// The refit.
    #[serde(skip)]
    pub fit: Option<FitResult>,
    /// Explained pattern (base residual - residual with the effect, floor-normalised).
    #[serde(skip)]
    pattern: Vec<f64>,
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
    /// The recording that would separate them.
    pub separating_recording: String,
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
    /// The verdict in words.
    pub verdict: String,
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
    /// The verdict in words.
    text: String,
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
    /// Reference-free: the accel observations are gravity magnitudes.
    magnitude: Option<Magnitude>,
    /// Reference-free: the moves between consecutive still poses (gyro gains).
    moves: Vec<crate::reference_free::MoveData>,
    /// Moves skipped (lost samples).
    moves_skipped: usize,
    /// Conventions and decisions (reference-free: gravity, Earth rate, gyro gains).
    pub notes: Vec<String>,
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

impl<'a> Workbench<'a> {
    /// Segments `series`, takes the truth from `reference`, measures the noise floors.
    pub fn new(
        series: &'a ImuSeries,
        reference: &Reference,
        opts: DiagnoseOptions,
    ) -> Result<Workbench<'a>, DiagnoseError> {
        let obs = Observations::from_recording(series, reference, &opts.segment, true)?;
        let rate = series.sample_rate_hz();
        let (accel_floor, gyro_floor) = floors(series, &obs, &opts)?;
        let n_of = |v: &[(usize, FitPoint)]| -> Vec<usize> {
            v.iter()
                .map(|(i, _)| obs.segmentation.segments[*i].n)
                .collect()
        };
        let (an, gn) = (n_of(&obs.accel), n_of(&obs.gyro));
        let accel_points = floored_points(&obs.points(Triad::Accel), &accel_floor, rate, &an);
        let gyro_points = floored_points(&obs.points(Triad::Gyro), &gyro_floor, rate, &gn);
        let spectral = [
            spectral_lines(series, &obs, Triad::Accel),
            spectral_lines(series, &obs, Triad::Gyro),
        ];
        Ok(Workbench {
            series,
            accel_index: obs.accel.iter().map(|(i, _)| *i).collect(),
            gyro_index: obs.gyro.iter().map(|(i, _)| *i).collect(),
            obs,
            accel_floor,
            gyro_floor,
            accel_points,
            gyro_points,
            opts,
            spectral,
            magnitude: None,
            moves: Vec::new(),
            moves_skipped: 0,
            notes: Vec::new(),
        })
    }

    /// A workbench without a reference: the unit was held still in many orientations and
    /// turned between them (as for `imu-calibrate --reference-free`).
    ///
    /// - The accel is held against the gravity magnitude at every still pose
    ///   (`g - |corrected mean|`, one residual per pose; its floor is the per-axis floor
    ///   projected on the pose's direction); the rotation gauge is fixed as in the
    ///   reference-free calibration (accel misalignment `xy`, `xz`, `yz` held at 0).
    /// - The gyro offsets (bias, g-sensitivity, temperature, warm-up) are held against the
    ///   still poses, whose true rate is Earth's: its vertical part along the calibrated up
    ///   direction when the latitude is given; the part a heading would fix (horizontal, or all
    ///   of it without a latitude) is an extra noise of each pose mean.
    /// - The gyro gains (scale, misalignment, asymmetry, nonlinearity) are held against the
    ///   rotations integrated over the moves between poses, as `imu-calibrate
    ///   --reference-free` fits them, with the gain effects of the library as candidates; the
    ///   ladder's calibration is that procedure's fit of the final model.
    pub fn reference_free(
        series: &'a ImuSeries,
        gravity_m_s2: Option<f64>,
        latitude_deg: Option<f64>,
        opts: DiagnoseOptions,
    ) -> Result<Workbench<'a>, DiagnoseError> {
        use crate::reference_free::{local_gravity, mean_se, pose_conditions};
        use imu_model::units::EARTH_RATE_RAD_S;
        let segmentation =
            crate::segment::detect(series, &opts.segment).map_err(CalibrateError::from)?;
        let (g_m_s2, gravity_note) = local_gravity(gravity_m_s2, latitude_deg);
        let (vertical_rad_s, earth_note) = match latitude_deg {
            Some(lat) => {
                let (vertical, horizontal) = imu_model::earth::earth_rate_split_rad_s(lat);
                (
                    vertical,
                    format!(
                        "gyro: Earth's vertical rate at latitude {lat} deg is the true rate along \
                         the calibrated up direction of each pose; its horizontal part \
                         ({horizontal:.1e} rad/s, heading unknown) is counted as noise of each pose \
                         mean"
                    ),
                )
            }
            None => (
                0.0,
                format!(
                    "gyro: Earth's rate ({EARTH_RATE_RAD_S:.2e} rad/s, unknown in the sensor \
                     frame without latitude and heading) is counted as noise of each pose mean; \
                     give the latitude to remove its vertical part"
                ),
            ),
        };
        // Variance of the unknown part of Earth's rate on axis `a` of a pose whose up
        // direction is `u`: a horizontal vector at a random heading, or, without a latitude,
        // a vector in a random direction.
        let earth_var = |u: &Vec3, a: usize| {
            imu_model::earth::unknown_heading_variance_rad2_s2(latitude_deg, u[a])
        };
        let poses: Vec<usize> = (0..segmentation.segments.len())
            .filter(|&i| segmentation.segments[i].kind == SegmentKind::Static)
            .collect();
        let dirs: Vec<Vec3> = poses
            .iter()
            .map(|&i| segmentation.segments[i].mean_accel().normalize())
            .collect();
        let point = |i: usize, up: &Vec3, gyro: bool| -> FitPoint {
            let s = &segmentation.segments[i];
            let c = pose_conditions(series, s);
            FitPoint {
                true_input: if gyro {
                    up * vertical_rad_s
                } else {
                    up * g_m_s2
                },
                measured: if gyro { s.mean_gyro() } else { s.mean_accel() },
                std_error: mean_se(
                    if gyro {
                        s.std_gyro_rad_s
                    } else {
                        s.std_accel_m_s2
                    },
                    s.n,
                ),
                conditions: imu_model::Conditions {
                    specific_force_m_s2: up * g_m_s2,
                    ..c
                },
                t_s: 0.5 * (s.start_s + s.end_s),
                duration_s: s.end_s - s.start_s,
            }
        };
        let unknown = crate::fit::SegmentTruth {
            specific_force_m_s2: [f64::NAN; 3],
            angular_rate_rad_s: [f64::NAN; 3],
            temp_c: f64::NAN,
            time_since_power_on_s: f64::NAN,
        };
        let mut obs = Observations {
            segment_truth: vec![unknown; segmentation.segments.len()],
            accel: poses
                .iter()
                .zip(&dirs)
                .map(|(&i, u)| (i, point(i, u, false)))
                .collect(),
            gyro: poses
                .iter()
                .zip(&dirs)
                .map(|(&i, u)| (i, point(i, u, true)))
                .collect(),
            segmentation,
        };
        let rate = series.sample_rate_hz();
        let (accel_floor, gyro_floor) = floors(series, &obs, &opts)?;
        let n: Vec<usize> = poses
            .iter()
            .map(|&i| obs.segmentation.segments[i].n)
            .collect();
        let accel_points = floored_points(&obs.points(Triad::Accel), &accel_floor, rate, &n);
        let spectral = [
            spectral_lines(series, &obs, Triad::Accel),
            spectral_lines(series, &obs, Triad::Gyro),
        ];
        let mut wb = Workbench {
            series,
            accel_index: poses.clone(),
            gyro_index: poses.clone(),
            obs: obs.clone(),
            accel_floor,
            gyro_floor,
            accel_points,
            gyro_points: Vec::new(),
            opts,
            spectral,
            magnitude: Some(Magnitude {
                g_m_s2,
                dirs: dirs.clone(),
                gravity_m_s2,
                latitude_deg,
            }),
            moves: Vec::new(),
            moves_skipped: 0,
            notes: vec![
                gravity_note,
                "accel: held against the gravity magnitude at each still pose; misalignment xy, \
                 xz, yz held at 0 (the magnitude cannot see a rotation of the whole frame: the \
                 accelerometer axes define the frame)"
                    .into(),
                earth_note,
                "gyro gains (scale, misalignment, asymmetry, nonlinearity, temperature scale) \
                 are held against the rotations integrated over the moves between poses, the \
                 gyro offsets against the still poses"
                    .into(),
            ],
        };
        // The calibrated up direction of each pose, from a bias + scale + misalignment fit of
        // the magnitudes (the measured direction if that fit fails).
        let first = TriadModel::with_effects(&TriadModel::PAPER_BASE);
        let mag = wb.magnitude.clone().expect("set above");
        let up: Vec<Vec3> = match wb.fit_magnitude(&mag, &first, None) {
            Ok(f) => wb
                .accel_points
                .iter()
                .map(|p| f.fit.model.inverse(p.measured, &p.conditions).normalize())
                .collect(),
            Err(_) => dirs,
        };
        for (k, (_, p)) in obs.accel.iter_mut().enumerate() {
            p.true_input = up[k] * g_m_s2;
            p.conditions.specific_force_m_s2 = up[k] * g_m_s2;
            wb.accel_points[k].true_input = p.true_input;
            wb.accel_points[k].conditions.specific_force_m_s2 = p.true_input;
        }
        for (k, (i, p)) in obs.gyro.iter_mut().enumerate() {
            p.true_input = up[k] * vertical_rad_s;
            p.conditions.specific_force_m_s2 = up[k] * g_m_s2;
            obs.segment_truth[*i] = crate::fit::SegmentTruth {
                specific_force_m_s2: (up[k] * g_m_s2).into(),
                angular_rate_rad_s: p.true_input.into(),
                temp_c: p.conditions.temp_c,
                time_since_power_on_s: p.conditions.time_since_power_on_s,
            };
        }
        let mut gyro_points = floored_points(&obs.points(Triad::Gyro), &wb.gyro_floor, rate, &n);
        for (p, u) in gyro_points.iter_mut().zip(&up) {
            for a in 0..3 {
                p.std_error[a] = (p.std_error[a].powi(2) + earth_var(u, a)).sqrt();
            }
        }
        wb.gyro_points = gyro_points;
        let pose_segs: Vec<&crate::segment::Segment> = poses
            .iter()
            .map(|&i| &obs.segmentation.segments[i])
            .collect();
        let conditions: Vec<imu_model::Conditions> = pose_segs
            .iter()
            .map(|s| pose_conditions(series, s))
            .collect();
        (wb.moves, wb.moves_skipped) =
            crate::reference_free::prepare_moves(series, &pose_segs, &up, &conditions, g_m_s2);
        wb.obs = obs;
        Ok(wb)
    }

    /// The series under study.
    pub fn series(&self) -> &ImuSeries {
        self.series
    }

    /// The explanatory signals (true input, specific force, temperature, time since power-on,
    /// rotation rate, table angle) per observation of `triad`, as (name with unit, values), the
    /// values in the order of [`TriadDiagnosis::segments`]; the names are those of
    /// [`Correlate::signal`].
    pub fn signal_values(&self, triad: Triad) -> Vec<(String, Vec<f64>)> {
        let (points, _, _) = self.points(triad);
        signals(points, triad)
    }

    fn points(&self, t: Triad) -> (&[FitPoint], &[usize], &NoiseFloor) {
        if t == Triad::Gyro {
            (&self.gyro_points, &self.gyro_index, &self.gyro_floor)
        } else {
            (&self.accel_points, &self.accel_index, &self.accel_floor)
        }
    }

    fn fit_opts(&self, t: Triad) -> FitOptions {
        FitOptions {
            fixed: Vec::new(),
            bias_drift: None,
            drift_model: false,
            shared_noise: Some(self.shared(t)),
            ..self.opts.fit.clone()
        }
    }

    /// The gravity-magnitude observations when `t` is the accel of a reference-free workbench.
    fn magnitude(&self, t: Triad) -> Option<&Magnitude> {
        self.magnitude.as_ref().filter(|_| t == Triad::Accel)
    }

    /// Number of residuals of `t`: three per segment, one per pose for gravity magnitudes.
    fn n_residuals(&self, t: Triad) -> usize {
        let (points, _, _) = self.points(t);
        if self.magnitude(t).is_some() {
            points.len()
        } else {
            3 * points.len()
        }
    }

    /// Noise parameters profiled out of every fit of `t`: a white scale and a random walk per
    /// axis, or one of each for gravity magnitudes.
    fn n_profiled(&self, t: Triad) -> f64 {
        if self.magnitude(t).is_some() {
            2.0
        } else {
            6.0
        }
    }

    /// Generalised chi-square per axis of residuals `res` of `t` under the floor plus `shared`.
    fn chi2_axes(&self, t: Triad, res: &[[f64; 3]], shared: &[SharedNoise; 3]) -> [f64; 3] {
        let (points, _, _) = self.points(t);
        match self.magnitude(t) {
            Some(mag) => mag.chi2(res, points, shared),
            None => floor_chi2(res, points, shared),
        }
    }

    /// Expected residual RMS per axis of a fit of `t` with raw Jacobian `x`.
    fn expected_rms(&self, t: Triad, x: &DMatrix<f64>, shared: &[SharedNoise; 3]) -> [f64; 3] {
        let (points, _, _) = self.points(t);
        match self.magnitude(t) {
            Some(mag) => mag.expected_rms(points, x, shared),
            None => expected_residual_rms(points, x, shared),
        }
    }

    /// The noise the segment means of `t` share: the floor's flicker at the median segment
    /// duration (no random walk: the tests profile it).
    fn shared(&self, t: Triad) -> [SharedNoise; 3] {
        let (_, index, floor) = self.points(t);
        let rate = self.series.sample_rate_hz();
        let mut d: Vec<f64> = index
            .iter()
            .map(|&i| self.obs.segmentation.segments[i].n as f64 / rate)
            .collect();
        d.sort_by(f64::total_cmp);
        let tau = d.get(d.len() / 2).copied().unwrap_or(1.0);
        std::array::from_fn(|a| SharedNoise {
            random_walk_q: 0.0,
            random_walk_origin_s: None,
            flicker_tau_max_s: None,
            flicker_var: floor.flicker_var[a],
            flicker_tau_s: tau,
        })
    }

    /// The model actually fittable on this recording for `triad` (gyro gains held without
    /// plateaus), and a note when something was held.
    pub fn fittable(&self, triad: Triad, model: &TriadModel) -> (TriadModel, Option<String>) {
        if triad == Triad::Gyro && self.magnitude.is_some() {
            use crate::reference_free::GYRO_GAIN_KINDS;
            let gains: Vec<EffectKind> = model
                .kinds()
                .into_iter()
                .filter(|k| GYRO_GAIN_KINDS.contains(k))
                .collect();
            if gains.is_empty() {
                return (model.clone(), None);
            }
            let mut m = model.clone();
            for k in &gains {
                m.remove(*k);
            }
            let note = format!(
                "gyro {} come from the moves between poses (imu-calibrate --reference-free), not \
                 from the still poses held against the model here",
                gains.iter().map(|k| k.id()).collect::<Vec<_>>().join(", ")
            );
            return (m, Some(note));
        }
        if triad == Triad::Gyro {
            self.obs.gyro_model_for(model)
        } else {
            (model.clone(), None)
        }
    }

    /// Fit with the residuals' white scale and bias wander per axis profiled out (their
    /// maximum-likelihood values alternated with the parameter fit): a slow wander of the
    /// bias, whatever its size, is then part of the noise model of every candidate alike.
    /// `family` fixes the wander's kind per axis (extra flicker when true, else a random walk);
    /// None lets the first pass choose.
    fn fit(
        &self,
        triad: Triad,
        model: &TriadModel,
        family: Option<[bool; 3]>,
    ) -> Result<Profiled, FitError> {
        if let Some(mag) = self.magnitude(triad) {
            return self.fit_magnitude(mag, model, family.map(|f| f[0]));
        }
        let mut family = family;
        let (points, _, _) = self.points(triad);
        let shared = self.shared(triad);
        let mut scale = [1.0_f64; 3];
        let mut wander = [Wander::default(); 3];
        let mut m = model.clone();
        let mut last: Option<Profiled> = None;
        for _ in 0..5 {
            let pts: Vec<FitPoint> = points
                .iter()
                .map(|p| {
                    let mut q = p.clone();
                    for (a, sc) in scale.iter().enumerate() {
                        q.std_error[a] *= sc.sqrt();
                    }
                    q
                })
                .collect();
            let opts = FitOptions {
                shared_noise: Some(std::array::from_fn(|a| {
                    wander[a].scaled(&shared[a], scale[a])
                })),
                ..self.fit_opts(triad)
            };
            let fit = fit_triad(&m, triad, &pts, &opts)?;
            m = fit.model.clone();
            let mut loglik = 0.0;
            let mut next_scale = scale;
            let mut next_wander = wander;
            for a in 0..3 {
                let r: Vec<f64> = fit.residuals.iter().map(|v| v[a]).collect();
                let (sa, wa, ll) = profile_axis(&r, points, a, &shared[a], family.map(|f| f[a]));
                next_scale[a] = sa;
                next_wander[a] = wa;
                loglik += ll;
            }
            let settled = (0..3).all(|a| {
                (next_scale[a] / scale[a] - 1.0).abs() < 1e-3 && next_wander[a].near(&wander[a])
            });
            scale = next_scale;
            wander = next_wander;
            // The family chosen on the first pass is kept while the fit settles.
            family = Some(family.unwrap_or(wander.map(|w| w.flicker)));
            let done = settled;
            last = Some(Profiled {
                fit,
                loglik,
                scale,
                wander,
            });
            if done {
                break;
            }
        }
        Ok(last.expect("at least one iteration"))
    }

    /// The reference-free accel fit: `g - |corrected mean|` at every pose, generalised least
    /// squares under the magnitude covariance, with one white scale and one random walk
    /// profiled out (alternated with the fit, as in [`Self::fit`]). The rotation gauge (accel
    /// misalignment `xy`, `xz`, `yz`) is held at 0: the accelerometer axes define the frame.
    fn fit_magnitude(
        &self,
        mag: &Magnitude,
        model: &TriadModel,
        family: Option<bool>,
    ) -> Result<Profiled, FitError> {
        let mut family = family;
        use crate::reference_free::{GAUGE, conditioning_warnings, store_std_errors};
        use imu_stats::lsq::{LsqError, LsqOptions, jacobian, least_squares};
        let triad = Triad::Accel;
        let points = &self.accel_points;
        let n = points.len();
        let shared = self.shared(triad);
        let names = model.param_names(triad);
        let units = model.param_units(triad);
        let gauge: Vec<usize> = GAUGE
            .iter()
            .filter_map(|g| names.iter().position(|x| x == g))
            .collect();
        let mut p = model.params();
        let mut fixed = vec![false; names.len()];
        for &i in &gauge {
            p[i] = 0.0;
            fixed[i] = true;
        }
        let lsq = LsqOptions {
            max_iterations: self.opts.fit.max_iterations,
            tolerance: self.opts.fit.tolerance,
            min_eigenvalue: self.opts.fit.min_eigenvalue,
            ..LsqOptions::default()
        };
        let cov = |w: Wander| mag.covariance(points, &shared.map(|s| w.scaled(&s, 1.0)));
        let white = cov(Wander::default()).diagonal().mean();
        let wander_units = (white / span_s(points).max(1e-9), white);
        let (mut scale, mut rho) = (1.0_f64, Wander::default());
        let mut last: Option<Profiled> = None;
        for _ in 0..5 {
            let ch = (cov(rho) * scale)
                .cholesky()
                .ok_or(FitError::BadObservation { triad, index: 0 })?;
            let l = ch.l();
            let mut work = model.clone();
            let whitened = |q: &[f64]| {
                work.set_params(q);
                let e = mag.residuals(&work, points);
                l.solve_lower_triangular(&e).unwrap_or(e)
            };
            let sol = least_squares(whitened, &p, &fixed, &names, &lsq).map_err(|e| match e {
                LsqError::TooFewResiduals {
                    n_residuals,
                    n_free,
                } => FitError::TooFewObservations {
                    triad,
                    n_points: n,
                    n_obs: n_residuals,
                    n_free,
                },
                _ => FitError::NothingToFit { triad },
            })?;
            let mut m = model.clone();
            m.set_params(&sol.params);
            let mut raw = |q: &[f64]| {
                let mut w = model.clone();
                w.set_params(q);
                mag.residuals(&w, points)
            };
            let x = jacobian(&mut raw, &sol.params, &sol.free);
            let e = mag.residuals(&m, points);
            let (next_scale, next_rho, loglik) =
                profile_wander(e.as_slice(), cov, wander_units, family);
            family = Some(next_rho.flicker);
            let residuals: Vec<[f64; 3]> = e
                .iter()
                .zip(&mag.dirs)
                .map(|(v, u)| (u * *v).into())
                .collect();
            let residual_rms: [f64; 3] = std::array::from_fn(|a| {
                (residuals.iter().map(|r| r[a] * r[a]).sum::<f64>() / n.max(1) as f64).sqrt()
            });
            store_std_errors(&mut m, &sol.std_errors, &gauge);
            m.residual_rms = Some(residual_rms);
            let mut unobservable: Vec<Unobservable> = gauge
                .iter()
                .map(|&i| Unobservable {
                    name: names[i].clone(),
                    reason: "gauge: the gravity magnitude cannot see a rotation of the whole \
                             frame; held at 0 so that the accelerometer axes define the frame"
                        .into(),
                })
                .collect();
            unobservable.extend(sol.unobservable.iter().cloned());
            let chi2_axis = mag.split(sol.chi2, e.as_slice(), &cov(rho));
            let fit = FitResult {
                triad,
                model: m,
                names: names.clone(),
                units: units.clone(),
                params: sol.params.clone(),
                std_errors: sol.std_errors.clone(),
                correlation: sol.correlation.clone(),
                free: sol.free.clone(),
                unobservable,
                residual_rms,
                residuals,
                jacobian_raw: x,
                chi2: sol.chi2,
                chi2_axis,
                dof: sol.dof,
                reduced_chi2: sol.reduced_chi2,
                drift_random_walk: [0.0; 3],
                iterations: sol.iterations,
                converged: sol.converged,
                warnings: conditioning_warnings(
                    triad,
                    &sol,
                    &names,
                    crate::reference_free::ReferenceFreeOptions::default().weak_eigenvalue,
                    "poses",
                ),
            };
            let settled = (next_scale / scale - 1.0).abs() < 1e-3 && next_rho.near(&rho);
            scale = next_scale;
            rho = next_rho;
            p = sol.params;
            last = Some(Profiled {
                fit,
                loglik,
                scale: [scale; 3],
                wander: [rho; 3],
            });
            if settled {
                break;
            }
        }
        Ok(last.expect("at least one iteration"))
    }

    /// Fit with several starts for effects with a time constant; keep the most likely.
    fn fit_candidate(
        &self,
        triad: Triad,
        model: &TriadModel,
        added: EffectKind,
        family: [bool; 3],
    ) -> Option<Profiled> {
        let (points, _, _) = self.points(triad);
        let span = points
            .iter()
            .map(|p| p.conditions.time_since_power_on_s)
            .fold(0.0, f64::max);
        let mut best: Option<Profiled> = None;
        let mut consider = |r: Profiled| {
            if best.as_ref().is_none_or(|b| r.loglik > b.loglik) {
                best = Some(r);
            }
        };
        let starts = start_values(added, span);
        if starts.is_empty() {
            if let Ok(r) = self.fit(triad, model, Some(family)) {
                // A nonlinear parameter whose neutral start gives a zero column is refitted
                // from the first solution.
                if r.fit
                    .unobservable
                    .iter()
                    .any(|u| u.reason.contains("zero Jacobian"))
                    && let Ok(r2) = self.fit(triad, &r.fit.model, Some(family))
                {
                    consider(r2);
                }
                consider(r);
            }
        } else {
            for tau in starts {
                let mut m = model.clone();
                let names = m.param_names(triad);
                let mut p = m.params();
                // Give the time constant its start and a small amplitude so it is excited.
                for (i, n) in names.iter().enumerate() {
                    if n.ends_with("tau_s") {
                        p[i] = tau;
                    } else if n.starts_with(added.id()) {
                        p[i] = 1e-9;
                    }
                }
                m.set_params(&p);
                if let Ok(r) = self.fit(triad, &m, Some(family)) {
                    consider(r);
                }
            }
        }
        best
    }

    /// Holds `model` against the recording's `triad`: verdict, residuals, structure, and every
    /// library effect not in the model tried as a candidate.
    pub fn diagnose(
        &self,
        triad: Triad,
        model: &TriadModel,
    ) -> Result<TriadDiagnosis, DiagnoseError> {
        let full_model = model.clone();
        let (model, _) = self.fittable(triad, model);
        let profiled = self.fit(triad, &model, None)?;
        let family = profiled.wander.map(|w| w.flicker);
        let base = profiled.fit.clone();
        let (points, index, floor) = self.points(triad);
        let n = points.len();
        let dof = base.dof;
        // The verdict holds the residuals against the floor measured in the segments (white and
        // flicker); a random walk the segments cannot resolve is not assumed (the candidate
        // tests profile it).
        let shared = self.shared(triad);
        let chi2_axis = self.chi2_axes(triad, &base.residuals, &shared);
        let chi2: f64 = chi2_axis.iter().sum();
        let p_value = distributions::chi2_sf(chi2, dof as f64);
        let axis_dof: [f64; 3] = match self.magnitude(triad) {
            // One residual per pose, shared by the axes by their squared direction cosines.
            Some(mag) => std::array::from_fn(|a| {
                let share = mag.dirs.iter().map(|u| u[a] * u[a]).sum::<f64>() / n.max(1) as f64;
                (share * dof as f64).max(1.0)
            }),
            None => [(n as f64 - base.free.len() as f64 / 3.0).max(1.0); 3],
        };
        let floor_expected = self.expected_rms(triad, &base.jacobian_raw, &shared);
        let axes: [AxisVerdict; 3] = std::array::from_fn(|a| {
            let dof_a = axis_dof[a];
            AxisVerdict {
                residual_rms: base.residual_rms[a],
                noise_floor_rms: floor_expected[a],
                noise_floor_with_drift_rms: 0.0,
                chi2: chi2_axis[a],
                dof: dof_a,
                p_value: distributions::chi2_sf(chi2_axis[a], dof_a),
            }
        });
        let magnitude_sd: Option<Vec<f64>> = self.magnitude(triad).map(|mag| {
            let c = mag.covariance(points, &shared);
            (0..n).map(|k| c[(k, k)].max(0.0).sqrt()).collect()
        });
        let segments: Vec<SegmentResidual> = points
            .iter()
            .zip(index)
            .zip(&base.residuals)
            .enumerate()
            .map(|(k, ((p, &i), r))| {
                let s = &self.obs.segmentation.segments[i];
                let fl: [f64; 3] = match (&magnitude_sd, self.magnitude(triad)) {
                    // The magnitude's noise, split like the residual along the pose's direction.
                    (Some(sd), Some(mag)) => {
                        std::array::from_fn(|a| (sd[k] * mag.dirs[k][a].abs()).max(1e-300))
                    }
                    _ => [p.std_error[0], p.std_error[1], p.std_error[2]],
                };
                SegmentResidual {
                    segment: i,
                    kind: s.kind,
                    start_s: s.start_s,
                    end_s: s.end_s,
                    residual: *r,
                    floor: fl,
                    z: std::array::from_fn(|a| r[a] / fl[a]),
                }
            })
            .collect();
        let mut worst: Vec<usize> = (0..segments.len()).collect();
        let zmax = |s: &SegmentResidual| s.z.iter().map(|v| v.abs()).fold(0.0, f64::max);
        worst.sort_by(|&a, &b| zmax(&segments[b]).total_cmp(&zmax(&segments[a])));
        worst.truncate(5);
        let signals = signals(points, triad);
        let structure = std::array::from_fn(|a| residual_structure(&segments, &signals, a));
        let spectral_lines = self.spectral[usize::from(triad == Triad::Gyro)].clone();

        // Candidates.
        let excess = (chi2 - dof as f64).max(1e-12);
        let n_obs = self.n_residuals(triad) as f64;
        let base_pattern: Vec<f64> = normalised(&base.residuals, points);
        let mut candidates: Vec<Candidate> = EffectKind::ALL
            .into_iter()
            .filter(|k| k.applies_to(triad) && !model.has(*k))
            .filter_map(|k| {
                let mut m = model.clone();
                m.add(k);
                let (m, held) = self.fittable(triad, &m);
                if !m.has(k) {
                    return Some(unobservable_candidate(
                        k,
                        triad,
                        held.unwrap_or_else(|| "not fittable on this recording".into()),
                    ));
                }
                let prof = self.fit_candidate(triad, &m, k, family)?;
                let r = prof.fit.clone();
                let new_params = r.free.len().saturating_sub(base.free.len());
                let not_obs: Vec<String> = r
                    .unobservable
                    .iter()
                    .filter(|u| u.name.starts_with(k.id()))
                    .map(|u| format!("{}: {}", u.name, u.reason))
                    .collect();
                if new_params == 0 || r.dof == 0 {
                    let mut c = unobservable_candidate(k, triad, not_obs.join("; "));
                    c.not_observable = not_obs;
                    return Some(c);
                }
                // Likelihood ratio with the noise scale and drift profiled in both models, as an
                // F statistic (exact for a linear model with one profiled scale).
                let lr = (2.0 * (prof.loglik - profiled.loglik)).max(0.0);
                let dof2 = (n_obs - r.free.len() as f64 - self.n_profiled(triad)).max(1.0);
                let f = (lr / n_obs).exp_m1() * dof2 / new_params as f64;
                let p = distributions::f_sf(f, new_params as f64, dof2);
                if p >= self.opts.alpha {
                    // Not significant, and its values say nothing: show why instead of them.
                    let weak = barely_excited(k, &r, span_s(points));
                    if !weak.is_empty() {
                        let mut c = unobservable_candidate(k, triad, weak.join("; "));
                        c.not_observable = weak;
                        return Some(c);
                    }
                }
                let cand_chi2: f64 = self.chi2_axes(triad, &r.residuals, &shared).iter().sum();
                let d_chi2 = (chi2 - cand_chi2).max(0.0);
                let pattern: Vec<f64> = normalised(&r.residuals, points)
                    .iter()
                    .zip(&base_pattern)
                    .map(|(a, b)| b - a)
                    .collect();
                let params = effect_params(&r, k);
                Some(Candidate {
                    effect: k,
                    triad,
                    new_params,
                    not_observable: not_obs,
                    chi2: cand_chi2,
                    dof: r.dof,
                    f,
                    p_value: p,
                    delta_aic: lr - 2.0 * new_params as f64,
                    share_of_excess: d_chi2 / excess,
                    residual_rms: r.residual_rms,
                    significant: p < self.opts.alpha,
                    claimed: false,
                    explanation: explain(k, triad, &params, &r),
                    model_change: model_change(triad, &r.model, k),
                    params,
                    fit: Some(r),
                    pattern,
                })
            })
            .collect();
        let consistent_before = p_value >= self.opts.alpha;
        let mut ambiguities = rank_and_claim(&mut candidates, consistent_before, triad, &self.opts);
        let wander: [Wander; 3] =
            std::array::from_fn(|a| profiled.wander[a].absolute(profiled.scale[a]));
        let with_drift: [SharedNoise; 3] = std::array::from_fn(|a| wander[a].added(&shared[a]));
        let chi2_drift: f64 = self
            .chi2_axes(triad, &base.residuals, &with_drift)
            .iter()
            .sum();
        let mut drift_params = wander.iter().filter(|w| !w.is_none()).count();
        if self.magnitude(triad).is_some() {
            // One wander, common to the axes.
            drift_params = drift_params.min(1);
        }
        let p_value_with_drift =
            distributions::chi2_sf(chi2_drift, dof.saturating_sub(drift_params).max(1) as f64);
        let mut axes = axes;
        let with_drift_expected = self.expected_rms(triad, &base.jacobian_raw, &with_drift);
        for (a, v) in axes.iter_mut().enumerate() {
            v.noise_floor_with_drift_rms = with_drift_expected[a];
        }
        let mut consistent = consistent_before && spectral_lines.is_empty();
        let mut consistent_with_drift = (consistent_before
            || p_value_with_drift >= self.opts.alpha)
            && spectral_lines.is_empty();
        let mut verdict = verdict_text(
            triad,
            &model,
            consistent_before,
            (p_value_with_drift >= self.opts.alpha).then_some((p_value_with_drift, wander)),
            p_value,
            &axes,
            &candidates,
            &ambiguities,
            &structure,
            &spectral_lines,
        );
        let mut base = base;
        let mut moves = None;
        if triad == Triad::Gyro && self.magnitude.is_some() {
            // Reference-free: the gains are held against the moves between poses.
            let m = self.diagnose_moves(&full_model, &base.model)?;
            consistent &= m.verdict.consistent;
            consistent_with_drift &= m.verdict.consistent;
            let _ = write!(verdict, " {}", m.text);
            // Every model handed on (to the ladder, into the calibration) is the whole gyro
            // model: the offsets from the still poses, the gains from the moves.
            base.model = merged(&full_model, &[&base.model, &m.gains]);
            for c in &mut candidates {
                if let Some(f) = c.fit.as_mut() {
                    let mut spec = full_model.clone();
                    spec.add(c.effect);
                    f.model = merged(&spec, &[&f.model, &m.gains]);
                }
            }
            candidates.extend(m.candidates);
            sort_candidates(&mut candidates);
            ambiguities.extend(m.ambiguities);
            moves = Some(m.verdict);
        }
        Ok(TriadDiagnosis {
            triad,
            effects: model.kinds(),
            noise_scale: profiled.scale,
            drift_random_walk: wander.map(|w| w.random_walk_q.sqrt()),
            drift_bias_instability: wander.map(|w| w.bias_instability()),
            chi2,
            dof,
            p_value,
            consistent,
            consistent_with_drift,
            p_value_with_drift,
            axes,
            segments,
            worst,
            structure,
            spectral_lines,
            candidates,
            ambiguities,
            verdict,
            fit: base,
            noise_floor: floor.clone(),
            moves,
        })
    }

    /// Reference-free: the gyro gain effects of `full` fitted to the rotations integrated over
    /// the moves between poses, their verdict against the moves' noise, and every library gain
    /// effect not in the model tried as a candidate (F test with the scale profiled, AIC,
    /// share of the excess). `offsets` is the still-pose fit (its values join each candidate's
    /// model).
    fn diagnose_moves(
        &self,
        full: &TriadModel,
        offsets: &TriadModel,
    ) -> Result<MovesDiagnosis, DiagnoseError> {
        use crate::reference_free::{GYRO_GAIN_KINDS, fit_gains};
        let triad = Triad::Gyro;
        let gain_model = |kinds: &[EffectKind]| {
            let mut g = TriadModel::default();
            for k in kinds {
                g.add(*k);
            }
            merged(&g, &[full])
        };
        let kinds: Vec<EffectKind> = full
            .kinds()
            .into_iter()
            .filter(|k| GYRO_GAIN_KINDS.contains(k))
            .collect();
        let lsq = imu_stats::lsq::LsqOptions {
            max_iterations: self.opts.fit.max_iterations,
            tolerance: self.opts.fit.tolerance,
            min_eigenvalue: self.opts.fit.min_eigenvalue,
            ..imu_stats::lsq::LsqOptions::default()
        };
        let n_res = 2 * self.moves.len();
        // Whitened residuals of a gain model (nothing fitted when it has no parameters).
        let whitened = |g: &TriadModel| -> Vec<f64> {
            self.moves
                .iter()
                .flat_map(|m| m.residual(g).map(|v| v / m.sigma_rad))
                .collect()
        };
        let raw_rms = |g: &TriadModel| -> f64 {
            let sq: f64 = self
                .moves
                .iter()
                .map(|m| m.residual(g).iter().map(|v| v * v).sum::<f64>())
                .sum();
            (sq / n_res.max(1) as f64).sqrt()
        };
        let fit =
            |g: &TriadModel| -> Result<(TriadModel, Option<imu_stats::lsq::LsqSolution>), FitError> {
                if g.n_params() == 0 {
                    return Ok((g.clone(), None));
                }
                let sol = fit_gains(&self.moves, g, &vec![false; g.n_params()], &lsq).map_err(
                    |e| match e {
                        imu_stats::lsq::LsqError::TooFewResiduals {
                            n_residuals,
                            n_free,
                        } => FitError::TooFewObservations {
                            triad,
                            n_points: self.moves.len(),
                            n_obs: n_residuals,
                            n_free,
                        },
                        _ => FitError::NothingToFit { triad },
                    },
                )?;
                let mut m = g.clone();
                m.set_params(&sol.params);
                Ok((m, Some(sol)))
            };
        let chi2_of = |g: &TriadModel| whitened(g).iter().map(|v| v * v).sum::<f64>();
        let (gains, sol0) = fit(&gain_model(&kinds))?;
        let free0 = sol0.as_ref().map_or(0, |s| s.free.len());
        let chi2_0 = chi2_of(&gains);
        let dof_0 = n_res.saturating_sub(free0).max(1);
        let p0 = distributions::chi2_sf(chi2_0, dof_0 as f64);
        let expected_rms_rad = (self
            .moves
            .iter()
            .map(|m| m.sigma_rad * m.sigma_rad)
            .sum::<f64>()
            / self.moves.len().max(1) as f64)
            .sqrt();
        let verdict = MovesVerdict {
            n_moves: self.moves.len(),
            skipped: self.moves_skipped,
            effects: kinds.clone(),
            residual_rms_rad: raw_rms(&gains),
            expected_rms_rad,
            chi2: chi2_0,
            dof: dof_0,
            p_value: p0,
            consistent: p0 >= self.opts.alpha,
        };
        let base_pattern = whitened(&gains);
        let excess = (chi2_0 - dof_0 as f64).max(1e-12);
        let mut candidates: Vec<Candidate> = GYRO_GAIN_KINDS
            .into_iter()
            .filter(|k| !kinds.contains(k))
            .map(|k| {
                let mut with = kinds.clone();
                with.push(k);
                let Ok((g, Some(sol))) = fit(&gain_model(&with)) else {
                    return unobservable_candidate(k, triad, "the moves cannot fit it".into());
                };
                let new_params = sol.free.len().saturating_sub(free0);
                let not_obs: Vec<String> = sol
                    .unobservable
                    .iter()
                    .filter(|u| u.name.starts_with(k.id()))
                    .map(|u| format!("{}: {}", u.name, u.reason))
                    .collect();
                if new_params == 0 || sol.dof == 0 {
                    let mut c = unobservable_candidate(k, triad, not_obs.join("; "));
                    c.not_observable = not_obs;
                    return c;
                }
                let chi2_1 = chi2_of(&g).max(1e-300);
                let f = ((chi2_0 - chi2_1).max(0.0) / new_params as f64)
                    / (chi2_1 / sol.dof.max(1) as f64);
                let p = distributions::f_sf(f, new_params as f64, sol.dof.max(1) as f64);
                let lr = n_res as f64 * (chi2_0 / chi2_1).ln();
                let pattern: Vec<f64> = whitened(&g)
                    .iter()
                    .zip(&base_pattern)
                    .map(|(a, b)| b - a)
                    .collect();
                let rms = raw_rms(&g);
                let residuals: Vec<[f64; 3]> = self
                    .moves
                    .iter()
                    .map(|m| {
                        let [a, b] = m.residual(&g);
                        [a, b, 0.0]
                    })
                    .collect();
                let mut spec = full.clone();
                spec.add(k);
                let r = FitResult {
                    triad,
                    model: merged(&spec, &[offsets, &g]),
                    names: g.param_names(triad),
                    units: g.param_units(triad),
                    params: sol.params.clone(),
                    std_errors: sol.std_errors.clone(),
                    correlation: sol.correlation.clone(),
                    free: sol.free.clone(),
                    unobservable: sol.unobservable.clone(),
                    residual_rms: [rms; 3],
                    residuals,
                    jacobian_raw: DMatrix::zeros(0, 0),
                    chi2: chi2_1,
                    chi2_axis: [chi2_1 / 3.0; 3],
                    dof: sol.dof,
                    reduced_chi2: sol.reduced_chi2,
                    drift_random_walk: [0.0; 3],
                    iterations: sol.iterations,
                    converged: sol.converged,
                    warnings: Vec::new(),
                };
                let params = effect_params(&r, k);
                let best = params
                    .iter()
                    .max_by(|a, b| {
                        let t = |p: &ParamValue| p.std_error.map_or(0.0, |s| (p.value / s).abs());
                        t(a).total_cmp(&t(b))
                    })
                    .map(|p| {
                        format!(
                            " ({} = {:.3e}{} {})",
                            p.name,
                            p.value,
                            p.std_error
                                .map_or(String::new(), |e| format!(" +/- {e:.1e}")),
                            p.unit
                        )
                    })
                    .unwrap_or_default();
                Candidate {
                    effect: k,
                    triad,
                    new_params,
                    not_observable: not_obs,
                    chi2: chi2_1,
                    dof: sol.dof,
                    f,
                    p_value: p,
                    delta_aic: lr - 2.0 * new_params as f64,
                    share_of_excess: (chi2_0 - chi2_1).max(0.0) / excess,
                    residual_rms: [rms; 3],
                    significant: p < self.opts.alpha,
                    claimed: false,
                    explanation: format!(
                        "{}{best}: the rotations integrated over the moves between poses \
                         need it; direction error after the moves {:.2e} rad RMS with it, \
                         {:.2e} rad without",
                        k.description(),
                        rms,
                        verdict.residual_rms_rad
                    ),
                    model_change: model_change(triad, &r.model, k),
                    params,
                    fit: Some(r),
                    pattern,
                }
            })
            .collect();
        let ambiguities = rank_and_claim(&mut candidates, verdict.consistent, triad, &self.opts);
        let mut text = format!(
            "Gyro gains [{}] against {} moves between poses: direction error {:.2e} rad RMS vs \
             {:.2e} expected (p = {:.1e}): {}.",
            kinds.iter().map(|k| k.id()).collect::<Vec<_>>().join(", "),
            verdict.n_moves,
            verdict.residual_rms_rad,
            verdict.expected_rms_rad,
            p0,
            if verdict.consistent {
                "consistent"
            } else {
                "NOT consistent"
            }
        );
        if let Some(c) = candidates.iter().find(|c| c.claimed) {
            let _ = write!(
                text,
                " Missing gain effect: {} (F-test p = {:.1e}, explains {:.0} % of the excess).",
                c.explanation,
                c.p_value,
                100.0 * c.share_of_excess.min(1.0)
            );
        }
        Ok(MovesDiagnosis {
            verdict,
            candidates,
            ambiguities,
            gains,
            text,
        })
    }

    /// The ladder: from `base` (accel and gyro models), repeatedly add the best claimed effect
    /// of a triad that is not yet consistent with its noise floor, until both are consistent
    /// or nothing more is claimed.
    pub fn ladder(&self, base: &imu_model::Calibration) -> Result<Ladder, DiagnoseError> {
        let mut models = [base.accel.clone(), base.gyro.clone()];
        let triads = [Triad::Accel, Triad::Gyro];
        let mut steps = Vec::new();
        let mut added: Vec<(Triad, EffectKind)> = Vec::new();
        loop {
            let diags = [
                self.diagnose(Triad::Accel, &models[0])?,
                self.diagnose(Triad::Gyro, &models[1])?,
            ];
            steps.push(LadderStep {
                added: added.last().copied(),
                accel: StepSummary::of(&diags[0]),
                gyro: StepSummary::of(&diags[1]),
            });
            let pick = diags
                .iter()
                .enumerate()
                .filter_map(|(i, d)| d.candidates.iter().find(|c| c.claimed).map(|c| (i, c)))
                .max_by(|a, b| a.1.delta_aic.total_cmp(&b.1.delta_aic));
            let Some((i, c)) = pick else {
                let (calibration, notes) = self.final_calibration(base, &diags);
                return Ok(Ladder {
                    steps,
                    final_diagnoses: diags,
                    calibration,
                    notes,
                });
            };
            if steps.len() > self.opts.max_steps {
                let (calibration, notes) = self.final_calibration(base, &diags);
                return Ok(Ladder {
                    steps,
                    final_diagnoses: diags,
                    calibration,
                    notes,
                });
            }
            added.push((triads[i], c.effect));
            models[i] = c
                .fit
                .as_ref()
                .map(|f| f.model.clone())
                .expect("claimed candidates carry their fit");
        }
    }

    fn final_calibration(
        &self,
        base: &imu_model::Calibration,
        diags: &[TriadDiagnosis; 2],
    ) -> (imu_model::Calibration, Vec<String>) {
        let mut notes = self.notes.clone();
        let mut cal = base.clone();
        cal.accel = diags[0].fit.model.clone();
        cal.gyro = diags[1].fit.model.clone();
        if self.magnitude.is_none() {
            // A model imud would reject (e.g. a cubic term extrapolated over the full range) is
            // refitted with the offending parameter held, as imu-calibrate does.
            for (d, t) in diags.iter().zip([Triad::Accel, Triad::Gyro]) {
                if d.fit.model.validate(t).is_ok() {
                    continue;
                }
                let (points, _, _) = self.points(t);
                let one = crate::fit::Sessions::default();
                match crate::fit::fit_loadable(&d.fit.model, t, points, &one, &self.fit_opts(t)) {
                    Ok(r) => {
                        notes.extend(
                            r.unobservable
                                .iter()
                                .map(|u| format!("{t} {}: {}", u.name, u.reason)),
                        );
                        *cal.triad_mut(t) = r.model;
                    }
                    Err(e) => notes.push(format!("{t}: {e}")),
                }
            }
        }
        if let Some(mag) = &self.magnitude {
            // Reference-free: the gyro gains come from the moves; the final model (the
            // ladder's accel and gyro offsets, the base's gyro gains) is calibrated as
            // imu-calibrate --reference-free does.
            let o = crate::reference_free::ReferenceFreeOptions {
                accel: diags[0].fit.model.clone(),
                gyro: diags[1].fit.model.clone(),
                gravity_m_s2: mag.gravity_m_s2,
                latitude_deg: mag.latitude_deg,
                segment: self.opts.segment.clone(),
                ..Default::default()
            };
            match crate::reference_free::calibrate_reference_free(self.series, &o) {
                Ok(f) => {
                    cal.accel = f.calibration.accel;
                    cal.gyro = f.calibration.gyro;
                    for n in f.notes {
                        if !notes.contains(&n) {
                            notes.push(n);
                        }
                    }
                }
                Err(e) => notes.push(format!(
                    "the reference-free calibration of the final model failed ({e}): the \
                     calibration holds the workbench's accel and gyro offset fits and the base \
                     model's gyro gains as given"
                )),
            }
        }
        (cal, notes)
    }
}

/// One rung of the ladder.
#[derive(Clone, Debug, Serialize)]
pub struct LadderStep {
    /// The effect added at this step (None for the base model).
    pub added: Option<(Triad, EffectKind)>,
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
    /// The final model's diagnoses (accel, gyro).
    pub final_diagnoses: [TriadDiagnosis; 2],
    /// The final model as a calibration.
    #[serde(skip)]
    pub calibration: imu_model::Calibration,
    /// Conventions and decisions behind it (reference-free: gravity, Earth rate, gyro gains).
    pub notes: Vec<String>,
}

// ------------------------------------------------------------------------------ helpers

/// A fit with its noise scale and drift profiled out.
#[derive(Clone, Debug)]
struct Profiled {
    fit: FitResult,
    /// Gaussian log-likelihood of the residuals (constants dropped).
    loglik: f64,
    /// Residual variance over the floor's, per axis.
    scale: [f64; 3],
    /// Bias wander beyond the floor, in units of the scale, per axis.
    wander: [Wander; 3],
}

/// The bias wander between segments beyond the noise floor: a random walk (rate variance `q`)
/// or extra flicker (bias instability the segments are too short to measure), whichever the
/// residuals make likelier.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Wander {
    /// Random-walk rate variance, U^2/s.
    random_walk_q: f64,
    /// Extra flicker Allan variance floor, U^2.
    flicker_var: f64,
    /// The family: extra flicker (else a random walk).
    flicker: bool,
}

impl Wander {
    /// The floor's `shared` noise with this wander, all of it times the white `scale` (the
    /// profiled covariance).
    fn scaled(&self, shared: &SharedNoise, scale: f64) -> SharedNoise {
        SharedNoise {
            random_walk_q: scale * self.random_walk_q,
            flicker_var: scale * (shared.flicker_var + self.flicker_var),
            ..*shared
        }
    }

    /// The floor's `shared` noise (as measured) plus this wander (absolute).
    fn added(&self, shared: &SharedNoise) -> SharedNoise {
        SharedNoise {
            random_walk_q: shared.random_walk_q + self.random_walk_q,
            flicker_var: shared.flicker_var + self.flicker_var,
            ..*shared
        }
    }

    /// In absolute units, for a profiled white `scale`.
    fn absolute(&self, scale: f64) -> Wander {
        Wander {
            random_walk_q: scale * self.random_walk_q,
            flicker_var: scale * self.flicker_var,
            flicker: self.flicker,
        }
    }

    fn is_none(&self) -> bool {
        self.random_walk_q <= 0.0 && self.flicker_var <= 0.0
    }

    /// Bias instability `B` of the extra flicker (`flicker_var = (0.664 B)^2`).
    fn bias_instability(&self) -> f64 {
        self.flicker_var.max(0.0).sqrt() / imu_stats::noise_terms::BIAS_INSTABILITY_FACTOR
    }

    /// Settled: both parts within 0.1 % of `other`'s.
    fn near(&self, other: &Wander) -> bool {
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-3 * b.max(1e-300);
        close(self.random_walk_q, other.random_walk_q) && close(self.flicker_var, other.flicker_var)
    }
}

/// Maximum-likelihood white scale and bias wander of residuals `r` whose covariance with
/// wander `w` is `cov(w)` (scale 1): a random walk or extra flicker ([`profile_rho`], around
/// `units` = (random-walk rate, flicker variance) scales); `flicker` fixes the family, None
/// profiles both and keeps the likelier. Nested models are compared within one family (the
/// base model's), so that the likelihood ratio is the effect's alone.
fn profile_wander(
    r: &[f64],
    cov: impl Fn(Wander) -> DMatrix<f64>,
    units: (f64, f64),
    flicker: Option<bool>,
) -> (f64, Wander, f64) {
    let of = |flicker: bool, x: f64| Wander {
        random_walk_q: if flicker { 0.0 } else { x },
        flicker_var: if flicker { x } else { 0.0 },
        flicker,
    };
    let run = |f: bool| {
        let (scale, x, ll) = profile_rho(r, |x| cov(of(f, x)), if f { units.1 } else { units.0 });
        (scale, of(f, x), ll)
    };
    match flicker {
        Some(f) => run(f),
        None => {
            let (rw, fl) = (run(false), run(true));
            if fl.2 > rw.2 { fl } else { rw }
        }
    }
}

/// `r^T C^-1 r` and `ln |C|` for residuals `r` with covariance `c`.
fn gls(r: &[f64], c: DMatrix<f64>) -> Option<(f64, f64)> {
    let ch = c.cholesky()?;
    let logdet = 2.0 * ch.l().diagonal().iter().map(|d| d.ln()).sum::<f64>();
    let z = ch.solve(&DVector::from_column_slice(r));
    Some((r.iter().zip(z.iter()).map(|(a, b)| a * b).sum(), logdet))
}

/// Generalised chi-square per axis against the noise floor (white part from the points'
/// standard errors, shared part `shared`).
fn floor_chi2(res: &[[f64; 3]], points: &[FitPoint], shared: &[SharedNoise; 3]) -> [f64; 3] {
    std::array::from_fn(|a| {
        let r: Vec<f64> = res.iter().map(|v| v[a]).collect();
        gls(&r, segment_covariance(points, a, &shared[a], 1.0)).map_or(f64::INFINITY, |(c, _)| c)
    })
}

/// Maximum-likelihood white scale and random-walk rate (relative to the scale) of residuals
/// `r` whose covariance at rate `rho` is `cov(rho)` (scale 1), and the log-likelihood there:
/// `rho` on a log grid around `unit` refined by golden section, the scale in closed form.
fn profile_rho(r: &[f64], cov: impl Fn(f64) -> DMatrix<f64>, unit: f64) -> (f64, f64, f64) {
    let n = r.len() as f64;
    let ll = |rho: f64| -> Option<(f64, f64)> {
        let (chi2, logdet) = gls(r, cov(rho))?;
        let scale = (chi2 / n).max(1e-300);
        Some((scale, -0.5 * (n * scale.ln() + logdet + n)))
    };
    let grid: Vec<f64> = std::iter::once(0.0)
        .chain((0..=32).map(|k| unit * 10f64.powf(-4.0 + k as f64 * 0.25)))
        .collect();
    let mut best = (0.0, f64::NEG_INFINITY, 1.0);
    let mut best_k = 0;
    for (k, &rho) in grid.iter().enumerate() {
        if let Some((scale, l)) = ll(rho)
            && l > best.1
        {
            best = (rho, l, scale);
            best_k = k;
        }
    }
    if best_k > 0 {
        // Golden section in log rho between the neighbours of the best grid point.
        let lo = grid[best_k - 1].max(unit * 1e-5).ln();
        let hi = grid[(best_k + 1).min(grid.len() - 1)].ln();
        let (mut x0, mut x1) = (lo, hi);
        let g = 0.618_033_988_749_895;
        for _ in 0..30 {
            let (c, d) = (x1 - g * (x1 - x0), x0 + g * (x1 - x0));
            let lc = ll(c.exp()).map_or(f64::NEG_INFINITY, |v| v.1);
            let ld = ll(d.exp()).map_or(f64::NEG_INFINITY, |v| v.1);
            if lc > ld {
                x1 = d;
            } else {
                x0 = c;
            }
        }
        let rho = (0.5 * (x0 + x1)).exp();
        if let Some((scale, l)) = ll(rho)
            && l > best.1
        {
            best = (rho, l, scale);
        }
    }
    (best.2, best.0, best.1)
}

/// Time span of the points, s.
fn span_s(points: &[FitPoint]) -> f64 {
    points
        .iter()
        .map(|p| p.t_s)
        .fold(f64::NEG_INFINITY, f64::max)
        - points.iter().map(|p| p.t_s).fold(f64::INFINITY, f64::min)
}

/// [`profile_wander`] for one axis's residuals under [`segment_covariance`].
fn profile_axis(
    r: &[f64],
    points: &[FitPoint],
    a: usize,
    shared: &SharedNoise,
    flicker: Option<bool>,
) -> (f64, Wander, f64) {
    let n = r.len() as f64;
    let s2 = points.iter().map(|p| p.std_error[a].powi(2)).sum::<f64>() / n;
    let cov = |w: Wander| segment_covariance(points, a, &w.scaled(shared, 1.0), 1.0);
    profile_wander(r, cov, (s2 / span_s(points).max(1e-9), s2), flicker)
}

/// Expected covariance of the residuals of a generalised least-squares fit with raw Jacobian
/// `x` when the observations have covariance `c`: with the residual maker
/// `M = I - X (X^T C^-1 X)^-1 X^T C^-1`, `M C M^T` (`c` itself when `x` is empty or singular).
fn residual_covariance(c: DMatrix<f64>, x: &DMatrix<f64>) -> DMatrix<f64> {
    let big = c.nrows();
    if x.nrows() != big || x.ncols() == 0 {
        return c;
    }
    let Some(ch) = c.clone().cholesky() else {
        return c;
    };
    let cinv_x = ch.solve(x);
    let Some(info_inv) = (x.transpose() * &cinv_x).try_inverse() else {
        return c;
    };
    let m = DMatrix::identity(big, big) - x * info_inv * cinv_x.transpose();
    &m * &c * m.transpose()
}

/// RMS per axis the residuals of a fit with raw Jacobian `x` (rows `3 k + axis`) would have if
/// the model were right and the means had their own floor plus the `shared` noise. The fit is
/// generalised least squares, whose estimates (the bias above all) are not plain means when the
/// means are correlated: see [`residual_covariance`].
fn expected_residual_rms(
    points: &[FitPoint],
    x: &DMatrix<f64>,
    shared: &[SharedNoise; 3],
) -> [f64; 3] {
    let n = points.len();
    let big = 3 * n;
    let mut c = DMatrix::zeros(big, big);
    for (a, sh) in shared.iter().enumerate() {
        let ca = segment_covariance(points, a, sh, 1.0);
        for k in 0..n {
            for l in 0..n {
                c[(3 * k + a, 3 * l + a)] = ca[(k, l)];
            }
        }
    }
    let e = residual_covariance(c, x);
    std::array::from_fn(|a| {
        ((0..n).map(|k| e[(3 * k + a, 3 * k + a)]).sum::<f64>() / n.max(1) as f64)
            .max(0.0)
            .sqrt()
    })
}

// ------------------------------------------------------------------------------ magnitude

/// Accel observations without a reference (still poses in unknown orientations): only the
/// magnitude of the corrected specific force is known, local gravity. Each pose gives one
/// residual, `g - |corrected mean|`, stored as a vector along the pose's measured direction
/// (so per-axis summaries keep their meaning); its noise is the mean's per-axis noise projected
/// on that direction.
#[derive(Clone, Debug)]
struct Magnitude {
    /// Local gravity, m/s^2.
    g_m_s2: f64,
    /// Unit direction of each pose's measured specific force (order of the accel points).
    dirs: Vec<Vec3>,
    /// Local gravity as given (for the final reference-free calibration).
    gravity_m_s2: Option<f64>,
    /// Latitude as given, deg.
    latitude_deg: Option<f64>,
}

impl Magnitude {
    /// Covariance of the magnitude residuals: the per-axis covariance of the means
    /// ([`segment_covariance`]: white floor, flicker, random walk) projected on each pose's
    /// direction, `C_kl = sum_a u_ka u_la C^a_kl`.
    fn covariance(&self, points: &[FitPoint], shared: &[SharedNoise; 3]) -> DMatrix<f64> {
        let n = points.len();
        let mut c = DMatrix::zeros(n, n);
        for (a, sh) in shared.iter().enumerate() {
            let ca = segment_covariance(points, a, sh, 1.0);
            for k in 0..n {
                for l in 0..n {
                    c[(k, l)] += self.dirs[k][a] * self.dirs[l][a] * ca[(k, l)];
                }
            }
        }
        c
    }

    /// The scalar residuals of stored residual vectors.
    fn scalar(&self, res: &[[f64; 3]]) -> Vec<f64> {
        res.iter()
            .zip(&self.dirs)
            .map(|(r, u)| Vec3::from(*r).dot(u))
            .collect()
    }

    /// `chi2` split over the axes by each pose's squared direction cosines (the magnitude mixes
    /// the axes: the split is the diagonal's, the total the full generalised chi-square).
    fn split(&self, chi2: f64, e: &[f64], c: &DMatrix<f64>) -> [f64; 3] {
        let w: [f64; 3] = std::array::from_fn(|a| {
            e.iter()
                .enumerate()
                .map(|(k, v)| self.dirs[k][a].powi(2) * v * v / c[(k, k)].max(1e-300))
                .sum()
        });
        let total: f64 = w.iter().sum();
        if total > 0.0 {
            w.map(|v| chi2 * v / total)
        } else {
            [chi2 / 3.0; 3]
        }
    }

    /// Generalised chi-square (split over the axes) of stored residuals.
    fn chi2(&self, res: &[[f64; 3]], points: &[FitPoint], shared: &[SharedNoise; 3]) -> [f64; 3] {
        let e = self.scalar(res);
        let c = self.covariance(points, shared);
        match gls(&e, c.clone()) {
            Some((chi2, _)) => self.split(chi2, &e, &c),
            None => [f64::INFINITY; 3],
        }
    }

    /// Expected residual RMS per axis (as [`expected_residual_rms`], rows of `x` per pose).
    fn expected_rms(
        &self,
        points: &[FitPoint],
        x: &DMatrix<f64>,
        shared: &[SharedNoise; 3],
    ) -> [f64; 3] {
        let e = residual_covariance(self.covariance(points, shared), x);
        let n = points.len().max(1) as f64;
        std::array::from_fn(|a| {
            (self
                .dirs
                .iter()
                .enumerate()
                .map(|(k, u)| u[a] * u[a] * e[(k, k)])
                .sum::<f64>()
                / n)
                .max(0.0)
                .sqrt()
        })
    }

    /// `g - |corrected mean|` per pose under `m`.
    fn residuals(&self, m: &TriadModel, points: &[FitPoint]) -> DVector<f64> {
        DVector::from_iterator(
            points.len(),
            points
                .iter()
                .map(|p| self.g_m_s2 - m.inverse(p.measured, &p.conditions).norm()),
        )
    }
}

fn normalised(res: &[[f64; 3]], points: &[FitPoint]) -> Vec<f64> {
    res.iter()
        .zip(points)
        .flat_map(|(r, p)| (0..3).map(move |a| r[a] / p.std_error[a]))
        .collect()
}

/// `spec`'s effects with their values taken, by parameter name, from the first of `parts` that
/// has them (else `spec`'s own).
fn merged(spec: &TriadModel, parts: &[&TriadModel]) -> TriadModel {
    let t = Triad::Gyro;
    let names = spec.param_names(t);
    let mut p = spec.params();
    for (i, n) in names.iter().enumerate() {
        if let Some(v) = parts.iter().find_map(|m| {
            m.param_names(t)
                .iter()
                .position(|x| x == n)
                .map(|j| m.params()[j])
        }) {
            p[i] = v;
        }
    }
    let mut out = spec.clone();
    out.set_params(&p);
    out
}

/// Observable candidates first, by AIC improvement.
fn sort_candidates(c: &mut [Candidate]) {
    c.sort_by(|a, b| {
        (b.new_params > 0)
            .cmp(&(a.new_params > 0))
            .then(b.delta_aic.total_cmp(&a.delta_aic))
    });
}

/// Sorts `candidates`, finds the pairs this recording cannot tell apart (significant, their
/// explained patterns correlated, comparable AIC), and claims the best one when the model is
/// not `consistent` with the noise, it is significant, explains a substantial share of the
/// excess and is not confused with another.
fn rank_and_claim(
    candidates: &mut [Candidate],
    consistent: bool,
    triad: Triad,
    opts: &DiagnoseOptions,
) -> Vec<Ambiguity> {
    sort_candidates(candidates);
    let mut ambiguities = Vec::new();
    let sig: Vec<usize> = (0..candidates.len())
        .filter(|&i| candidates[i].significant)
        .collect();
    for (ai, &i) in sig.iter().enumerate() {
        for &j in &sig[ai + 1..] {
            let (ci, cj) = (&candidates[i], &candidates[j]);
            let r = descriptive::correlation(&ci.pattern, &cj.pattern).unwrap_or(0.0);
            // Comparable likelihoods: an AIC difference under 10 (a likelihood ratio under
            // e^5) does not pick one of two non-nested models with confidence.
            let comparable = (ci.delta_aic - cj.delta_aic).abs() < AMBIGUOUS_AIC;
            if r.abs() >= opts.ambiguity_correlation && comparable {
                ambiguities.push(Ambiguity {
                    triad,
                    effects: [ci.effect, cj.effect],
                    correlation: r,
                    separating_recording: separating_recording(ci.effect, cj.effect),
                });
            }
        }
    }
    if let Some(top) = candidates.first_mut() {
        let confused = ambiguities.iter().any(|a| a.effects.contains(&top.effect));
        top.claimed =
            !consistent && top.significant && top.share_of_excess >= opts.min_share && !confused;
    }
    ambiguities
}

/// Physical upper bound of a lever arm inside an IMU package, m.
const MAX_LEVER_ARM_M: f64 = 1.0;

/// Parameters of candidate `k` that the recording excites so weakly that their standard error
/// exceeds any physically possible value (a lever arm seen only through Earth's rate, a
/// time constant longer than the recording): what to say instead of their fitted values.
fn barely_excited(k: EffectKind, r: &FitResult, span_s: f64) -> Vec<String> {
    let prefix = format!("{}.", k.id());
    (0..r.names.len())
        .filter(|&i| r.names[i].starts_with(&prefix))
        .filter_map(|i| {
            let se = r.std_errors[i]?;
            let name = &r.names[i];
            match k {
                EffectKind::LeverArm if se > MAX_LEVER_ARM_M => Some(format!(
                    "{name}: standard error {se:.1e} m, more than any lever arm inside an IMU \
                     package ({MAX_LEVER_ARM_M} m): the recording barely excites it (rotate \
                     about each axis at several rates)"
                )),
                EffectKind::Warmup if name.ends_with("tau_s") && se > span_s => Some(format!(
                    "{name}: standard error {se:.0} s, longer than the recording ({span_s:.0} s): \
                     no decay is resolved (record from power-on)"
                )),
                _ => None,
            }
        })
        .collect()
}

fn unobservable_candidate(k: EffectKind, triad: Triad, why: String) -> Candidate {
    Candidate {
        effect: k,
        triad,
        new_params: 0,
        not_observable: vec![why.clone()],
        chi2: f64::NAN,
        dof: 0,
        f: f64::NAN,
        p_value: f64::NAN,
        delta_aic: f64::NEG_INFINITY,
        share_of_excess: 0.0,
        residual_rms: [f64::NAN; 3],
        significant: false,
        claimed: false,
        explanation: format!(
            "{}: not observable in this recording ({why})",
            k.description()
        ),
        params: Vec::new(),
        model_change: String::new(),
        fit: None,
        pattern: Vec::new(),
    }
}

fn effect_params(r: &FitResult, k: EffectKind) -> Vec<ParamValue> {
    let prefix = format!("{}.", k.id());
    (0..r.names.len())
        .filter(|&i| r.names[i].starts_with(&prefix))
        .map(|i| ParamValue {
            name: r.names[i].clone(),
            value: r.params[i],
            std_error: r.std_errors[i],
            unit: r.units[i].clone(),
        })
        .collect()
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// What drives one parameter, in physical words.
fn driver(k: EffectKind, param: &str, triad: Triad) -> String {
    let t = triad.name();
    let rest = param.split_once('.').map_or("", |x| x.1);
    let axis_of = |s: &str| s.chars().last().map(String::from).unwrap_or_default();
    match k {
        EffectKind::GSensitivity => {
            let mut c = rest.chars();
            let (row, col) = (c.next().unwrap_or('?'), c.next().unwrap_or('?'));
            format!("the {row}-{t} residual follows the specific force along {col}")
        }
        EffectKind::Misalignment => {
            let mut c = rest.chars();
            let (row, col) = (c.next().unwrap_or('?'), c.next().unwrap_or('?'));
            format!("the {row}-{t} residual follows the input along {col}")
        }
        EffectKind::ScaleNonlinearity => {
            let power = if rest.starts_with("quadratic") {
                "square"
            } else {
                "cube"
            };
            let a = axis_of(rest);
            format!("the {a}-{t} residual follows the {power} of its input")
        }
        EffectKind::AsymmetricScale => {
            let a = axis_of(rest);
            format!("the {a}-{t} gain differs between positive and negative input")
        }
        EffectKind::Scale => format!(
            "the {}-{t} residual is proportional to its input",
            axis_of(rest)
        ),
        EffectKind::Bias => format!("a constant offset on {}-{t}", axis_of(rest)),
        EffectKind::TempBias => format!("the {}-{t} residual follows temperature", axis_of(rest)),
        EffectKind::TempScale => format!("the {}-{t} gain follows temperature", axis_of(rest)),
        EffectKind::Warmup => format!(
            "the {}-{t} residual decays with time since power-on",
            axis_of(rest)
        ),
        EffectKind::LeverArm => format!(
            "the {t} residual follows the square of the rotation rate (centripetal \
             acceleration of a proof mass offset along {})",
            axis_of(rest)
        ),
    }
}

fn explain(k: EffectKind, triad: Triad, params: &[ParamValue], r: &FitResult) -> String {
    // The parameter with the largest |value / se| names the pattern.
    let best = params
        .iter()
        .filter(|p| !p.name.ends_with("tau_s"))
        .max_by(|a, b| {
            let t = |p: &ParamValue| p.std_error.map_or(0.0, |s| (p.value / s).abs());
            t(a).total_cmp(&t(b))
        });
    let mut s = k.description().to_string();
    if let Some(p) = best {
        let _ = write!(
            s,
            ": {} ({} = {:.3e}{} {})",
            driver(k, &p.name, triad),
            p.name,
            p.value,
            p.std_error
                .map_or(String::new(), |e| format!(" +/- {e:.1e}")),
            p.unit
        );
    }
    if let Some(tau) = params.iter().find(|p| p.name.ends_with("tau_s")) {
        let _ = write!(s, ", time constant {:.0} s", tau.value);
    }
    let _ = write!(
        s,
        "; residual RMS with it: {:.3e} {:.3e} {:.3e} {}",
        r.residual_rms[0],
        r.residual_rms[1],
        r.residual_rms[2],
        triad.unit()
    );
    s
}

/// The TOML lines of `k` as fitted in `m` (what to add to the model file).
fn model_change(triad: Triad, m: &TriadModel, k: EffectKind) -> String {
    let mut only = TriadModel::default();
    only.add(k);
    if let (Some(src), Some(dst)) = (m.get(k), only.get_mut(k)) {
        dst.set_params(&src.params());
    }
    let mut cal = imu_model::Calibration::identity();
    *cal.triad_mut(triad) = only;
    let text = cal.to_toml_string();
    let header = format!("[{}.{}", triad.name(), k.id());
    match text.find(&header) {
        Some(i) => text[i..].trim_end().to_string(),
        None => text,
    }
}

/// The recording that separates two effects the present one cannot.
fn separating_recording(a: EffectKind, b: EffectKind) -> String {
    use EffectKind::*;
    let has = |x: EffectKind| a == x || b == x;
    if has(Warmup) && (has(TempBias) || has(TempScale)) {
        "a temperature cycle after the warm-up has settled (heat and cool the sensor, e.g. in a \
         chamber or with the sinusoidal temperature profile): temperature then changes without \
         the time since power-on, and the two stop moving together"
            .into()
    } else if has(ScaleNonlinearity) && has(AsymmetricScale) {
        "inputs of both signs at several magnitudes (e.g. rate steps of +/-20, 40, 60, 80 deg/s): \
         a square bends both signs the same way, an asymmetry changes the gain with the sign"
            .into()
    } else if has(LeverArm) {
        "rotations at several rates about each axis, with the sensor off the table axis in \
         different directions: the centripetal term grows with the square of the rate and points \
         along the offset"
            .into()
    } else if has(GSensitivity) {
        "more static orientations (each axis up and down, and at 45 degrees): the g-dependent \
         bias follows the specific force, the other effect does not"
            .into()
    } else {
        format!(
            "a recording in which the signals that drive {a} and {b} vary independently of each \
             other"
        )
    }
}

/// Explanatory signals per observation: (name, values).
fn signals(points: &[FitPoint], triad: Triad) -> Vec<(String, Vec<f64>)> {
    let u = triad.unit();
    let mut out: Vec<(String, Vec<f64>)> = Vec::new();
    let col = |f: &dyn Fn(&FitPoint) -> f64| points.iter().map(f).collect::<Vec<f64>>();
    for (a, name) in AXES.iter().enumerate() {
        out.push((format!("input {name} [{u}]"), col(&|p| p.true_input[a])));
    }
    out.push((
        format!("input magnitude [{u}]"),
        col(&|p| p.true_input.norm()),
    ));
    for (a, name) in AXES.iter().enumerate() {
        out.push((
            format!("sign of input {name}"),
            col(&|p| p.true_input[a].signum()),
        ));
    }
    for (a, name) in AXES.iter().enumerate() {
        out.push((
            format!("specific force {name} [m/s^2]"),
            col(&|p| p.conditions.specific_force_m_s2[a]),
        ));
    }
    out.push(("temperature [degC]".into(), col(&|p| p.conditions.temp_c)));
    out.push((
        "time since power-on [s]".into(),
        col(&|p| p.conditions.time_since_power_on_s),
    ));
    for (a, name) in AXES.iter().enumerate() {
        out.push((
            format!("rotation rate {name} [rad/s]"),
            col(&|p| p.conditions.angular_rate_rad_s[a]),
        ));
    }
    out.push((
        "rotation rate squared [rad^2/s^2]".into(),
        col(&|p| p.conditions.angular_rate_rad_s.norm_squared()),
    ));
    // Table angle: direction of the specific force in the plane normal to the sensor axis it
    // varies least along.
    let f: Vec<_> = points
        .iter()
        .map(|p| p.conditions.specific_force_m_s2.normalize())
        .collect();
    if f.iter().all(|v| v.iter().all(|x| x.is_finite())) && !f.is_empty() {
        let var = |a: usize| {
            let m = f.iter().map(|v| v[a]).sum::<f64>() / f.len() as f64;
            f.iter().map(|v| (v[a] - m).powi(2)).sum::<f64>()
        };
        let axis = (0..3)
            .min_by(|&a, &b| var(a).total_cmp(&var(b)))
            .unwrap_or(0);
        let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
        out.push((
            format!("table angle about {} [deg]", AXES[axis]),
            f.iter().map(|v| v[j].atan2(v[i]).to_degrees()).collect(),
        ));
    }
    out
}

fn residual_structure(
    segs: &[SegmentResidual],
    signals: &[(String, Vec<f64>)],
    a: usize,
) -> Structure {
    let r: Vec<f64> = segs.iter().map(|s| s.residual[a]).collect();
    let mut correlates: Vec<Correlate> = signals
        .iter()
        .map(|(name, v)| Correlate {
            signal: name.clone(),
            r: descriptive::correlation(&r, v).unwrap_or(0.0),
        })
        .filter(|c| c.r.is_finite() && c.r != 0.0)
        .collect();
    correlates.sort_by(|x, y| y.r.abs().total_cmp(&x.r.abs()));
    let mut order: Vec<usize> = (0..segs.len()).collect();
    order.sort_by(|&i, &j| segs[i].start_s.total_cmp(&segs[j].start_s));
    let z: Vec<f64> = order.iter().map(|&i| segs[i].z[a]).collect();
    let t: Vec<f64> = order
        .iter()
        .map(|&i| 0.5 * (segs[i].start_s + segs[i].end_s))
        .collect();
    Structure {
        correlates,
        lag1_autocorrelation: descriptive::lag1_autocorrelation(&z),
        dominant_period_s: lomb_scargle_peak(&t, &z),
    }
}

/// Periodic components inside the static segments: the averaged, Hann-windowed periodogram of
/// blocks of every static segment, each bin compared with the median of its neighbourhood; a
/// bin standing out at a false-alarm probability of 1e-6 over all bins is a line.
pub fn spectral_lines(series: &ImuSeries, obs: &Observations, triad: Triad) -> Vec<SpectralLine> {
    let rate = series.sample_rate_hz();
    let data = if triad == Triad::Gyro {
        &series.gyro_rad_s
    } else {
        &series.accel_m_s2
    };
    let statics: Vec<_> = obs.segmentation.of_kind(SegmentKind::Static).collect();
    let Some(shortest) = statics.iter().map(|s| s.n).min() else {
        return Vec::new();
    };
    let mut len = 1usize;
    while len * 2 <= shortest.min(1024) {
        len *= 2;
    }
    if len < 64 {
        return Vec::new();
    }
    let mut out = Vec::new();
    for axis in 0..3 {
        let mut periodogram = Periodogram::new(len);
        for s in &statics {
            let y: Vec<f64> = data[s.range()].iter().map(|v| v[axis]).collect();
            periodogram.add_blocks(&y);
        }
        if periodogram.blocks() < 4 {
            continue;
        }
        out.extend(
            periodogram
                .lines(1e-6)
                .into_iter()
                .map(|peak| SpectralLine {
                    axis,
                    frequency_hz: peak.bin as f64 * rate / len as f64,
                    amplitude: peak.amplitude,
                    ratio: peak.ratio,
                }),
        );
    }
    out
}

#[allow(clippy::too_many_arguments)]
fn verdict_text(
    triad: Triad,
    model: &TriadModel,
    consistent: bool,
    with_drift: Option<(f64, [Wander; 3])>,
    p: f64,
    axes: &[AxisVerdict; 3],
    candidates: &[Candidate],
    ambiguities: &[Ambiguity],
    structure: &[Structure; 3],
    lines: &[SpectralLine],
) -> String {
    let u = triad.unit();
    let ids: Vec<&str> = model.kinds().iter().map(|k| k.id()).collect();
    let mut s = format!("{triad} model [{}]: ", ids.join(", "));
    if consistent {
        let _ = write!(
            s,
            "consistent with the noise floor (p = {p:.3}); residual RMS {} vs floor {} {u}.",
            fmt3(axes.each_ref().map(|a| a.residual_rms)),
            fmt3(axes.each_ref().map(|a| a.noise_floor_rms))
        );
    } else {
        let worst = (0..3)
            .max_by(|&a, &b| {
                (axes[a].residual_rms / axes[a].noise_floor_rms)
                    .total_cmp(&(axes[b].residual_rms / axes[b].noise_floor_rms))
            })
            .unwrap_or(0);
        let _ = write!(
            s,
            "NOT consistent with the noise floor (p = {p:.1e}); residual RMS {} vs floor {} {u}, \
             worst on {} ({:.1}x the floor).",
            fmt3(axes.each_ref().map(|a| a.residual_rms)),
            fmt3(axes.each_ref().map(|a| a.noise_floor_rms)),
            AXES[worst],
            axes[worst].residual_rms / axes[worst].noise_floor_rms
        );
        let any_significant = candidates.iter().any(|c| c.significant);
        if let Some((pd, w)) = with_drift.filter(|_| !any_significant) {
            let per_axis: Vec<String> = w
                .iter()
                .zip(AXES)
                .map(|(w, x)| {
                    if w.flicker_var > 0.0 {
                        format!("{x}: bias instability {:.2e} {u}", w.bias_instability())
                    } else if w.random_walk_q > 0.0 {
                        format!(
                            "{x}: random walk {:.2e} {u}/sqrt(s)",
                            w.random_walk_q.sqrt()
                        )
                    } else {
                        format!("{x}: none")
                    }
                })
                .collect();
            let _ = write!(
                s,
                " The excess is a slow wander of the bias between segments, not a missing effect: \
                 with it ({}) the residuals are consistent with the floor (p = {pd:.3}). (Bias \
                 instability and random walk the segments are too short to show; a long static \
                 recording through imu-noise measures them.)",
                per_axis.join(", ")
            );
        } else {
            match candidates.first() {
                Some(c) if c.claimed => {
                    let _ = write!(
                        s,
                        " Missing effect: {} (F-test p = {:.1e}, explains {:.0} % of the excess).",
                        c.explanation,
                        c.p_value,
                        100.0 * c.share_of_excess.min(1.0)
                    );
                }
                _ => {
                    if let Some(a) = ambiguities.first() {
                        let _ = write!(
                            s,
                            " {} and {} both explain the residual and cannot be told apart in this \
                         recording (their explained patterns correlate {:.2}); to separate them \
                         record {}.",
                            a.effects[0], a.effects[1], a.correlation, a.separating_recording
                        );
                    } else {
                        let _ = write!(
                            s,
                            " No effect of the library explains it: unexplained structure remains."
                        );
                        if let Some(c) = candidates.first().filter(|c| c.new_params > 0) {
                            let _ = write!(
                                s,
                                " (Best candidate {}: p = {:.1e}, explains {:.0} % of the excess.)",
                                c.effect,
                                c.p_value,
                                100.0 * c.share_of_excess.clamp(0.0, 1.0)
                            );
                        }
                        let a = worst;
                        if let Some(cr) = structure[a].correlates.first() {
                            let _ = write!(
                                s,
                                " On {}: strongest correlate {} (r = {:.2}), lag-1 autocorrelation \
                             {:.2}",
                                AXES[a], cr.signal, cr.r, structure[a].lag1_autocorrelation
                            );
                        }
                        if let Some((period, share)) = structure[a].dominant_period_s {
                            let _ = write!(
                                s,
                                ", dominant period {period:.0} s ({:.0} % of the variance)",
                                100.0 * share
                            );
                        }
                        s.push('.');
                    }
                }
            }
        }
    }
    for l in lines {
        let _ = write!(
            s,
            " Unexplained structure: a periodic component at {:.3} Hz, amplitude {:.2e} {u} on \
             {}-{triad} ({:.0}x the local noise) inside the static segments; no library effect \
             models a periodic disturbance (look for vibration or electrical interference at \
             that frequency).",
            l.frequency_hz, l.amplitude, AXES[l.axis], l.ratio
        );
    }
    s
}

fn fmt3(v: [f64; 3]) -> String {
    format!("{:.2e}/{:.2e}/{:.2e}", v[0], v[1], v[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_effect_has_physical_words_for_its_parameters() {
        for k in EffectKind::ALL {
            for t in [Triad::Accel, Triad::Gyro] {
                if !k.applies_to(t) {
                    continue;
                }
                let mut m = TriadModel::default();
                m.add(k);
                for name in m.param_names(t) {
                    let d = driver(k, &name, t);
                    assert!(!d.contains('?') && d.contains(t.name()), "{name}: {d}");
                }
            }
        }
    }
}
