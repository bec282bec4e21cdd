//! The covariance of segment means beyond their white errors: bias wander under bias
//! instability (flicker structure function or the noise model's Gauss-Markov bank) and random
//! walk, correlated between segments; recordings (`Sessions`) share no wander.

use super::*;

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
pub(super) fn flicker_structure(n: f64) -> f64 {
    let xlx = |x: f64| if x <= 0.0 { 0.0 } else { x * x * x.ln() };
    xlx(n + 1.0) + xlx((n - 1.0).abs()) - 2.0 * xlx(n)
}

/// Covariance of the means over two segments (`mid`, `len`) of a unit-variance first-order
/// Gauss-Markov process with correlation time `t_s`.
pub(super) fn gauss_markov_mean_cov(
    mid_k: f64,
    len_k: f64,
    mid_l: f64,
    len_l: f64,
    t_s: f64,
) -> f64 {
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
pub(super) const FLICKER_BANK_DT_S: f64 = 0.01;

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

/// The index of the earliest point of each session (None for a session without points).
fn first_of_sessions(points: &[FitPoint], sessions: &Sessions) -> Vec<Option<usize>> {
    let n = points.len();
    let mut first: Vec<Option<usize>> = vec![None; sessions.count(n)];
    for k in 0..n {
        let f = &mut first[sessions.of(k)];
        if f.is_none_or(|j| points[k].t_s < points[j].t_s) {
            *f = Some(k);
        }
    }
    first
}

/// The bank of `shared`'s flicker: (correlation time s, variance) of each Gauss-Markov
/// process; empty without a flicker or a longest correlation time.
fn flicker_bank(shared: &SharedNoise) -> Vec<(f64, f64)> {
    match shared.flicker_tau_max_s {
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
    }
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
    let first = first_of_sessions(points, sessions);
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
    let structure = |k: usize, l: usize| {
        if unit == 0.0 || k == l {
            0.0
        } else {
            let t = 0.5 * (tau(k) + tau(l));
            unit * flicker_structure((points[k].t_s - points[l].t_s).abs() / t)
        }
    };
    // The structure function of every pair, evaluated once (each element of the covariance
    // needs three, and the workbench builds this matrix for every likelihood it profiles):
    // the same value either way round, so the matrix is symmetric exactly.
    let pairs: Vec<f64> = if shared.flicker_tau_max_s.is_none() && unit != 0.0 {
        let mut m = vec![0.0; n * n];
        for k in 0..n {
            for l in k + 1..n {
                let v = structure(k, l);
                m[k * n + l] = v;
                m[l * n + k] = v;
            }
        }
        m
    } else {
        Vec::new()
    };
    let d = |k: usize, l: usize| pairs.get(k * n + l).copied().unwrap_or(0.0);
    let bank = flicker_bank(shared);
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
