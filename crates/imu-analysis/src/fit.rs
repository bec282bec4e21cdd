//! Weighted Levenberg-Marquardt fit of a [`TriadModel`]'s parameters to segment means (Aslan &
//! Saranli 3.1.2 and 3.2.2-3.2.3: multi-position static and rate-table calibration).
//!
//! Each observation is a segment: the TRUE input over it (specific force or angular rate, from a
//! reference), the MEASURED mean and the standard error of that mean. The residual is
//! `forward(true) - measured`, weighted by the standard error; the Jacobian is numeric (central
//! differences), so any effect of the model library can be fitted. Parameter standard errors
//! come from `(J^T W J)^-1`, where `W` is the inverse covariance of the segment means: their
//! white standard errors plus, given the triad's noise model, the bias's wander under bias
//! instability and random walk, correlated between segments; the result is scaled up by the
//! reduced chi-square when above 1 (unmodelled effects, or drift without a noise model).
//! Parameters the data cannot separate (a zero or collinear column of the normalised normal
//! matrix) are held at their starting values and reported as unobservable instead of being
//! given a meaningless number.

use imu_model::nalgebra::{DMatrix, DVector};
use imu_model::{Conditions, EffectKind, Triad, TriadModel, Vec3};
use imu_stats::lsq::{LsqOptions, covariance, find_unobservable, jacobian, minimize};

/// One observation: a segment's true input and measured mean.
#[derive(Clone, Debug, PartialEq)]
pub struct FitPoint {
    /// True input of the triad over the segment (m/s^2 or rad/s).
    pub true_input: Vec3,
    /// Measured mean over the segment (same unit).
    pub measured: Vec3,
    /// Standard error of the measured mean per axis (same unit, > 0).
    pub std_error: Vec3,
    /// Conditions of the segment (temperature, true specific force for g-sensitivity, ...).
    pub conditions: Conditions,
    /// Time of the segment (its middle), s; orders the segments for the drift model.
    pub t_s: f64,
    /// Length of the segment, s (0: an instant). With [`FitOptions::noise`] the covariance of
    /// two segment means under bias instability depends on it.
    pub duration_s: f64,
}

/// Settings of [`fit_triad`].
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Iteration budget.
    pub max_iterations: usize,
    /// Stop when the relative cost change falls below this.
    pub tolerance: f64,
    /// Smallest eigenvalue of the normalised normal matrix (unit diagonal) still counted as
    /// observable: 1 - (multiple correlation) of the weakest parameter combination.
    pub min_eigenvalue: f64,
    /// Parameters to hold at their starting values (layout of [`TriadModel::params`]); empty =
    /// all free.
    pub fixed: Vec<bool>,
    /// Standard deviation of the bias's wander over the recording per axis (triad unit), added
    /// in quadrature to the standard errors of `bias.*`. A drift common to every segment looks
    /// exactly like bias, so no residual shows it: it must come from a noise characterisation
    /// (see [`bias_drift_from_noise`]).
    pub bias_drift: Option<[f64; 3]>,
    /// Uncertainty of the true input common to every segment per axis (triad unit; e.g.
    /// Earth's rate where the reference does not fix north), added in quadrature to the
    /// standard errors of `bias.*` always, with or without a noise model: it is not noise of the
    /// sensor, so no covariance of the segment means carries it.
    pub bias_input_uncertainty: Option<[f64; 3]>,
    /// The triad's noise (from a noise characterisation such as imu-noise's), for the
    /// covariance of the segment means: besides each mean's white standard error, the bias
    /// wanders under bias instability `B` (flicker: correlated between nearby segments and more
    /// different between distant ones, see [`segment_covariance`]) and random walk `K`
    /// (`K^2 min(t_k, t_l)`, from the start of the recording). Without it
    /// that wander shows only in the residuals, and the one reduced chi-square that scales the
    /// covariance spreads it evenly over the axes and over near and distant segments: too small
    /// standard errors on a noisy axis and for contrasts between distant segments, too large on
    /// a quiet axis. The covariance carries the bias's wander over the recording too, so
    /// `bias_drift` is not added when this is given.
    pub noise: Option<imu_model::NoiseModel>,
    /// Model excess scatter of the segment means as a random-walk drift in time (so contrasts
    /// between early and late segments get the larger uncertainty they have) instead of white
    /// scatter; the drift rate is estimated per axis from the residuals. Off by default: on
    /// the simulated 3DM-GX1 (flicker-dominated drift, 12-24 segments) the estimated rate is
    /// too noisy and the standard errors came out worse than with white scatter scaled by the
    /// reduced chi-square.
    pub drift_model: bool,
    /// Known correlated noise of the segment means per axis (random walk, flicker): the means
    /// are then weighted with the covariance `se_k^2 delta_kl + shared_kl` (see
    /// [`segment_covariance`]) instead of white errors; takes precedence over `noise`. With
    /// `drift_model` on, its random walk is estimated instead.
    pub shared_noise: Option<[SharedNoise; 3]>,
}

/// Bias wander over a recording of `duration_s` from a noise model: bias instability `B` and
/// rate random walk `K` over the span, `sqrt(B^2 + K^2 T / 3)` per axis (the variance of a
/// random walk's deviation from its mean over `T` is `K^2 T / 3`).
pub fn bias_drift_from_noise(noise: &imu_model::NoiseModel, duration_s: f64) -> [f64; 3] {
    std::array::from_fn(|a| {
        (noise.bias_instability[a].powi(2) + noise.random_walk[a].powi(2) * duration_s / 3.0).sqrt()
    })
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            max_iterations: 100,
            tolerance: 1e-12,
            min_eigenvalue: 1e-8,
            fixed: Vec::new(),
            bias_drift: None,
            bias_input_uncertainty: None,
            noise: None,
            drift_model: false,
            shared_noise: None,
        }
    }
}

pub use imu_stats::lsq::Unobservable;

/// Result of [`fit_triad`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FitResult {
    /// Which triad.
    pub triad: Triad,
    /// The fitted model, with standard errors and residual RMS set (an effect with a held
    /// parameter carries no standard errors).
    #[serde(skip)]
    pub model: TriadModel,
    /// Parameter names, layout of [`TriadModel::params`].
    pub names: Vec<String>,
    /// Parameter units.
    pub units: Vec<String>,
    /// Fitted values.
    pub params: Vec<f64>,
    /// Standard errors; `None` for parameters held fixed or unobservable.
    pub std_errors: Vec<Option<f64>>,
    /// Correlation matrix of the free parameters (rows/cols in the order of `free`).
    pub correlation: Vec<Vec<f64>>,
    /// Indices of the fitted parameters.
    pub free: Vec<usize>,
    /// Parameters the data could not determine (held at their starting values).
    pub unobservable: Vec<Unobservable>,
    /// Per-axis RMS of `forward(true) - measured` over the observations (triad unit).
    pub residual_rms: [f64; 3],
    /// Per-observation residuals (triad unit).
    pub residuals: Vec<[f64; 3]>,
    /// Jacobian of the raw residuals (rows `3 k + axis`) with respect to the free parameters
    /// at the solution: what the expected residual under a covariance needs.
    #[serde(skip)]
    pub jacobian_raw: DMatrix<f64>,
    /// Weighted sum of squared residuals.
    pub chi2: f64,
    /// The weighted sum of squared residuals per axis.
    pub chi2_axis: [f64; 3],
    /// Degrees of freedom (observations - free parameters).
    pub dof: usize,
    /// chi2 / dof (the covariance is scaled by it when above 1).
    pub reduced_chi2: f64,
    /// Random-walk drift estimated from the excess scatter of the segment means per axis,
    /// unit/sqrt(s) (0 where the white errors explain the scatter, or with the drift model off).
    pub drift_random_walk: [f64; 3],
    /// Iterations taken.
    pub iterations: usize,
    /// True if the cost settled within the budget.
    pub converged: bool,
    /// Human-readable notes (poor conditioning, high correlations, held parameters).
    pub warnings: Vec<String>,
}

/// Failures of [`fit_triad`].
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// Fewer residuals than free parameters.
    #[error(
        "{triad}: {n_obs} residuals ({n_points} segments x 3 axes) cannot determine {n_free} \
         parameters with any degrees of freedom left; record more positions"
    )]
    TooFewObservations {
        /// Triad.
        triad: Triad,
        /// Segments.
        n_points: usize,
        /// Residuals.
        n_obs: usize,
        /// Free parameters.
        n_free: usize,
    },
    /// Nothing to fit.
    #[error("{triad}: the model has no free observable parameters")]
    NothingToFit {
        /// Triad.
        triad: Triad,
    },
    /// A standard error or value was not finite and positive.
    #[error("{triad}: observation {index} has a non-finite value or a standard error <= 0")]
    BadObservation {
        /// Triad.
        triad: Triad,
        /// Index of the observation.
        index: usize,
    },
    /// The `fixed` mask does not match the model.
    #[error("{triad}: fixed mask has {got} entries, the model {expected} parameters")]
    MaskLength {
        /// Triad.
        triad: Triad,
        /// Given.
        got: usize,
        /// Model parameter count.
        expected: usize,
    },
}

/// Noise shared by the segment means of one axis, beyond each mean's own white error.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SharedNoise {
    /// Random-walk rate variance `q` (unit^2/s, K^2 of the IEEE random walk): covariance
    /// `q min(t_k - t0, t_l - t0)`.
    pub random_walk_q: f64,
    /// Where the random walk starts, s (`t0`; None: at the first segment).
    pub random_walk_origin_s: Option<f64>,
    /// Longest correlation time of the flicker, s: with it the flicker is the Gauss-Markov bank
    /// of [`imu_model::NoiseModel::flicker_bank`] (the noise model's own definition, correlated
    /// up to that time); without it, pure flicker noise at every scale (its structure function).
    pub flicker_tau_max_s: Option<f64>,
    /// Flicker (bias instability) Allan variance floor `sigma_f^2` (unit^2; `(0.664 B)^2`).
    pub flicker_var: f64,
    /// Averaging time of the flicker structure for points without a duration, s.
    pub flicker_tau_s: f64,
}

/// Structure function of tau-averages of flicker FM noise separated by `n` averaging times,
/// in units of `sigma_f^2 / (2 ln 2)`: `(n+1)^2 ln(n+1) + (n-1)^2 ln|n-1| - 2 n^2 ln n`
/// (4 ln 2 for adjacent averages, growing as 2 ln n). (With `x(t)` the integral of `y`, the
/// flicker-FM phase structure function is `~ s^2 (c - ln s)`; the difference of two averages
/// combines it at lags `tau`, `n tau` and `(n +/- 1) tau`, where `c` cancels.)
fn flicker_structure(n: f64) -> f64 {
    let xlx = |x: f64| if x <= 0.0 { 0.0 } else { x * x * x.ln() };
    xlx(n + 1.0) + xlx((n - 1.0).abs()) - 2.0 * xlx(n)
}

/// Covariance of the means over two segments (`mid`, `len`) of a unit-variance first-order
/// Gauss-Markov process with correlation time `t_s`.
fn gauss_markov_mean_cov(mid_k: f64, len_k: f64, mid_l: f64, len_l: f64, t_s: f64) -> f64 {
    // Average of exp(-|u| / T) over an interval of length L (-> 1 as L -> 0).
    let shrink = |len: f64| {
        let x = len / t_s;
        if x < 1e-6 {
            1.0 - x / 2.0
        } else {
            -(-x).exp_m1() / x
        }
    };
    if mid_k == mid_l && len_k == len_l {
        // Within one segment: 2 (x - 1 + e^-x) / x^2.
        let x = len_k / t_s;
        return if x < 1e-4 {
            1.0 - x / 3.0
        } else {
            2.0 * (x + (-x).exp_m1()) / (x * x)
        };
    }
    let gap = (mid_k - mid_l).abs() - 0.5 * (len_k + len_l);
    if gap < 0.0 {
        // Overlapping segments (not produced by segmentation): treat as instants.
        return (-(mid_k - mid_l).abs() / t_s).exp();
    }
    shrink(len_k) * shrink(len_l) * (-gap / t_s).exp()
}

/// Sample period the flicker bank is built for, s. Only processes slower than about a second
/// matter for segment means, and the bank is scaled to the same Allan floor whatever the period.
const FLICKER_BANK_DT_S: f64 = 0.01;

/// Which recording (power-on) each fit point comes from, for the covariance of the segment
/// means. The bias's wander (random walk, flicker) of two recordings are independent
/// realisations that started at different power-ons, so segment means of different sessions
/// share none of it: their covariance is zero, and within each session the random walk and the
/// flicker's reference segment start afresh (times are on each session's own clock).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sessions {
    /// Session of each point (parallel to the points); empty: every point in session 0.
    pub of_point: Vec<usize>,
    /// Turn-on to turn-on bias repeatability per axis, 1 sigma (triad unit): each session's bias
    /// differs from the fitted bias (then the mean over power-ons) by an independent offset of
    /// this size, shared by all segments of the session. None: one bias common to every session.
    pub turn_on_bias: Option<[f64; 3]>,
}

impl Sessions {
    /// The session of point `k`.
    pub fn of(&self, k: usize) -> usize {
        self.of_point.get(k).copied().unwrap_or(0)
    }

    /// Number of sessions among `n` points.
    pub fn count(&self, n: usize) -> usize {
        (0..n).map(|k| self.of(k) + 1).max().unwrap_or(0)
    }
}

/// Covariance of the segment means of axis `a`: `white_scale se_k^2 delta_kl` plus the shared
/// random walk and flicker. The flicker term is the covariance of the increments from the
/// first segment (a common offset is the bias's business), `(D_k0 + D_l0 - D_kl) / 2`, with `D`
/// the flicker structure function of two means at the mean of their durations. All points are
/// one session (one recording); see [`session_covariance`] for several.
pub fn segment_covariance(
    points: &[FitPoint],
    a: usize,
    shared: &SharedNoise,
    white_scale: f64,
) -> DMatrix<f64> {
    session_covariance(points, &Sessions::default(), a, shared, white_scale)
}

/// [`segment_covariance`] of points from several sessions: the shared noise within each
/// session (its random walk from `shared.random_walk_origin_s` on the session's clock, else
/// from its first segment; its flicker increments from its first segment), the turn-on bias
/// variance within each session, zero between sessions.
pub fn session_covariance(
    points: &[FitPoint],
    sessions: &Sessions,
    a: usize,
    shared: &SharedNoise,
    white_scale: f64,
) -> DMatrix<f64> {
    let n = points.len();
    // The first segment of each session and the start of its random walk.
    let mut first: Vec<Option<usize>> = vec![None; sessions.count(n)];
    for k in 0..n {
        let f = &mut first[sessions.of(k)];
        if f.is_none_or(|j| points[k].t_s < points[j].t_s) {
            *f = Some(k);
        }
    }
    let k0 = |k: usize| first[sessions.of(k)].unwrap_or(k);
    let t0 = |k: usize| {
        shared
            .random_walk_origin_s
            .unwrap_or_else(|| points[k0(k)].t_s)
    };
    let turn_on_var = sessions.turn_on_bias.map_or(0.0, |b| b[a] * b[a]);
    let unit = shared.flicker_var / (2.0 * std::f64::consts::LN_2);
    let tau = |k: usize| {
        if points[k].duration_s > 0.0 {
            points[k].duration_s
        } else {
            shared.flicker_tau_s.max(1e-9)
        }
    };
    let d = |k: usize, l: usize| {
        if unit == 0.0 || k == l {
            0.0
        } else {
            let t = 0.5 * (tau(k) + tau(l));
            unit * flicker_structure((points[k].t_s - points[l].t_s).abs() / t)
        }
    };
    // The bank: (correlation time, variance) of each Gauss-Markov process.
    let bank: Vec<(f64, f64)> = match shared.flicker_tau_max_s {
        Some(tau_max_s) if shared.flicker_var > 0.0 => {
            let unit_model = imu_model::NoiseModel {
                bias_instability_tau_max_s: tau_max_s,
                ..Default::default()
            };
            let b2 = shared.flicker_var / imu_stats::noise_terms::BIAS_INSTABILITY_FACTOR.powi(2);
            unit_model
                .flicker_bank(FLICKER_BANK_DT_S)
                .into_iter()
                .map(|(t, u)| (t, u * b2))
                .collect()
        }
        _ => Vec::new(),
    };
    let flicker = |k: usize, l: usize| {
        if shared.flicker_tau_max_s.is_some() {
            let (pk, pl) = (&points[k], &points[l]);
            bank.iter()
                .map(|&(t, v)| {
                    v * gauss_markov_mean_cov(pk.t_s, pk.duration_s, pl.t_s, pl.duration_s, t)
                })
                .sum()
        } else {
            let k0 = k0(k);
            0.5 * (d(k, k0) + d(l, k0) - d(k, l))
        }
    };
    DMatrix::from_fn(n, n, |k, l| {
        let white = if k == l {
            white_scale * points[k].std_error[a].powi(2)
        } else {
            0.0
        };
        if sessions.of(k) != sessions.of(l) {
            return white;
        }
        let t0 = t0(k);
        let rw = shared.random_walk_q * (points[k].t_s - t0).min(points[l].t_s - t0).max(0.0);
        white + rw + flicker(k, l) + turn_on_var
    })
}

/// The shared noise of [`fit_triad`]: `opts.shared_noise` as given, else from `opts.noise` (a
/// noise characterisation: flicker floor `(0.664 B)^2`, random walk `K^2` starting with the
/// recording at t = 0, so the fitted bias is the bias at its start), else none.
fn shared_noise(opts: &FitOptions, points: &[FitPoint]) -> [SharedNoise; 3] {
    if let Some(s) = opts.shared_noise {
        return s;
    }
    let Some(n) = &opts.noise else {
        return [SharedNoise::default(); 3];
    };
    let t_first = points.iter().map(|p| p.t_s).fold(f64::INFINITY, f64::min);
    std::array::from_fn(|a| SharedNoise {
        random_walk_q: n.random_walk[a].powi(2),
        random_walk_origin_s: Some(t_first.min(0.0)),
        flicker_var: (imu_stats::noise_terms::BIAS_INSTABILITY_FACTOR * n.bias_instability[a])
            .powi(2),
        flicker_tau_s: 1.0,
        flicker_tau_max_s: Some(n.bias_instability_tau_max_s),
    })
}

/// Per-axis whitening of the residuals: `L_a^-1` of [`session_covariance`] on axis `a`.
#[derive(Clone, Debug)]
struct Whitener {
    l_inv: [DMatrix<f64>; 3],
}

impl Whitener {
    fn new(points: &[FitPoint], sessions: &Sessions, shared: &[SharedNoise; 3]) -> Whitener {
        let l_inv = std::array::from_fn(|a| {
            let c = session_covariance(points, sessions, a, &shared[a], 1.0);
            let l = match c.clone().cholesky() {
                Some(ch) => ch.l(),
                // A shared part that is not quite positive definite (unequal segment lengths
                // under the flicker approximation): fall back to its diagonal.
                None => DMatrix::from_diagonal(&c.diagonal().map(f64::sqrt)),
            };
            l.try_inverse()
                .expect("triangular with a positive diagonal")
        });
        Whitener { l_inv }
    }

    /// Whitened residuals (layout `3 k + axis`) from raw ones.
    fn apply(&self, raw: &DVector<f64>) -> DVector<f64> {
        let n = raw.len() / 3;
        let mut out = DVector::zeros(raw.len());
        for a in 0..3 {
            let ra = DVector::from_fn(n, |k, _| raw[3 * k + a]);
            let wa = &self.l_inv[a] * ra;
            for k in 0..n {
                out[3 * k + a] = wa[k];
            }
        }
        out
    }

    /// Whitened sum of squares of one axis of raw residuals.
    fn axis_chi2(&self, raw: &DVector<f64>, a: usize) -> f64 {
        let n = raw.len() / 3;
        let ra = DVector::from_fn(n, |k, _| raw[3 * k + a]);
        (&self.l_inv[a] * ra).norm_squared()
    }
}

/// Raw residuals `forward(true) - measured` at parameter vector `p` (layout `3 k + axis`).
fn raw_residuals(model: &mut TriadModel, p: &[f64], points: &[FitPoint]) -> DVector<f64> {
    model.set_params(p);
    let mut r = DVector::zeros(3 * points.len());
    for (k, pt) in points.iter().enumerate() {
        let y = model.forward(pt.true_input, &pt.conditions);
        for a in 0..3 {
            r[3 * k + a] = y[a] - pt.measured[a];
        }
    }
    r
}

/// The engine's settings for a triad fit.
fn lsq_options(opts: &FitOptions) -> LsqOptions {
    LsqOptions {
        max_iterations: opts.max_iterations,
        tolerance: opts.tolerance,
        min_eigenvalue: opts.min_eigenvalue,
        collinear_advice: "; vary the input (e.g. gravity direction) to separate them".into(),
    }
}

/// The residuals of `points` under `model` at a parameter vector, whitened by `w` (raw
/// without): the problem the least-squares engine solves.
fn triad_residuals<'a>(
    model: &'a mut TriadModel,
    points: &'a [FitPoint],
    w: Option<&'a Whitener>,
) -> impl FnMut(&[f64]) -> DVector<f64> + 'a {
    move |p: &[f64]| {
        let raw = raw_residuals(model, p, points);
        match w {
            Some(w) => w.apply(&raw),
            None => raw,
        }
    }
}

/// The drift rate variance `q` of one axis that brings its whitened chi-square down to `dof`
/// (0 if the white errors already explain the scatter), by bisection in log q.
fn drift_q(
    points: &[FitPoint],
    sessions: &Sessions,
    raw: &DVector<f64>,
    mut q: [SharedNoise; 3],
    a: usize,
    dof: f64,
) -> f64 {
    let mut chi2 = |qa: f64| {
        q[a].random_walk_q = qa;
        Whitener::new(points, sessions, &q).axis_chi2(raw, a)
    };
    if chi2(0.0) <= dof {
        return 0.0;
    }
    let span_s = points
        .iter()
        .map(|p| p.t_s)
        .fold(f64::NEG_INFINITY, f64::max)
        - points.iter().map(|p| p.t_s).fold(f64::INFINITY, f64::min);
    let scale = (0..points.len())
        .map(|k| raw[3 * k + a].powi(2))
        .fold(0.0, f64::max)
        / span_s.max(1e-9);
    let (mut lo, mut hi) = (scale * 1e-12, scale);
    while chi2(hi) > dof && hi < scale * 1e12 {
        hi *= 10.0;
    }
    for _ in 0..60 {
        let mid = (lo * hi).sqrt();
        if chi2(mid) > dof {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// Fit the parameters of `model` (its current values are the starting point; the effects
/// present define what is fitted) to `points`, all from one recording.
pub fn fit_triad(
    model: &TriadModel,
    triad: Triad,
    points: &[FitPoint],
    opts: &FitOptions,
) -> Result<FitResult, FitError> {
    fit_triad_sessions(model, triad, points, &Sessions::default(), opts)
}

/// [`fit_triad`] to points from several recordings (`sessions` says which point comes from
/// which, and whether their biases may differ): one parameter set for all of them, the segment
/// means weighted with [`session_covariance`].
pub fn fit_triad_sessions(
    model: &TriadModel,
    triad: Triad,
    points: &[FitPoint],
    sessions: &Sessions,
    opts: &FitOptions,
) -> Result<FitResult, FitError> {
    for (index, pt) in points.iter().enumerate() {
        let ok = (0..3).all(|a| {
            pt.true_input[a].is_finite()
                && pt.measured[a].is_finite()
                && pt.std_error[a].is_finite()
                && pt.std_error[a] > 0.0
        });
        if !ok {
            return Err(FitError::BadObservation { triad, index });
        }
    }
    let mut m = model.clone();
    let names = m.param_names(triad);
    let units = m.param_units(triad);
    let np = m.n_params();
    if !opts.fixed.is_empty() && opts.fixed.len() != np {
        return Err(FitError::MaskLength {
            triad,
            got: opts.fixed.len(),
            expected: np,
        });
    }
    let mut p = m.params();
    let mut free: Vec<usize> = (0..np)
        .filter(|&i| !opts.fixed.get(i).copied().unwrap_or(false))
        .collect();
    let lsq = lsq_options(opts);
    // Observability is judged on the white errors alone (secondary effects such as
    // g-sensitivity follow the bias in canonical order, so a g-sensitivity column collinear with
    // a bias goes, not the bias).
    let white = Whitener::new(points, &Sessions::default(), &[SharedNoise::default(); 3]);
    let unobservable = find_unobservable(
        &mut triad_residuals(&mut m, points, Some(&white)),
        &p,
        &mut free,
        &names,
        &lsq,
    );
    m.set_params(&p);
    if free.is_empty() {
        return Err(FitError::NothingToFit { triad });
    }
    let n_obs = 3 * points.len();
    if n_obs <= free.len() {
        return Err(FitError::TooFewObservations {
            triad,
            n_points: points.len(),
            n_obs,
            n_free: free.len(),
        });
    }

    // Fit with white errors; then, if the scatter exceeds them and the drift model is on,
    // estimate per-axis random-walk drift, re-weight and refit until the drift settles.
    let mut q = shared_noise(opts, points);
    let mut w = Whitener::new(points, sessions, &q);
    let first = minimize(
        &mut triad_residuals(&mut m, points, Some(&w)),
        &mut p,
        &free,
        &lsq,
    );
    let (mut cost, mut iterations, mut converged) = (first.cost, first.iterations, first.converged);
    if opts.drift_model {
        let dof_axis = (points.len() as f64 - free.len() as f64 / 3.0).max(1.0);
        for _ in 0..8 {
            let raw = raw_residuals(&mut m, &p, points);
            let next: [f64; 3] =
                std::array::from_fn(|a| drift_q(points, sessions, &raw, q, a, dof_axis));
            let settled =
                (0..3).all(|a| (next[a] - q[a].random_walk_q).abs() <= 1e-3 * next[a].max(1e-300));
            for (s, v) in q.iter_mut().zip(next) {
                s.random_walk_q = v;
            }
            w = Whitener::new(points, sessions, &q);
            let next = minimize(
                &mut triad_residuals(&mut m, points, Some(&w)),
                &mut p,
                &free,
                &lsq,
            );
            cost = next.cost;
            iterations += next.iterations;
            converged = next.converged;
            if settled {
                break;
            }
        }
    }

    let dof = n_obs - free.len();
    let reduced_chi2 = cost / dof as f64;
    let j = jacobian(&mut triad_residuals(&mut m, points, Some(&w)), &p, &free);
    m.set_params(&p);
    let mut warnings = Vec::new();
    // Scale by the reduced chi-square only upwards: below 1 the white errors are trusted.
    let mut cov = match covariance(&j, reduced_chi2) {
        Some(cov) => cov,
        None => {
            warnings.push("normal matrix not invertible: no standard errors".into());
            DMatrix::from_element(free.len(), free.len(), f64::NAN)
        }
    };
    let drift = opts.bias_drift.filter(|_| opts.noise.is_none());
    for extra in [drift, opts.bias_input_uncertainty].into_iter().flatten() {
        for (c, &i) in free.iter().enumerate() {
            let axis = ["bias.x", "bias.y", "bias.z"]
                .iter()
                .position(|n| *n == names[i]);
            if let Some(axis) = axis {
                cov[(c, c)] += extra[axis].powi(2);
            }
        }
    }
    let mut std_errors = vec![None; np];
    for (c, &i) in free.iter().enumerate() {
        std_errors[i] = Some(cov[(c, c)].max(0.0).sqrt());
    }
    let nf = free.len();
    let mut correlation = vec![vec![0.0; nf]; nf];
    for a_ in 0..nf {
        for b in 0..nf {
            correlation[a_][b] = cov[(a_, b)] / (cov[(a_, a_)] * cov[(b, b)]).sqrt();
            if a_ < b && correlation[a_][b].abs() > 0.99 {
                warnings.push(format!(
                    "{} and {} are correlated {:.3}: poorly separated by these data",
                    names[free[a_]], names[free[b]], correlation[a_][b]
                ));
            }
        }
    }
    for u in &unobservable {
        warnings.push(format!("{} not fitted: {}", u.name, u.reason));
    }
    if !converged {
        warnings.push(format!("not converged after {iterations} iterations"));
    }

    let mut residuals_u = Vec::with_capacity(points.len());
    let mut sq = [0.0; 3];
    for pt in points {
        let d = m.forward(pt.true_input, &pt.conditions) - pt.measured;
        for a_ in 0..3 {
            sq[a_] += d[a_] * d[a_];
        }
        residuals_u.push([d[0], d[1], d[2]]);
    }
    let residual_rms = sq.map(|s| (s / points.len() as f64).sqrt());
    let raw_final = raw_residuals(&mut m, &p, points);
    let chi2_axis = std::array::from_fn(|a| w.axis_chi2(&raw_final, a));
    let jacobian_raw = jacobian(&mut triad_residuals(&mut m, points, None), &p, &free);
    m.set_params(&p);
    // Standard errors go into the model per effect; an effect with a held parameter gets none
    // (a 0 would claim the held value is exact).
    let mut rest = std_errors.as_slice();
    for e in m.effects_mut() {
        let (mine, tail) = rest.split_at(e.n_params().min(rest.len()));
        rest = tail;
        e.set_std_errors(mine.iter().copied().collect::<Option<Vec<f64>>>());
    }
    m.residual_rms = Some(residual_rms);

    Ok(FitResult {
        triad,
        model: m,
        names,
        units,
        params: p,
        std_errors,
        correlation,
        free,
        unobservable,
        residual_rms,
        residuals: residuals_u,
        jacobian_raw,
        chi2: cost,
        chi2_axis,
        dof,
        reduced_chi2,
        drift_random_walk: q.map(|s| s.random_walk_q.sqrt()),
        iterations,
        converged,
        warnings,
    })
}

// ------------------------------------------------------------------ calibration from segments

pub use crate::reference::{Reference, ReferenceError, SegmentTruth};

/// What [`calibrate`] fits and how.
#[derive(Clone, Debug)]
pub struct CalibrateOptions {
    /// Accel model to fit (its effects and starting values).
    pub accel: TriadModel,
    /// Gyro model to fit.
    pub gyro: TriadModel,
    /// Segmentation settings.
    pub segment: crate::segment::SegmentOptions,
    /// Fit settings (the `fixed` mask, `bias_drift` and `noise` are ignored here).
    pub fit: FitOptions,
    /// Accel bias wander over the recording (m/s^2), see [`FitOptions::bias_drift`].
    pub accel_bias_drift_m_s2: Option<[f64; 3]>,
    /// Gyro bias wander over the recording (rad/s), see [`FitOptions::bias_drift`].
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
    /// Decisions taken (held parameters, ...).
    pub notes: Vec<String>,
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

/// The parameter name (`effect.name.x`) of a validation error's key (`effect.name[0]`).
pub(crate) fn invalid_param_name(key: &str) -> String {
    match key.strip_suffix(']').and_then(|k| k.rsplit_once('[')) {
        Some((base, i)) => match i {
            "0" => format!("{base}.x"),
            "1" => format!("{base}.y"),
            "2" => format!("{base}.z"),
            _ => key.to_string(),
        },
        None => key.to_string(),
    }
}

/// [`fit_triad`], then make sure the fitted model is one imud can load: while validation
/// rejects a fitted parameter (in practice a cubic nonlinearity that data within +/-1 g cannot
/// pin down, extrapolated to the +/-20 g over which the model must stay invertible), that
/// parameter is held at 0 (no such term), reported as unobservable, and the rest refitted.
pub(crate) fn fit_loadable(
    model: &TriadModel,
    triad: Triad,
    points: &[FitPoint],
    sessions: &Sessions,
    opts: &FitOptions,
) -> Result<FitResult, CalibrateError> {
    let mut start = model.clone();
    let mut fixed = vec![false; model.n_params()];
    let mut held: Vec<Unobservable> = Vec::new();
    loop {
        let o = FitOptions {
            fixed: fixed.clone(),
            ..opts.clone()
        };
        let mut r = fit_triad_sessions(&start, triad, points, sessions, &o)?;
        let Err(e) = r.model.validate(triad) else {
            for u in &held {
                r.warnings
                    .push(format!("{} not fitted: {}", u.name, u.reason));
            }
            r.unobservable.extend(held);
            return Ok(r);
        };
        let name = invalid_param_name(&e.key);
        let Some(i) = r
            .names
            .iter()
            .position(|n| *n == name)
            .filter(|&i| !fixed[i])
        else {
            return Err(CalibrateError::InvalidModel {
                triad,
                key: e.key,
                message: e.message,
            });
        };
        let se = r.std_errors[i].map_or_else(String::new, |s| format!(" +/- {s:.2e}"));
        held.push(Unobservable {
            name,
            reason: format!(
                "fitted to {:.3e}{se}, it makes the model invalid ({}); held at 0 (no such term)",
                r.params[i], e.message
            ),
        });
        fixed[i] = true;
        let mut p = start.params();
        p[i] = 0.0;
        start.set_params(&p);
    }
}

/// Effects whose parameters only a large input excites (held without rate plateaus).
const GAIN_KINDS: [EffectKind; 4] = [
    EffectKind::Misalignment,
    EffectKind::Scale,
    EffectKind::AsymmetricScale,
    EffectKind::ScaleNonlinearity,
];

fn point(
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
    /// centripetal term of a lever arm shows there); gyro points from every segment.
    pub fn from_recording(
        series: &crate::ImuSeries,
        reference: &Reference,
        segment: &crate::segment::SegmentOptions,
        accel_on_plateaus: bool,
    ) -> Result<Observations, CalibrateError> {
        use crate::segment::SegmentKind;
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
    pub fn gyro_model_for(&self, model: &TriadModel) -> (TriadModel, Option<String>) {
        use crate::segment::SegmentKind;
        gyro_model_with_plateaus(model, self.segmentation.count(SegmentKind::Plateau) > 0)
    }
}

/// `model` without the gyro gain effects unless some recording has rate plateaus, and the note
/// saying what was held.
fn gyro_model_with_plateaus(model: &TriadModel, plateaus: bool) -> (TriadModel, Option<String>) {
    if plateaus {
        return (model.clone(), None);
    }
    let held: Vec<EffectKind> = GAIN_KINDS.into_iter().filter(|k| model.has(*k)).collect();
    if held.is_empty() {
        return (model.clone(), None);
    }
    let mut m = model.clone();
    for k in &held {
        m.remove(*k);
    }
    let note = format!(
        "no rate plateaus found: gyro {} not fitted (Earth rate cannot excite them; record a \
         rate-table run)",
        held.iter().map(|k| k.id()).collect::<Vec<_>>().join(", ")
    );
    (m, Some(note))
}

/// Error unless the recordings together hold `needed` segments of `kind` (the first
/// recording's thresholds and hint say what is short).
fn require_segments(
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
fn joint_points(
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
    let several = recordings.len() > 1;
    let in_recording = |i: usize, e: CalibrateError| {
        if several {
            CalibrateError::Recording {
                number: i + 1,
                origin: recordings[i].0.origin.clone(),
                source: Box::new(e),
            }
        } else {
            e
        }
    };
    if recordings.is_empty() {
        return Err(CalibrateError::NoRecording);
    }
    let mut notes = Vec::new();
    let mut obs = Vec::with_capacity(recordings.len());
    let mut gyro_bias_std_rad_s: Option<[f64; 3]> = None;
    for (i, (series, reference)) in recordings.iter().enumerate() {
        let o = Observations::from_recording(series, reference, &opts.segment, false)
            .map_err(|e| in_recording(i, e))?;
        let caveats = reference
            .caveats(series, &o.segmentation.segments)
            .map_err(|e| in_recording(i, e.into()))?;
        let prefix = if several {
            format!("recording {} ({}): ", i + 1, series.origin)
        } else {
            String::new()
        };
        notes.extend(caveats.notes.iter().map(|n| format!("{prefix}{n}")));
        notes.extend(
            o.segmentation
                .skipped
                .iter()
                .map(|k| format!("{prefix}{} skipped by {}: not fitted", k.describe(), k.by)),
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
    if several {
        notes.push(bias_note(recordings.len(), opts));
    }
    let caveats = crate::reference::ReferenceCaveats {
        gyro_bias_std_rad_s,
        notes: Vec::new(),
    };
    let fit_opts = |drift, input, noise: &Option<imu_model::NoiseModel>| FitOptions {
        fixed: Vec::new(),
        bias_drift: drift,
        bias_input_uncertainty: input,
        noise: noise.clone(),
        ..opts.fit.clone()
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
        &fit_opts(opts.accel_bias_drift_m_s2, None, &opts.accel_noise),
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
        &fit_opts(
            opts.gyro_bias_drift_rad_s,
            caveats.gyro_bias_std_rad_s,
            &opts.gyro_noise,
        ),
    )?;

    let mut calibration = imu_model::Calibration::identity();
    calibration.accel = accel.model.clone();
    calibration.gyro = gyro.model.clone();
    let (mut a0, mut g0) = (0, 0);
    let recordings: Vec<RecordingFit> = obs
        .into_iter()
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
        .collect();
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

/// What a joint fit assumes of the biases of its `n` recordings.
fn bias_note(n: usize, opts: &CalibrateOptions) -> String {
    let fmt = |v: [f64; 3]| format!("[{:.1e}, {:.1e}, {:.1e}]", v[0], v[1], v[2]);
    let triad = |name: &str, unit: &str, turn_on: Option<[f64; 3]>| match turn_on {
        None => format!(
            "the {name} bias is taken as the same in all {n} recordings (no change between \
             power-ons)"
        ),
        Some(b) => format!(
            "the {name} bias is the mean over the {n} power-ons, each recording's own bias \
             allowed to differ from it by {} {unit} (1 sigma, turn-on repeatability)",
            fmt(b)
        ),
    };
    let mut note = format!(
        "{} recordings fitted together: {}; {}; bias wander is independent between recordings",
        n,
        triad("accel", "m/s^2", opts.accel_turn_on_bias_m_s2),
        triad("gyro", "rad/s", opts.gyro_turn_on_bias_rad_s)
    );
    if opts.accel_turn_on_bias_m_s2.is_none() || opts.gyro_turn_on_bias_rad_s.is_none() {
        note.push_str(
            "; a MEMS bias usually changes from one power-on to the next: give its turn-on \
             repeatability (imu-calibrate --accel-turn-on-bias-m-s2, \
             --gyro-turn-on-bias-rad-s) to fit the mean bias with that spread",
        );
    }
    note
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(kinds: &[EffectKind]) -> TriadModel {
        let mut m = TriadModel::default();
        for k in kinds {
            m.add(*k);
        }
        m
    }

    #[test]
    fn a_cubic_that_would_make_the_model_non_invertible_is_held() {
        use EffectKind::*;
        // Measurements with a strong cubic term (x - 1e-5 x^3): fitted as it is, the curve
        // would fold over well inside +/-20 g.
        let g = 9.8;
        let points: Vec<FitPoint> = [-1.0, -0.7, -0.35, 0.0, 0.35, 0.7, 1.0]
            .iter()
            .enumerate()
            .map(|(k, &c)| {
                let x = Vec3::new(c * g, 0.5 * c * g, -0.8 * c * g);
                FitPoint {
                    true_input: x,
                    measured: x.map(|v| v - 1e-5 * v * v * v),
                    std_error: Vec3::repeat(1e-3),
                    conditions: Conditions::default(),
                    t_s: k as f64,
                    duration_s: 0.0,
                }
            })
            .collect();
        let m = model(&[Bias, Scale, ScaleNonlinearity]);
        let r = fit_loadable(
            &m,
            Triad::Accel,
            &points,
            &Sessions::default(),
            &FitOptions::default(),
        )
        .unwrap();
        assert!(!r.unobservable.is_empty(), "{:?}", r.warnings);
        for u in &r.unobservable {
            assert!(u.name.starts_with("scale-nonlinearity.cubic"), "{u:?}");
        }
        assert!(r.model.validate(Triad::Accel).is_ok());
        assert!(
            r.unobservable[0].reason.contains("invalid"),
            "{:?}",
            r.unobservable
        );
    }

    /// Points `k` seconds apart, 20 s long, with distinct white errors.
    fn timed_points(times_s: &[f64]) -> Vec<FitPoint> {
        times_s
            .iter()
            .enumerate()
            .map(|(k, &t)| FitPoint {
                true_input: Vec3::zeros(),
                measured: Vec3::zeros(),
                std_error: Vec3::repeat(1e-3 * (1.0 + k as f64)),
                conditions: Conditions::default(),
                t_s: t,
                duration_s: 20.0,
            })
            .collect()
    }

    #[test]
    fn sessions_share_no_noise_and_each_starts_its_own_random_walk() {
        // Session 0 at 10, 50, 90 s; session 1 (its own clock) at 15, 70 s.
        let times = [10.0, 50.0, 90.0, 15.0, 70.0];
        let points = timed_points(&times);
        let sessions = Sessions {
            of_point: vec![0, 0, 0, 1, 1],
            turn_on_bias: None,
        };
        for shared in [
            SharedNoise {
                random_walk_q: 1e-8,
                random_walk_origin_s: Some(0.0),
                flicker_var: 4e-8,
                flicker_tau_s: 1.0,
                flicker_tau_max_s: Some(1000.0),
            },
            SharedNoise {
                random_walk_q: 1e-8,
                random_walk_origin_s: None,
                flicker_var: 4e-8,
                flicker_tau_s: 1.0,
                flicker_tau_max_s: None,
            },
        ] {
            let c = session_covariance(&points, &sessions, 0, &shared, 1.0);
            // Nothing shared across sessions.
            for k in 0..3 {
                for l in 3..5 {
                    assert_eq!(c[(k, l)], 0.0);
                    assert_eq!(c[(l, k)], 0.0);
                }
            }
            // Within each session, exactly the one-recording covariance of its points alone.
            for range in [0..3, 3..5] {
                let alone = segment_covariance(&points[range.clone()], 0, &shared, 1.0);
                let block = c.view((range.start, range.start), (range.len(), range.len()));
                assert!((block - &alone).abs().max() <= 1e-18, "{c}\n{alone}");
            }
        }
        // With the random walk from t = 0 on each session's clock, session 1's first segment
        // (15 s) carries 15 q, not the 5 s since session 0's first one.
        let rw = SharedNoise {
            random_walk_q: 1e-8,
            random_walk_origin_s: Some(0.0),
            ..SharedNoise::default()
        };
        let c = session_covariance(&points, &sessions, 0, &rw, 0.0);
        assert!((c[(3, 3)] - 15.0 * 1e-8).abs() < 1e-20);
        assert!((c[(3, 4)] - 15.0 * 1e-8).abs() < 1e-20);
        // A turn-on bias spread is shared within a session only.
        let spread = Sessions {
            turn_on_bias: Some([2e-3, 0.0, 0.0]),
            ..sessions.clone()
        };
        let c = session_covariance(&points, &spread, 0, &SharedNoise::default(), 1.0);
        assert!((c[(0, 2)] - 4e-6).abs() < 1e-18 && (c[(3, 4)] - 4e-6).abs() < 1e-18);
        assert_eq!(c[(0, 3)], 0.0);
        assert!((c[(1, 1)] - (4e-6 + 4e-6)).abs() < 1e-18);
    }

    #[test]
    fn a_turn_on_spread_widens_only_the_bias_of_a_joint_fit() {
        use EffectKind::*;
        // Two sessions see the same scale error but biases 1e-3 apart (turn-on to turn-on).
        let scale = 2e-3;
        let mut points = Vec::new();
        let mut of_point = Vec::new();
        for (session, bias) in [(0usize, 0.010), (1, 0.011)] {
            for (k, u) in [-1.0, -0.5, 0.5, 1.0].iter().enumerate() {
                let x = Vec3::new(u * 9.8, -u * 4.0, u * 6.0);
                points.push(FitPoint {
                    true_input: x,
                    measured: x * (1.0 + scale) + Vec3::repeat(bias),
                    std_error: Vec3::repeat(1e-4),
                    conditions: Conditions::default(),
                    t_s: 30.0 * k as f64,
                    duration_s: 20.0,
                });
                of_point.push(session);
            }
        }
        let m = model(&[Bias, Scale]);
        let common = Sessions {
            of_point: of_point.clone(),
            turn_on_bias: None,
        };
        let spread = Sessions {
            of_point,
            turn_on_bias: Some([1e-3; 3]),
        };
        let opts = FitOptions::default();
        let a = fit_triad_sessions(&m, Triad::Accel, &points, &common, &opts).unwrap();
        let b = fit_triad_sessions(&m, Triad::Accel, &points, &spread, &opts).unwrap();
        // Common bias: the 1e-3 difference is excess scatter (reduced chi-square >> 1).
        assert!(a.reduced_chi2 > 10.0, "{}", a.reduced_chi2);
        // With the spread: the offsets (0.5 sigma each) are expected, the bias is their mean
        // with a standard error of about 1e-3 / sqrt(2), the scale exact and its error from
        // the white errors alone.
        assert!(b.reduced_chi2 < 0.2, "{}", b.reduced_chi2);
        // (Canonical order: scale.x..z, then bias.x..z.)
        for axis in 0..3 {
            assert!((b.params[axis] - scale).abs() < 1e-9, "{:?}", b.params);
            // The inputs are symmetric about 0 in each session: the white-error value.
            let sxx: f64 = points.iter().map(|p| p.true_input[axis].powi(2)).sum();
            let se_s = b.std_errors[axis].unwrap();
            assert!((se_s / (1e-4 / sxx.sqrt()) - 1.0).abs() < 0.01, "{se_s}");
            assert!((b.params[3 + axis] - 0.0105).abs() < 1e-9, "{:?}", b.params);
            let se_b = b.std_errors[3 + axis].unwrap();
            assert!((se_b - 1e-3 / 2f64.sqrt()).abs() < 0.02e-3, "{se_b}");
        }
    }

    /// The reference's unknown input (Earth's rate without a heading) widens the bias standard
    /// error with a noise model as well as without: a noise model replaces only the drift.
    #[test]
    fn the_unknown_input_widens_the_bias_with_or_without_a_noise_model() {
        let points = timed_points(&[0.0, 40.0, 80.0, 120.0]);
        let m = model(&[EffectKind::Bias]);
        let noise = imu_model::NoiseModel {
            white_density: [1e-3; 3],
            ..Default::default()
        };
        let input = 7.3e-5;
        for with_noise in [false, true] {
            let base = FitOptions {
                noise: with_noise.then(|| noise.clone()),
                ..FitOptions::default()
            };
            let widened = FitOptions {
                bias_input_uncertainty: Some([input; 3]),
                ..base.clone()
            };
            let a = fit_triad(&m, Triad::Gyro, &points, &base).unwrap();
            let b = fit_triad(&m, Triad::Gyro, &points, &widened).unwrap();
            for axis in 0..3 {
                let (sa, sb) = (a.std_errors[axis].unwrap(), b.std_errors[axis].unwrap());
                assert!(
                    (sb * sb - sa * sa - input * input).abs() < 1e-6 * input * input,
                    "noise model {with_noise}: {sa:e} -> {sb:e}"
                );
            }
        }
    }

    #[test]
    fn recovers_exact_parameters_and_flags_unobservable_g_sensitivity() {
        use EffectKind::*;
        let mut truth = model(&[Bias, Scale, Misalignment]);
        let tp: Vec<f64> = (0..truth.n_params())
            .map(|i| 1e-3 * (i as f64 - 4.0))
            .collect();
        truth.set_params(&tp);
        let g = 9.8;
        let dirs = [
            [g, 0.0, 0.0],
            [-g, 0.0, 0.0],
            [0.0, g, 0.0],
            [0.0, -g, 0.0],
            [0.0, 0.0, g],
            [0.0, 0.0, -g],
            [g / 2f64.sqrt(), g / 2f64.sqrt(), 0.0],
            [0.0, g / 2f64.sqrt(), -g / 2f64.sqrt()],
        ];
        let points: Vec<FitPoint> = dirs
            .iter()
            .map(|d| {
                let x = Vec3::from(*d);
                FitPoint {
                    true_input: x,
                    measured: truth.forward(x, &Conditions::default()),
                    std_error: Vec3::repeat(1e-3),
                    conditions: Conditions::default(),
                    t_s: 0.0,
                    duration_s: 0.0,
                }
            })
            .collect();
        let r = fit_triad(
            &model(&[Bias, Scale, Misalignment]),
            Triad::Accel,
            &points,
            &FitOptions::default(),
        )
        .unwrap();
        for (f, t) in r.params.iter().zip(&tp) {
            assert!((f - t).abs() < 1e-9, "{f} vs {t}");
        }
        assert!(r.unobservable.is_empty());

        // Gyro at rest in one orientation: g-sensitivity columns for x/y are zero, the z column
        // is collinear with the bias.
        let gyro = model(&[Bias, GSensitivity]);
        let pts: Vec<FitPoint> = (0..4)
            .map(|k| FitPoint {
                true_input: Vec3::new(1e-5 * k as f64, 0.0, 5e-5),
                measured: Vec3::new(0.01, -0.02, 0.003),
                std_error: Vec3::repeat(1e-4),
                conditions: Conditions {
                    specific_force_m_s2: Vec3::new(0.0, 0.0, g),
                    ..Conditions::default()
                },
                t_s: k as f64,
                duration_s: 0.0,
            })
            .collect();
        let r = fit_triad(&gyro, Triad::Gyro, &pts, &FitOptions::default()).unwrap();
        assert_eq!(r.free.len(), 3, "{:?}", r.unobservable);
        assert_eq!(r.unobservable.len(), 9);
        assert!(r.free.iter().all(|&i| r.names[i].starts_with("bias")));
        assert!(
            (r.params[0] - (0.01 - 1.5e-5)).abs() < 1e-9,
            "{}",
            r.params[0]
        );
    }
}
