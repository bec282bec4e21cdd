//! Weighted Levenberg-Marquardt fit of a `TriadModel`'s parameters to segment means (Aslan &
//! Saranli 3.1.2 and 3.2.2-3.2.3), on the one engine of `imu_stats::lsq`: each observation is a
//! segment's TRUE input, its MEASURED mean and the standard error of that mean; the residual
//! `forward(true) - measured` is whitened by the segment means' covariance (`covariance.rs`);
//! parameters the data cannot separate are held and named; a fitted model imud would reject is
//! refitted with the offending parameter held at 0 (`fit_loadable`).

use super::*;

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
    /// Uncertainty of the true input common to every segment per axis (triad unit; e.g.
    /// Earth's rate where the reference does not fix north), added in quadrature to the
    /// standard errors of `bias.*` always, whatever `mean_noise` says: it is not noise of the
    /// sensor, so no covariance of the segment means carries it.
    pub bias_input_uncertainty: Option<[f64; 3]>,
    /// What the segment means' errors are besides each mean's white standard error.
    pub mean_noise: MeanNoise,
    /// How scatter of the means beyond `mean_noise` is modelled.
    pub excess_scatter: ExcessScatter,
}

/// Bias wander over a recording of `duration_s` from a noise model: bias instability `B` and
/// rate random walk `K` over the span, `sqrt(B^2 + K^2 T / 3)` per axis (the variance of a
/// random walk's deviation from its mean over `T` is `K^2 T / 3`).
pub fn bias_drift_from_noise(noise: &imu_model::NoiseModel, duration_s: f64) -> [f64; 3] {
    std::array::from_fn(|a| {
        (noise.bias_instability[a].powi(2) + noise.random_walk[a].powi(2) * duration_s / 3.0).sqrt()
    })
}

/// The noise of the segment means beyond their white standard errors: one of three sources,
/// so the precedence between them is the type's, not a rule in a comment.
#[derive(Clone, Debug, PartialEq)]
pub enum MeanNoise {
    /// White errors only (the one reduced chi-square scales them); a drift common to every
    /// segment looks exactly like bias, so no residual shows it: `bias_drift`, the standard
    /// deviation of the bias's wander over the recording per axis (triad unit, e.g. from
    /// [`bias_drift_from_noise`]), is added in quadrature to the standard errors of `bias.*`.
    White {
        /// The bias wander, when known.
        bias_drift: Option<[f64; 3]>,
    },
    /// The triad's noise from a noise characterisation (such as imu-noise's), for the
    /// covariance of the segment means: besides each mean's white standard error, the bias
    /// wanders under bias instability `B` (flicker: correlated between nearby segments and more
    /// different between distant ones, see [`segment_covariance`]) and random walk `K`
    /// (`K^2 min(t_k, t_l)`, from the start of the recording). Without it that wander shows
    /// only in the residuals, and the one reduced chi-square that scales the covariance spreads
    /// it evenly over the axes and over near and distant segments: too small standard errors on
    /// a noisy axis and for contrasts between distant segments, too large on a quiet axis. The
    /// covariance carries the bias's wander over the recording, so no drift is added.
    Characterised(imu_model::NoiseModel),
    /// Known correlated noise of the segment means per axis (random walk, flicker): the means
    /// are weighted with the covariance `se_k^2 delta_kl + shared_kl` (see
    /// [`segment_covariance`]).
    Shared([SharedNoise; 3]),
}

/// How scatter of the segment means beyond [`MeanNoise`] is modelled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExcessScatter {
    /// As white scatter: the reduced chi-square scales the covariance (upwards only).
    White,
    /// As a random-walk drift in time, its rate estimated per axis from the residuals (so
    /// contrasts between early and late segments get the larger uncertainty they have); it
    /// replaces the random walk of [`MeanNoise`]. Not the default: on the simulated 3DM-GX1
    /// (flicker-dominated drift, 12-24 segments) the estimated rate is too noisy and the
    /// standard errors came out worse than with white scatter.
    RandomWalk,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            max_iterations: 100,
            tolerance: 1e-12,
            min_eigenvalue: 1e-8,
            fixed: Vec::new(),
            bias_input_uncertainty: None,
            mean_noise: MeanNoise::White { bias_drift: None },
            excess_scatter: ExcessScatter::White,
        }
    }
}

pub use imu_stats::lsq::{NotFitted, Unobservable};

/// One fitted parameter: its typed identity, value, standard error and unit (one entry of a
/// [`FitResult`]'s `parameters`, or of a workbench candidate).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FittedParam {
    /// `<effect>.<param>` (the same as `id.name`, kept for the JSON's readers).
    pub name: String,
    /// Fitted value.
    pub value: f64,
    /// Standard error; `None` for a parameter held fixed or unobservable.
    pub std_error: Option<f64>,
    /// Unit.
    pub unit: String,
    /// Which effect and what it acts on (what programs match on, never the name).
    pub id: imu_model::ParamId,
}

impl FittedParam {
    /// One entry per parameter of `model`, from values, standard errors and units in the
    /// layout of [`TriadModel::params`].
    pub fn list(
        model: &TriadModel,
        values: &[f64],
        std_errors: &[Option<f64>],
        units: &[String],
    ) -> Vec<FittedParam> {
        model
            .param_ids()
            .into_iter()
            .zip(values.iter().zip(std_errors).zip(units))
            .map(|(id, ((&value, &std_error), unit))| FittedParam {
                name: id.name.clone(),
                value,
                std_error,
                unit: unit.clone(),
                id,
            })
            .collect()
    }
}

/// Result of [`fit_triad`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FitResult {
    /// Which triad.
    pub triad: Triad,
    /// The fitted model, with standard errors and residual RMS set (an effect with a held
    /// parameter carries no standard errors).
    #[serde(skip)]
    pub model: TriadModel,
    /// Every parameter, one struct each (identity, value, standard error, unit), layout of
    /// [`TriadModel::params`]; `names`, `units`, `params` and `std_errors` are the same
    /// columns, kept for the JSON's readers and the numeric code.
    pub parameters: Vec<FittedParam>,
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
    /// Poor conditioning, high correlations, held parameters (JSON: `warnings`, the
    /// sentences, and `warning_codes`).
    #[serde(flatten)]
    pub warnings: Warnings,
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

/// The shared noise of [`fit_triad`]: as given, or from a noise characterisation (flicker
/// floor `(0.664 B)^2`, random walk `K^2` starting with the recording at t = 0, so the fitted
/// bias is the bias at its start), or none for white errors.
pub(super) fn shared_noise(opts: &FitOptions, points: &[FitPoint]) -> [SharedNoise; 3] {
    let n = match &opts.mean_noise {
        MeanNoise::Shared(s) => return *s,
        MeanNoise::White { .. } => return [SharedNoise::default(); 3],
        MeanNoise::Characterised(n) => n,
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
pub(super) struct Whitener {
    l_inv: [DMatrix<f64>; 3],
}

impl Whitener {
    pub(super) fn new(
        points: &[FitPoint],
        sessions: &Sessions,
        shared: &[SharedNoise; 3],
    ) -> Whitener {
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
    pub(super) fn apply(&self, raw: &DVector<f64>) -> DVector<f64> {
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
    pub(super) fn axis_chi2(&self, raw: &DVector<f64>, a: usize) -> f64 {
        let n = raw.len() / 3;
        let ra = DVector::from_fn(n, |k, _| raw[3 * k + a]);
        (&self.l_inv[a] * ra).norm_squared()
    }
}

/// Raw residuals `forward(true) - measured` at parameter vector `p` (layout `3 k + axis`).
pub(super) fn raw_residuals(
    model: &mut TriadModel,
    p: &[f64],
    points: &[FitPoint],
) -> DVector<f64> {
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
pub(super) fn lsq_options(opts: &FitOptions) -> LsqOptions {
    LsqOptions {
        max_iterations: opts.max_iterations,
        tolerance: opts.tolerance,
        min_eigenvalue: opts.min_eigenvalue,
        collinear_advice: "; vary the input (e.g. gravity direction) to separate them".into(),
    }
}

/// The triad fit as a least-squares problem: raw residuals `forward(true) - measured` of
/// `points` under `model`, whitened by `w` (none: raw).
pub(super) struct TriadProblem<'a> {
    pub(super) model: &'a mut TriadModel,
    pub(super) points: &'a [FitPoint],
    pub(super) w: Option<&'a Whitener>,
}

impl Residuals for TriadProblem<'_> {
    fn raw(&mut self, p: &[f64]) -> DVector<f64> {
        raw_residuals(self.model, p, self.points)
    }

    fn whiten(&self, raw: DVector<f64>) -> DVector<f64> {
        match self.w {
            Some(w) => w.apply(&raw),
            None => raw,
        }
    }
}

/// [`TriadProblem`] over `points`, whitened by `w`.
pub(super) fn triad_residuals<'a>(
    model: &'a mut TriadModel,
    points: &'a [FitPoint],
    w: Option<&'a Whitener>,
) -> TriadProblem<'a> {
    TriadProblem { model, points, w }
}

/// The drift rate variance `q` of one axis that brings its whitened chi-square down to `dof`
/// (0 if the white errors already explain the scatter), by bisection in log q.
pub(super) fn drift_q(
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
    check_points(triad, points)?;
    let mut m = model.clone();
    let names = m.param_names(triad);
    let units = m.param_units(triad);
    let np = m.n_params();
    let mut p = m.params();
    let (free, unobservable) = free_parameters(&mut m, triad, points, opts, &names, &p)?;
    let n_obs = 3 * points.len();

    let WeightedFit {
        q,
        w,
        cost,
        iterations,
        converged,
    } = fit_weighted(&mut m, points, sessions, opts, &mut p, &free);

    let dof = n_obs - free.len();
    let reduced_chi2 = cost / dof as f64;
    let j = jacobian(&mut triad_residuals(&mut m, points, Some(&w)), &p, &free);
    m.set_params(&p);
    let mut warnings = Vec::new();
    let cov = parameter_covariance(&j, reduced_chi2, &m.param_ids(), &free, opts, &mut warnings);
    let mut std_errors = vec![None; np];
    for (c, &i) in free.iter().enumerate() {
        std_errors[i] = Some(cov[(c, c)].max(0.0).sqrt());
    }
    let correlation = correlations(&cov, &free, &names, &mut warnings);
    for u in &unobservable {
        warnings.push(FitWarning::of_fit(FitWarningKind::NotFitted(u.clone())));
    }
    if !converged {
        warnings.push(FitWarning::of_fit(FitWarningKind::NotConverged {
            iterations,
        }));
    }

    let (residuals_u, residual_rms) = unit_residuals(&m, points);
    let raw_final = raw_residuals(&mut m, &p, points);
    let chi2_axis = std::array::from_fn(|a| w.axis_chi2(&raw_final, a));
    let jacobian_raw = jacobian(&mut triad_residuals(&mut m, points, None), &p, &free);
    m.set_params(&p);
    set_effect_std_errors(&mut m, &std_errors);
    m.residual_rms = Some(residual_rms);

    Ok(FitResult {
        triad,
        parameters: FittedParam::list(&m, &p, &std_errors, &units),
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
        warnings: warnings.into(),
    })
}

/// The free parameters (not held by `opts.fixed`, and observable with white errors from
/// the start `p`) and the unobservable ones; errors for a mask of the wrong length, nothing
/// to fit, or too few observations.
fn free_parameters(
    m: &mut TriadModel,
    triad: Triad,
    points: &[FitPoint],
    opts: &FitOptions,
    names: &[String],
    p: &[f64],
) -> Result<(Vec<usize>, Vec<Unobservable>), FitError> {
    let np = m.n_params();
    if !opts.fixed.is_empty() && opts.fixed.len() != np {
        return Err(FitError::MaskLength {
            triad,
            got: opts.fixed.len(),
            expected: np,
        });
    }
    let mut free: Vec<usize> = (0..np)
        .filter(|&i| !opts.fixed.get(i).copied().unwrap_or(false))
        .collect();
    let lsq = lsq_options(opts);
    // Observability is judged on the white errors alone (secondary effects such as
    // g-sensitivity follow the bias in canonical order, so a g-sensitivity column collinear with
    // a bias goes, not the bias).
    let white = Whitener::new(points, &Sessions::default(), &[SharedNoise::default(); 3]);
    let unobservable = find_unobservable(
        &mut triad_residuals(m, points, Some(&white)),
        p,
        &mut free,
        names,
        &lsq,
    );
    m.set_params(p);
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
    Ok((free, unobservable))
}

/// An error naming the first point with a non-finite value or a standard error that is not
/// positive.
fn check_points(triad: Triad, points: &[FitPoint]) -> Result<(), FitError> {
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
    Ok(())
}

/// The weighted fit: the noise it ends with, and the minimizer's totals.
struct WeightedFit {
    /// Shared noise per axis (random walk estimated when the drift model is on).
    q: [SharedNoise; 3],
    /// The whitener of the last fit.
    w: Whitener,
    /// Final cost (chi-square).
    cost: f64,
    /// Iterations over all fits.
    iterations: usize,
    /// Whether the last fit converged.
    converged: bool,
}

/// Fits `p` (the `free` ones) with white errors; then, if the scatter exceeds them and the
/// drift model is on, estimates per-axis random-walk drift, re-weights and refits until the
/// drift settles (at most 8 times).
fn fit_weighted(
    m: &mut TriadModel,
    points: &[FitPoint],
    sessions: &Sessions,
    opts: &FitOptions,
    p: &mut Vec<f64>,
    free: &[usize],
) -> WeightedFit {
    let lsq = lsq_options(opts);
    let mut q = shared_noise(opts, points);
    let mut w = Whitener::new(points, sessions, &q);
    let first = minimize(&mut triad_residuals(m, points, Some(&w)), p, free, &lsq);
    let (mut cost, mut iterations, mut converged) = (first.cost, first.iterations, first.converged);
    if opts.excess_scatter == ExcessScatter::RandomWalk {
        let dof_axis = (points.len() as f64 - free.len() as f64 / 3.0).max(1.0);
        for _ in 0..8 {
            let raw = raw_residuals(m, p, points);
            let next: [f64; 3] =
                std::array::from_fn(|a| drift_q(points, sessions, &raw, q, a, dof_axis));
            let settled =
                (0..3).all(|a| (next[a] - q[a].random_walk_q).abs() <= 1e-3 * next[a].max(1e-300));
            for (s, v) in q.iter_mut().zip(next) {
                s.random_walk_q = v;
            }
            w = Whitener::new(points, sessions, &q);
            let next = minimize(&mut triad_residuals(m, points, Some(&w)), p, free, &lsq);
            cost = next.cost;
            iterations += next.iterations;
            converged = next.converged;
            if settled {
                break;
            }
        }
    }
    WeightedFit {
        q,
        w,
        cost,
        iterations,
        converged,
    }
}

/// Covariance of the `free` parameters from the Jacobian `j`, scaled by the reduced
/// chi-square only upwards (below 1 the white errors are trusted), with the bias drift and
/// input uncertainty of `opts` added to the biases.
fn parameter_covariance(
    j: &DMatrix<f64>,
    reduced_chi2: f64,
    ids: &[imu_model::ParamId],
    free: &[usize],
    opts: &FitOptions,
    warnings: &mut Vec<FitWarning>,
) -> DMatrix<f64> {
    let mut cov = match covariance(j, reduced_chi2) {
        Some(cov) => cov,
        None => {
            warnings.push(FitWarning::of_fit(FitWarningKind::NoStandardErrors));
            DMatrix::from_element(free.len(), free.len(), f64::NAN)
        }
    };
    let drift = match opts.mean_noise {
        MeanNoise::White { bias_drift } => bias_drift,
        MeanNoise::Characterised(_) | MeanNoise::Shared(_) => None,
    };
    for extra in [drift, opts.bias_input_uncertainty].into_iter().flatten() {
        for (c, &i) in free.iter().enumerate() {
            let axis = Some(&ids[i])
                .filter(|id| id.effect == EffectKind::Bias)
                .and_then(|id| id.role.axis());
            if let Some(axis) = axis {
                cov[(c, c)] += extra[axis].powi(2);
            }
        }
    }
    cov
}

/// Correlation matrix of the free parameters, with a warning for each pair beyond 0.99.
fn correlations(
    cov: &DMatrix<f64>,
    free: &[usize],
    names: &[String],
    warnings: &mut Vec<FitWarning>,
) -> Vec<Vec<f64>> {
    let nf = free.len();
    let mut correlation = vec![vec![0.0; nf]; nf];
    for a_ in 0..nf {
        for b in 0..nf {
            correlation[a_][b] = cov[(a_, b)] / (cov[(a_, a_)] * cov[(b, b)]).sqrt();
            if a_ < b && correlation[a_][b].abs() > 0.99 {
                warnings.push(FitWarning::of_fit(FitWarningKind::Correlated {
                    a: names[free[a_]].clone(),
                    b: names[free[b]].clone(),
                    correlation: correlation[a_][b],
                    evidence: Evidence::Data,
                }));
            }
        }
    }
    correlation
}

/// Residual (model output - measured, in the triad's units) of each point, and their RMS per
/// axis.
fn unit_residuals(m: &TriadModel, points: &[FitPoint]) -> (Vec<[f64; 3]>, [f64; 3]) {
    let mut residuals_u = Vec::with_capacity(points.len());
    let mut sq = [0.0; 3];
    for pt in points {
        let d = m.forward(pt.true_input, &pt.conditions) - pt.measured;
        for a_ in 0..3 {
            sq[a_] += d[a_] * d[a_];
        }
        residuals_u.push([d[0], d[1], d[2]]);
    }
    (residuals_u, sq.map(|s| (s / points.len() as f64).sqrt()))
}

/// Standard errors go into the model per effect; an effect with a held parameter gets none
/// (a 0 would claim the held value is exact).
fn set_effect_std_errors(m: &mut TriadModel, std_errors: &[Option<f64>]) {
    let mut rest = std_errors;
    for e in m.effects_mut() {
        let (mine, tail) = rest.split_at(e.n_params().min(rest.len()));
        rest = tail;
        e.set_std_errors(mine.iter().copied().collect::<Option<Vec<f64>>>());
    }
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
    // Each held parameter: its index and why (the fitted value that made the model invalid).
    let (mut r, held) = refit_holding(
        |held: &[(usize, Unobservable)]| {
            let mut start = model.clone();
            let mut p = start.params();
            let mut fixed = vec![false; model.n_params()];
            for (i, _) in held {
                p[*i] = 0.0;
                fixed[*i] = true;
            }
            start.set_params(&p);
            let o = FitOptions {
                fixed,
                ..opts.clone()
            };
            fit_triad_sessions(&start, triad, points, sessions, &o).map_err(CalibrateError::from)
        },
        |r: &FitResult, held: &[(usize, Unobservable)]| {
            let Err(e) = r.model.validate(triad) else {
                return Ok(None);
            };
            let name = invalid_param_name(&e.key);
            let Some(i) = r
                .names
                .iter()
                .position(|n| *n == name)
                .filter(|&i| held.iter().all(|(h, _)| *h != i))
            else {
                return Err(CalibrateError::InvalidModel {
                    triad,
                    key: e.key,
                    message: e.message,
                });
            };
            let reason = NotFitted::InvalidModel {
                value: r.params[i],
                std_error: r.std_errors[i],
                message: e.message,
            };
            Ok(Some((i, Unobservable { name, reason })))
        },
    )?;
    for (_, u) in held {
        r.warnings
            .push(FitWarning::of_fit(FitWarningKind::NotFitted(u.clone())));
        r.unobservable.push(u);
    }
    Ok(r)
}
