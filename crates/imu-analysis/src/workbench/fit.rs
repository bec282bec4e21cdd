//! Fitting a model to the workbench's observations: the triad fit with the bias wander profiled
//! out, the gravity-magnitude fit, and one candidate added to a model.

use super::*;

impl<'a> Workbench<'a> {
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

    pub(super) fn points(&self, t: Triad) -> (&[FitPoint], &[usize], &NoiseFloor) {
        if t == Triad::Gyro {
            (&self.gyro_points, &self.gyro_index, &self.gyro_floor)
        } else {
            (&self.accel_points, &self.accel_index, &self.accel_floor)
        }
    }

    pub(super) fn fit_opts(&self, t: Triad) -> FitOptions {
        FitOptions {
            fixed: Vec::new(),
            excess_scatter: crate::calibrate::ExcessScatter::White,
            mean_noise: crate::calibrate::MeanNoise::Shared(self.shared(t)),
            ..self.opts.fit.clone()
        }
    }

    /// The gravity-magnitude observations when `t` is the accel of a reference-free workbench.
    pub(super) fn magnitude(&self, t: Triad) -> Option<&Magnitude> {
        self.reference_free_magnitude()
            .filter(|_| t == Triad::Accel)
    }

    /// Reference-free: the gravity-magnitude observation (None with a reference).
    pub(super) fn reference_free_magnitude(&self) -> Option<&Magnitude> {
        match &self.mode {
            Mode::Reference => None,
            Mode::ReferenceFree { magnitude, .. } => Some(magnitude),
        }
    }

    /// Reference-free: the moves between poses and how many were skipped (none with a
    /// reference).
    pub(super) fn moves(&self) -> (&[crate::calibrate::reference_free::MoveData], usize) {
        match &self.mode {
            Mode::Reference => (&[], 0),
            Mode::ReferenceFree {
                moves,
                moves_skipped,
                ..
            } => (moves, *moves_skipped),
        }
    }

    /// Number of residuals of `t`: three per segment, one per pose for gravity magnitudes.
    pub(super) fn n_residuals(&self, t: Triad) -> usize {
        let (points, _, _) = self.points(t);
        if self.magnitude(t).is_some() {
            points.len()
        } else {
            3 * points.len()
        }
    }

    /// Noise parameters profiled out of every fit of `t`: a white scale and a random walk per
    /// axis, or one of each for gravity magnitudes.
    pub(super) fn n_profiled(&self, t: Triad) -> f64 {
        if self.magnitude(t).is_some() {
            2.0
        } else {
            6.0
        }
    }

    /// Generalised chi-square per axis of residuals `res` of `t` under the floor plus `shared`.
    pub(super) fn chi2_axes(
        &self,
        t: Triad,
        res: &[[f64; 3]],
        shared: &[SharedNoise; 3],
    ) -> [f64; 3] {
        let (points, _, _) = self.points(t);
        match self.magnitude(t) {
            Some(mag) => mag.chi2(res, points, shared),
            None => floor_chi2(res, points, shared),
        }
    }

    /// Expected residual RMS per axis of a fit of `t` with raw Jacobian `x`.
    pub(super) fn expected_rms(
        &self,
        t: Triad,
        x: &DMatrix<f64>,
        shared: &[SharedNoise; 3],
    ) -> [f64; 3] {
        let (points, _, _) = self.points(t);
        match self.magnitude(t) {
            Some(mag) => mag.expected_rms(points, x, shared),
            None => expected_residual_rms(points, x, shared),
        }
    }

    /// The noise the segment means of `t` share: the floor's flicker at the median segment
    /// duration (no random walk: the tests profile it).
    pub(super) fn shared(&self, t: Triad) -> [SharedNoise; 3] {
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
    pub fn fittable(
        &self,
        triad: Triad,
        model: &TriadModel,
    ) -> (TriadModel, Option<crate::note::Note>) {
        if triad == Triad::Gyro && self.reference_free_magnitude().is_some() {
            let gains: Vec<EffectKind> =
                model.kinds().into_iter().filter(|k| k.is_gain()).collect();
            if gains.is_empty() {
                return (model.clone(), None);
            }
            let mut m = model.clone();
            for k in &gains {
                m.remove(*k);
            }
            return (
                m,
                Some(crate::note::Note::GainsFromMoves { effects: gains }),
            );
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
    pub(super) fn fit(
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
                mean_noise: crate::calibrate::MeanNoise::Shared(std::array::from_fn(|a| {
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
    pub(super) fn fit_magnitude(
        &self,
        mag: &Magnitude,
        model: &TriadModel,
        family: Option<bool>,
    ) -> Result<Profiled, FitError> {
        let mut family = family;
        let problem = MagnitudeProblem::new(self, mag, model);
        let mut p = problem.start.clone();
        let white = problem.cov(Wander::default()).diagonal().mean();
        let wander_units = (white / span_s(problem.points).max(1e-9), white);
        let (mut scale, mut rho) = (1.0_f64, Wander::default());
        let mut last: Option<Profiled> = None;
        for _ in 0..5 {
            let sol = problem.solve(&p, scale, rho)?;
            let mut m = model.clone();
            m.set_params(&sol.params);
            let x = problem.jacobian(&sol);
            let e = mag.residuals(&m, problem.points);
            let (next_scale, next_rho, loglik) =
                profile_wander(e.as_slice(), |w| problem.cov(w), wander_units, family);
            family = Some(next_rho.flicker);
            let fit = problem.fit_result(m, &sol, &e, x, rho);
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
    pub(super) fn fit_candidate(
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
                    .any(|u| u.reason == NotFitted::ZeroJacobian)
                    && let Ok(r2) = self.fit(triad, &r.fit.model, Some(family))
                {
                    consider(r2);
                }
                consider(r);
            }
        } else {
            for tau in starts {
                let mut m = model.clone();
                let ids = m.param_ids();
                let mut p = m.params();
                // Give the time constant its start and a small amplitude so it is excited.
                for (i, id) in ids.iter().enumerate() {
                    if id.is_time_constant() {
                        p[i] = tau;
                    } else if id.effect == added {
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
}

/// What stays fixed while [`Workbench::fit_magnitude`] alternates the fit with the profiling:
/// the observations, the parameters (the rotation gauge held at 0) and the solver options.
struct MagnitudeProblem<'m> {
    mag: &'m Magnitude,
    model: &'m TriadModel,
    points: &'m [FitPoint],
    shared: [SharedNoise; 3],
    names: Vec<String>,
    units: Vec<String>,
    gauge: Vec<usize>,
    start: Vec<f64>,
    fixed: Vec<bool>,
    lsq: imu_stats::lsq::LsqOptions,
}

impl<'m> MagnitudeProblem<'m> {
    const TRIAD: Triad = Triad::Accel;

    fn new(bench: &'m Workbench<'_>, mag: &'m Magnitude, model: &'m TriadModel) -> Self {
        let names = model.param_names(Self::TRIAD);
        let gauge = crate::calibrate::reference_free::gauge(&model.param_ids());
        let mut start = model.params();
        let mut fixed = vec![false; names.len()];
        for &i in &gauge {
            start[i] = 0.0;
            fixed[i] = true;
        }
        MagnitudeProblem {
            mag,
            model,
            points: &bench.accel_points,
            shared: bench.shared(Self::TRIAD),
            units: model.param_units(Self::TRIAD),
            names,
            gauge,
            start,
            fixed,
            lsq: imu_stats::lsq::LsqOptions {
                max_iterations: bench.opts.fit.max_iterations,
                tolerance: bench.opts.fit.tolerance,
                min_eigenvalue: bench.opts.fit.min_eigenvalue,
                ..imu_stats::lsq::LsqOptions::default()
            },
        }
    }

    /// The magnitude residuals' covariance under bias wander `w`.
    fn cov(&self, w: Wander) -> DMatrix<f64> {
        self.mag
            .covariance(self.points, &self.shared.map(|s| w.scaled(&s, 1.0)))
    }

    /// Generalised least squares from `p` under the covariance of wander `rho` scaled by
    /// `scale`.
    fn solve(
        &self,
        p: &[f64],
        scale: f64,
        rho: Wander,
    ) -> Result<imu_stats::lsq::LsqSolution, FitError> {
        use imu_stats::lsq::{LsqError, least_squares};
        let triad = Self::TRIAD;
        let ch = (self.cov(rho) * scale)
            .cholesky()
            .ok_or(FitError::BadObservation { triad, index: 0 })?;
        let l = ch.l();
        let mut work = self.model.clone();
        let whitened = |q: &[f64]| {
            work.set_params(q);
            let e = self.mag.residuals(&work, self.points);
            l.solve_lower_triangular(&e).unwrap_or(e)
        };
        least_squares(whitened, p, &self.fixed, &self.names, &self.lsq).map_err(|e| match e {
            LsqError::TooFewResiduals {
                n_residuals,
                n_free,
            } => FitError::TooFewObservations {
                triad,
                n_points: self.points.len(),
                n_obs: n_residuals,
                n_free,
            },
            _ => FitError::NothingToFit { triad },
        })
    }

    /// The Jacobian of the raw (unwhitened) residuals at the solution.
    fn jacobian(&self, sol: &imu_stats::lsq::LsqSolution) -> DMatrix<f64> {
        let mut raw = |q: &[f64]| {
            let mut w = self.model.clone();
            w.set_params(q);
            self.mag.residuals(&w, self.points)
        };
        imu_stats::lsq::jacobian(&mut raw, &sol.params, &sol.free)
    }

    /// The fit result of one pass: the model `m` at the solution, its residuals `e` as vectors
    /// along the pose directions, the gauge listed as held, chi-square per axis under wander
    /// `rho`.
    fn fit_result(
        &self,
        mut m: TriadModel,
        sol: &imu_stats::lsq::LsqSolution,
        e: &DVector<f64>,
        x: DMatrix<f64>,
        rho: Wander,
    ) -> FitResult {
        use crate::calibrate::reference_free::{conditioning_warnings, store_std_errors};
        let triad = Self::TRIAD;
        let n = self.points.len();
        let residuals: Vec<[f64; 3]> = e
            .iter()
            .zip(&self.mag.dirs)
            .map(|(v, u)| (u * *v).into())
            .collect();
        let residual_rms: [f64; 3] = std::array::from_fn(|a| {
            (residuals.iter().map(|r| r[a] * r[a]).sum::<f64>() / n.max(1) as f64).sqrt()
        });
        store_std_errors(&mut m, &sol.std_errors, &self.gauge);
        m.residual_rms = Some(residual_rms);
        let mut unobservable: Vec<Unobservable> = self
            .gauge
            .iter()
            .map(|&i| Unobservable {
                name: self.names[i].clone(),
                reason: NotFitted::Gauge,
            })
            .collect();
        unobservable.extend(sol.unobservable.iter().cloned());
        let chi2_axis = self.mag.split(sol.chi2, e.as_slice(), &self.cov(rho));
        FitResult {
            triad,
            parameters: FittedParam::list(&m, &sol.params, &sol.std_errors, &self.units),
            model: m,
            names: self.names.clone(),
            units: self.units.clone(),
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
                sol,
                &self.names,
                crate::calibrate::reference_free::ReferenceFreeOptions::default().weak_eigenvalue,
                crate::calibrate::Evidence::Poses,
            )
            .into(),
        }
    }
}
