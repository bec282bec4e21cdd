//! IEEE Std 952/1293 noise terms (Q, N, B, K, R) from an Allan deviation curve: a weighted,
//! non-negative least-squares fit to the Allan VARIANCE, plus the classic slope read-offs.
//!
//! Model (U = unit of the rate data, e.g. rad/s or m/s^2):
//! `sigma^2(tau) = 3 Q^2/tau^2 + N^2/tau + (2 ln 2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2`, with
//! - Q quantization, U*s;
//! - N angle/velocity random walk (white rate noise), continuous density U/sqrt(Hz) = U*sqrt(s);
//!   the discrete per-sample standard deviation at rate f is N*sqrt(f);
//! - B bias instability, U (the flat ADEV floor is 0.664 B, NOT B);
//! - K rate/acceleration random walk, U*sqrt(Hz) = U/sqrt(s); the per-sample random-walk step
//!   at rate f is K/sqrt(f);
//! - R rate ramp, U/s.
//!
//! The fit is linear in the squared coefficients c = (Q^2, N^2, B^2, K^2, R^2), constrained to
//! c >= 0. With five unknowns, non-negative least squares is solved exactly by trying every one
//! of the 32 passive sets and keeping the best feasible unconstrained solution (the NNLS optimum
//! is the unconstrained optimum on its passive set). Weights are the inverse variance of each
//! Allan-variance estimate, var(sigma^2) = sigma^4 (2 / EDF + 0.05^2) (the second term is a
//! model-error floor, see [`MODEL_ERROR_FLOOR`]); the first pass takes sigma^2 from the data,
//! later passes (iteratively reweighted, 4 in all) from the fitted model, because weights from
//! the noisy data themselves favour points that happen to fall low. Term uncertainties (with
//! [`TermSelection::Supported`]) are the sandwich covariance of that weighted fit under an
//! assumed correlation of the Allan variances at different taus (see `sandwich`; on the passive
//! set; for a term fitted as zero, the 1-sigma upper bound from the full five-term covariance):
//! treating the overlapping estimates as independent made B and K look significant on pure
//! white noise.
//!
//! Term selection ([`fit_terms_with`]): a term is kept only if the curve supports it, i.e. its
//! estimate exceeds [`SIGNIFICANCE_SIGMAS`] standard deviations; the others are dropped one at a
//! time and the rest refitted (a spurious B or R otherwise takes the place of a real K). The
//! rate ramp R is considered only when asked for or when the curve has a ramp region
//! ([`RampTerm`]). [`fit_terms`] keeps the earlier fit of all five terms with independent-point
//! uncertainties ([`TermSelection::AllFive`]), which the workbench's noise floor is built on.

use serde::Serialize;
use thiserror::Error;

use nalgebra::{DMatrix, DVector};

use crate::allan::{DevCurve, DevPoint, Kind};

/// sqrt(2 ln 2 / pi): ADEV floor per unit bias instability.
pub const BIAS_INSTABILITY_FACTOR: f64 = 0.664_282_470_267_960_1;

/// Relative standard deviation added in quadrature to each Allan-variance point's statistical
/// one (2/EDF): short taus have millions of EDF, and without a floor the tiny deviations of real
/// (or simulated) spectra from the idealized power laws there would outweigh every long-tau
/// point, where K and R live.
pub const MODEL_ERROR_FLOOR: f64 = 0.10;

/// Errors of the noise-term fit.
#[derive(Debug, Error, PartialEq)]
pub enum NoiseError {
    /// Not enough usable points (positive deviation, EDF > 0).
    #[error("too few Allan deviation points to fit noise terms: {n_points} usable, need 3")]
    TooFewPoints {
        /// Usable points.
        n_points: usize,
    },
    /// The curve is not an Allan (ADEV/OADEV) curve.
    #[error("noise terms are defined on the Allan variance, got a {kind:?} curve")]
    WrongKind {
        /// The curve's kind.
        kind: Kind,
    },
}

/// One fitted term, in the continuous-time unit stated on the field that holds it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Term {
    /// Estimate (>= 0).
    pub value: f64,
    /// 1-sigma uncertainty (for a zero estimate: a 1-sigma upper bound).
    pub sigma: f64,
    /// `value > SIGNIFICANCE_SIGMAS * sigma` (2 sigma with [`TermSelection::AllFive`]): the
    /// data need this term.
    pub significant: bool,
}

/// Standard deviations a term's estimate must exceed to be reported significant (and kept).
/// Three, not two: an axis tests up to four terms and a recording has six axes, so at 2 sigma
/// about one recording in two would show a spurious term (20 white-noise seeds at 2 sigma gave
/// two false B/K; see `tests/noise_fit_truth.rs`).
pub const SIGNIFICANCE_SIGMAS: f64 = 3.0;

/// The five IEEE terms fitted to an Allan variance, in units of U (the rate unit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseTerms {
    /// Quantization noise Q, U*s.
    pub q_u_s: Term,
    /// White rate noise (angle/velocity random walk) N, U/sqrt(Hz).
    pub n_u_per_sqrt_hz: Term,
    /// Bias instability B, U.
    pub b_u: Term,
    /// Rate/acceleration random walk K, U*sqrt(Hz) (= U/sqrt(s)).
    pub k_u_sqrt_hz: Term,
    /// Rate ramp R, U/s.
    pub r_u_per_s: Term,
    /// Weighted residual sum of squares per degree of freedom (~1 for a good fit).
    pub chi2_per_dof: f64,
    /// Points used.
    pub n_points: usize,
    /// Of those, the Theo1 points beyond the largest Allan tau ([`fit_terms_extended`]); 0
    /// when the fit used the Allan curve alone.
    pub n_theo1_points: usize,
}

impl NoiseTerms {
    /// The model's Allan deviation at `tau_s`, in U.
    pub fn adev(&self, tau_s: f64) -> f64 {
        let c = self.coefficients();
        basis(tau_s)
            .iter()
            .zip(c)
            .map(|(a, c)| a * c)
            .sum::<f64>()
            .sqrt()
    }

    /// Allan deviation of each term alone at `tau_s` (Q, N, B, K, R), in U.
    pub fn term_adevs(&self, tau_s: f64) -> [f64; 5] {
        let c = self.coefficients();
        let a = basis(tau_s);
        std::array::from_fn(|i| (a[i] * c[i]).sqrt())
    }

    /// The five terms in the order Q, N, B, K, R.
    pub fn as_array(&self) -> [Term; 5] {
        [
            self.q_u_s,
            self.n_u_per_sqrt_hz,
            self.b_u,
            self.k_u_sqrt_hz,
            self.r_u_per_s,
        ]
    }

    fn coefficients(&self) -> [f64; 5] {
        [
            self.q_u_s.value,
            self.n_u_per_sqrt_hz.value,
            self.b_u.value,
            self.k_u_sqrt_hz.value,
            self.r_u_per_s.value,
        ]
        .map(|v| v * v)
    }

    /// Discrete per-sample standard deviation of the white noise at `rate_hz`: N sqrt(rate), U.
    pub fn white_per_sample_u(&self, rate_hz: f64) -> f64 {
        self.n_u_per_sqrt_hz.value * rate_hz.sqrt()
    }

    /// Discrete per-sample random-walk step at `rate_hz`: K / sqrt(rate), U.
    pub fn random_walk_step_per_sample_u(&self, rate_hz: f64) -> f64 {
        self.k_u_sqrt_hz.value / rate_hz.sqrt()
    }
}

/// Regressors of the Allan variance model for (Q^2, N^2, B^2, K^2, R^2) at `tau_s`.
fn basis(tau_s: f64) -> [f64; 5] {
    [
        3.0 / (tau_s * tau_s),
        1.0 / tau_s,
        BIAS_INSTABILITY_FACTOR * BIAS_INSTABILITY_FACTOR,
        tau_s / 3.0,
        tau_s * tau_s / 2.0,
    ]
}

/// Solves the normal equations `a x = b` of one passive set (columns scaled to unit norm, so
/// the absolute pivot threshold is relative); returns the inverse as well. `None` if singular.
fn solve(a: &DMatrix<f64>, b: &DVector<f64>) -> Option<(DVector<f64>, DMatrix<f64>)> {
    crate::linear::solve_with_inverse(a, b, 1e-13)
}

/// Whether the rate-ramp term R is fitted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RampTerm {
    /// Only when the curve has a rate-ramp region: somewhere it rises significantly faster
    /// than the +1/2 slope of a random walk (see [`ramp_region_present`]).
    #[default]
    Auto,
    /// Always fitted.
    Include,
    /// Never fitted.
    Exclude,
}

/// Options of [`fit_terms_with`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FitOptions {
    /// Which terms are reported, and how their significance is judged.
    pub selection: TermSelection,
    /// Whether the rate ramp R is fitted (with [`TermSelection::Supported`]).
    pub ramp: RampTerm,
}

/// How the fit decides which terms the curve supports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum TermSelection {
    /// Only the terms the curve supports: correlated-tau (sandwich) uncertainties,
    /// [`SIGNIFICANCE_SIGMAS`], insignificant terms dropped and the rest refitted (see
    /// [`fit_terms_with`]). What imu-noise reports.
    #[default]
    Supported,
    /// All five terms as fitted, uncertainties as if the points were independent, significant
    /// at 2 sigma: the fit [`fit_terms`] has always made, which the workbench's noise floor
    /// (and its calibrated negative controls) is built on. It reports spurious B and K on some
    /// white-noise records.
    AllFive,
}

/// All five terms as fitted ([`TermSelection::AllFive`]): the workbench floor's fit. For terms
/// the curve supports, use [`fit_terms_with`] and the default options.
pub fn fit_terms(curve: &DevCurve) -> Result<NoiseTerms, NoiseError> {
    fit_terms_with(
        curve,
        &FitOptions {
            selection: TermSelection::AllFive,
            ramp: RampTerm::Include,
        },
    )
}

/// Fits the IEEE terms to an ADEV/OADEV curve (see the module docs). The curve's EDF weights
/// the points; the units of the result are those of the rate data. Terms the curve does not
/// support are left out: starting from all five (R only as `options.ramp` says), the least
/// significant of Q, B, K, R whose estimate is not significant is dropped and the rest refitted,
/// until every remaining term is significant (N, the white noise, always stays). A dropped term
/// is reported as 0 with a 1-sigma upper bound.
pub fn fit_terms_with(curve: &DevCurve, options: &FitOptions) -> Result<NoiseTerms, NoiseError> {
    fit_terms_extended(curve, None, options)
}

/// As [`fit_terms_with`], with the points of a Theo1 curve of the same record (`theo1`,
/// [`Kind::Theo1`]) whose averaging times lie beyond the Allan curve's largest one (by more
/// than Theo1's tau resolution, 0.75 tau0): Theo1
/// reaches 75 % of the record where the Allan variance stops at half of it (in practice at the
/// last octave below), and there a rate random walk or ramp is plainest.
///
/// Theo1 is not the Allan variance: its expectation is a different functional of the noise
/// (SP 1065 section 5.2.14; Allan-compatible only for white FM). Each Theo1 point is therefore
/// modelled by its own expectation under each term, `theo1_basis` (exact for the same power-law
/// models the Allan basis assumes), not by a bias ratio: no rescaling (TheoBR's ratio assumes one
/// noise type at every tau, which a white-noise floor below a random walk is not). Its weight
/// follows from the same chi-square argument as the Allan points': an estimate with EDF nu has
/// variance 2 E[Theo1]^2 / nu, so the relative variance is 2 / nu plus the model-error floor,
/// with nu Theo1's EDF (SP 1065 Table 12, `edf_theo1`) for the noise type of the term that
/// dominates the model there (the curve's own EDF when smaller, as for the Allan points). The
/// Allan points' stop-ratio down-weighting is not applied: Theo1's EDF already counts the few
/// independent long-term differences left. The correlation between neighbouring taus (the
/// sandwich) takes the Theo1 points in tau order with the Allan ones.
pub fn fit_terms_extended(
    curve: &DevCurve,
    theo1: Option<&DevCurve>,
    options: &FitOptions,
) -> Result<NoiseTerms, NoiseError> {
    if !matches!(curve.kind, Kind::Adev | Kind::Oadev) {
        return Err(NoiseError::WrongKind { kind: curve.kind });
    }
    if let Some(t) = theo1
        && t.kind != Kind::Theo1
    {
        return Err(NoiseError::WrongKind { kind: t.kind });
    }
    let usable = |p: &&DevPoint| p.dev > 0.0 && p.dev.is_finite() && p.edf > 0.0;
    let mut pts: Vec<FitPoint> = curve
        .points
        .iter()
        .filter(usable)
        .map(|p| FitPoint {
            p,
            basis: basis(p.tau_s),
            theo: false,
        })
        .collect();
    let longest = pts.iter().map(|f| f.p.tau_s).fold(0.0, f64::max);
    if let Some(t) = theo1 {
        pts.extend(
            t.points
                .iter()
                .filter(usable)
                // Theo1's taus are 0.75 m tau0 with m even, a grid of 1.5 tau0: one within
                // 0.75 tau0 of the longest Allan tau is the same averaging time.
                .filter(|p| p.tau_s > longest + 0.75 * t.tau0_s)
                .map(|p| FitPoint {
                    p,
                    basis: theo1_basis(p.m, t.tau0_s),
                    theo: true,
                }),
        );
    }
    pts.sort_by(|a, b| a.p.tau_s.total_cmp(&b.p.tau_s));
    if pts.len() < 3 {
        return Err(NoiseError::TooFewPoints {
            n_points: pts.len(),
        });
    }
    let mut allowed = [true; 5];
    allowed[4] = match options.ramp {
        RampTerm::Include => true,
        RampTerm::Exclude => false,
        RampTerm::Auto => ramp_region_present(curve),
    };
    if options.selection == TermSelection::AllFive {
        return fit_allowed(None, &pts, &[true; 5], Uncertainty::Independent).map(|f| f.terms);
    }
    let record = single_record(curve.kind, &pts);
    let mut current = fit_allowed(record, &pts, &allowed, Uncertainty::CorrelatedTaus)?;
    loop {
        let t = current.terms.as_array();
        let drop = [0, 2, 3, 4]
            .into_iter()
            .filter(|&j| allowed[j] && t[j].value > 0.0 && !t[j].significant)
            .min_by(|&i, &j| (t[i].value / t[i].sigma).total_cmp(&(t[j].value / t[j].sigma)));
        let Some(j) = drop else {
            return Ok(current.terms);
        };
        let mut fewer = allowed;
        fewer[j] = false;
        let reduced = fit_allowed(record, &pts, &fewer, Uncertainty::CorrelatedTaus)?;
        // A term the residuals cannot do without stays even if its estimate is uncertain (an
        // exact curve's tiny Q): the drop may not raise the weighted residual sum by more than
        // DROP_F times the fuller fit's residual variance.
        let scale = current.rss / current.dof as f64;
        if reduced.rss - current.rss > DROP_F * scale {
            return Ok(current.terms);
        }
        allowed = fewer;
        current = reduced;
    }
}

/// Largest rise of the weighted residual sum of squares, in units of the fuller fit's residual
/// variance, for which an insignificant term is dropped.
const DROP_F: f64 = 25.0;

/// A fit with its weighted residual sum of squares and degrees of freedom.
struct Fitted {
    terms: NoiseTerms,
    rss: f64,
    dof: usize,
}

/// The iteratively reweighted NNLS fit over the allowed terms, with each term's uncertainty.
/// How the term uncertainties treat the points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Uncertainty {
    /// As independent (the inverse normal matrix; significance at 2 sigma).
    Independent,
    /// As correlated between taus (the sandwich; significance at [`SIGNIFICANCE_SIGMAS`]).
    CorrelatedTaus,
}

fn fit_allowed(
    record: Option<usize>,
    pts: &[FitPoint],
    allowed: &[bool; 5],
    uncertainty: Uncertainty,
) -> Result<Fitted, NoiseError> {
    // Iteratively reweighted: the first pass weights by the measured variance, later passes by
    // the fitted model's (measured-variance weights favour points that happen to fall low).
    let mut reference: Option<[f64; 5]> = None;
    let mut result = None;
    for _ in 0..IRLS_PASSES {
        let pass = nnls_pass(record, pts, reference.as_ref(), allowed)?;
        reference = Some(pass.c);
        result = Some(pass);
    }
    let Pass {
        rss,
        c,
        set,
        inv,
        scale,
    } = result.expect("IRLS_PASSES > 0");
    let rows = weighted_rows(record, pts, Some(&c));
    let taus: Vec<f64> = pts.iter().map(|f| f.p.tau_s).collect();
    let correlated = uncertainty == Uncertainty::CorrelatedTaus;
    let cov = if correlated {
        sandwich(&rows, &taus, &scale, &set, &inv)
    } else {
        inv
    };
    let all = [0, 1, 2, 3, 4];
    let full =
        solve(&normal_equations(&rows, &scale, &all).0, &DVector::zeros(5)).map(|(_, inv)| {
            if correlated {
                sandwich(&rows, &taus, &scale, &all, &inv)
            } else {
                inv
            }
        });
    let threshold = if correlated { SIGNIFICANCE_SIGMAS } else { 2.0 };
    let term = |j: usize| -> Term {
        let var_c = if let Some(k) = set.iter().position(|&s| s == j) {
            cov[(k, k)] / (scale[j] * scale[j])
        } else if let Some(f) = &full {
            f[(j, j)] / (scale[j] * scale[j])
        } else {
            f64::NAN
        };
        let sd_c = var_c.max(0.0).sqrt();
        let value = c[j].sqrt();
        let sigma = if c[j] > 0.0 {
            sd_c / (2.0 * value)
        } else {
            sd_c.sqrt()
        };
        Term {
            value,
            sigma,
            significant: value > threshold * sigma,
        }
    };
    let dof = pts.len().saturating_sub(set.len()).max(1);
    let terms = NoiseTerms {
        q_u_s: term(0),
        n_u_per_sqrt_hz: term(1),
        b_u: term(2),
        k_u_sqrt_hz: term(3),
        r_u_per_s: term(4),
        chi2_per_dof: rss / dof as f64,
        n_points: pts.len(),
        n_theo1_points: pts.iter().filter(|f| f.theo).count(),
    };
    Ok(Fitted { terms, rss, dof })
}

/// Covariance of the weighted least-squares estimate (scaled columns, on `set`) when the
/// whitened residuals are correlated as overlapping Allan variances are: the sandwich
/// `inv (A^T R A) inv`, with the assumed correlation `R_ij = sqrt(tau_i / tau_j)` for
/// `tau_i <= tau_j` (estimates at nearby taus share most of their data; an octave apart about
/// 0.7, a decade apart about 0.3). Treating the points as independent made B and K look
/// significant on pure white noise. The correlation is separable, so `A^T R A` is one pass with
/// a running sum (O(points), not O(points^2), for curves with thousands of taus).
fn sandwich(
    rows: &Rows,
    taus: &[f64],
    scale: &[f64; 5],
    set: &[usize],
    inv: &DMatrix<f64>,
) -> DMatrix<f64> {
    let k = set.len();
    let mut m = DMatrix::<f64>::zeros(k, k);
    let mut running = DVector::<f64>::zeros(k);
    for ((a, _), &tau) in rows.iter().zip(taus) {
        let row = DVector::from_fn(k, |r, _| a[set[r]] / scale[set[r]]);
        let root = tau.sqrt();
        // Earlier (shorter) taus i < j: sum_i row_i sqrt(tau_i), times row_j / sqrt(tau_j).
        let cross = &running * row.transpose() / root;
        m += &row * row.transpose() + &cross + cross.transpose();
        running += &row * root;
    }
    inv * m * inv
}

/// Whether the curve shows a rate-ramp region: two points an octave or more apart between
/// which the deviation rises faster than a random walk (+1/2 slope) could make it even at the
/// ends of their confidence intervals, i.e. `dev_lo(later) > dev_hi(earlier) (tau ratio)^(1/2)`,
/// with a mean slope of at least +3/4 (a ramp's +1).
pub fn ramp_region_present(curve: &DevCurve) -> bool {
    let p = &curve.points;
    p.iter().enumerate().any(|(i, a)| {
        p[i + 1..].iter().any(|b| {
            let ratio = b.tau_s / a.tau_s;
            let slope = (b.dev / a.dev).ln() / ratio.ln();
            ratio >= 2.0 && slope >= 0.75 && b.dev_lo > a.dev_hi * ratio.sqrt()
        })
    })
}

/// The classic graphical read-offs, for comparison with the fit (units of U as in
/// [`NoiseTerms`]); `None` where the curve has no segment of the needed slope.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SlopeReadoffs {
    /// N: sigma(tau) sqrt(tau) at the point whose local slope is nearest -1/2 (the -1/2 line
    /// through it, read at tau = 1 s), U/sqrt(Hz).
    pub n_u_per_sqrt_hz: Option<f64>,
    /// B: minimum ADEV / 0.664, U.
    pub b_u: Option<f64>,
    /// K: sigma(tau) sqrt(3/tau) at the point whose local slope is nearest +1/2 (the +1/2 line
    /// read at tau = 3 s), U*sqrt(Hz).
    pub k_u_sqrt_hz: Option<f64>,
}

/// Passes of the iteratively reweighted fit.
const IRLS_PASSES: usize = 4;

fn model_var(c: &[f64; 5], basis: &[f64; 5]) -> f64 {
    basis.iter().zip(c).map(|(a, c)| a * c).sum()
}

/// One point of the fit: the estimate, its regressors (the model's expectation of it per unit
/// squared term) and whether it is a Theo1 point.
struct FitPoint<'a> {
    p: &'a DevPoint,
    basis: [f64; 5],
    theo: bool,
}

/// Regressors of a Theo1 point at averaging factor `m` (tau = 0.75 m tau0): the expectation of
/// the Theo1 variance per unit (Q^2, N^2, B^2, K^2, R^2). Each Theo1 term
/// `(x_i - x_{i+u}) + (x_{i+m} - x_{i+m-u})` is a linear combination of phase values whose
/// weights sum to zero and have zero first moment, so for a phase with (generalized) structure
/// function D its mean square is `2 D(u) + 2 D(m - u) - D(m) - D(m - 2u)`, and
/// `E[Theo1] = sum_{u=1}^{m/2} (1/u) (2 D(u) + 2 D(m-u) - D(m) - D(m-2u)) / (0.75 m^2 tau0^2)`.
/// The D of each term is the one whose Allan variance is that term's `basis`:
/// white PM `2 Q^2` (t != 0), white FM `N^2 t`, flicker FM `-(B^2/pi) t^2 ln t`, random-walk FM
/// `-K^2 t^3 / 6`; the ramp is deterministic (phase `R t^2 / 2`: each term is
/// `R tau0^2 u (m - u)`). For white FM this is exactly the Allan variance at 0.75 m tau0
/// (Theo1 is Allan-compatible there); for the others it gives Theo1's bias: the Allan variance
/// at the same tau over E[Theo1] is 0.13 (white PM), 1.86 (flicker FM), 2.70 (random walk) and
/// 3.68 (ramp) at large m. O(m) per point.
fn theo1_basis(m: usize, tau0_s: f64) -> [f64; 5] {
    let d = |j: usize, k: usize| -> f64 {
        if k == 0 {
            return 0.0;
        }
        let t = k as f64 * tau0_s;
        match j {
            0 => 2.0,
            1 => t,
            2 => -t * t * t.ln() / std::f64::consts::PI,
            _ => -t * t * t / 6.0,
        }
    };
    let mut g = [0.0; 5];
    for u in 1..=m / 2 {
        let inv_u = 1.0 / u as f64;
        for (j, g) in g.iter_mut().enumerate().take(4) {
            *g += inv_u * (2.0 * d(j, u) + 2.0 * d(j, m - u) - d(j, m) - d(j, m - 2 * u));
        }
        let ramp = tau0_s * tau0_s * (u * (m - u)) as f64;
        g[4] += inv_u * ramp * ramp;
    }
    let norm = 0.75 * (m as f64 * tau0_s).powi(2);
    g.map(|v| v / norm)
}

type Rows = Vec<([f64; 5], f64)>;

/// Stable32's stop ratio for the Allan variances: taus past a quarter of the record rest on one
/// or two independent differences, whose chance excursions move all those points together (a
/// white-noise hour whose last three taus sat 2.5 to 12 times above the white variance gave a
/// "significant" K).
const STOP_RATIO: usize = 4;

/// Variance factor of the points past the stop ratio: they stay in the fit (an exact curve is
/// still fitted exactly) but with a tenth of their weight.
const BEYOND_STOP_VARIANCE_FACTOR: f64 = 10.0;

/// Phase points of the one record behind an OADEV curve (n_terms + 2m, the same at every
/// point); `None` for ADEV curves and for curves pooled over several records (or made up), where
/// the EDF refinements below are not applied and the curve's own EDF is used as given.
fn single_record(kind: Kind, pts: &[FitPoint]) -> Option<usize> {
    if kind != Kind::Oadev {
        return None;
    }
    // Theo1 points have n_terms = N - m.
    let phase = |f: &FitPoint| f.p.n_terms + if f.theo { f.p.m } else { 2 * f.p.m };
    let n = pts.first().map(phase)?;
    pts.iter().all(|f| phase(f) == n).then_some(n)
}

/// Greenhall's EDF of point `p` for the noise type of the model term that dominates at its tau
/// (Q white PM, N white FM, B flicker FM, K and R random-walk FM). The weights use the smaller
/// of this and the curve's own EDF: a noise type identified from a few dozen decimated points
/// at long taus can be wrong (white FM taken for flicker PM gave a point ten times the EDF it
/// has, and a spurious K), and neither estimate should give a point more weight than the other.
fn model_edf(n_phase: usize, f: &FitPoint, c: &[f64; 5]) -> f64 {
    let a = f.basis;
    let dominant = (0..5)
        .max_by(|&i, &j| (a[i] * c[i]).total_cmp(&(a[j] * c[j])))
        .unwrap_or(1);
    let alpha = [2, 0, -1, -2, -2][dominant];
    if f.theo {
        return crate::allan::edf_theo1(alpha, f.p.m, n_phase);
    }
    match Kind::Oadev.estimator() {
        Some(est) => crate::allan::edf_greenhall(alpha, est, f.p.m, n_phase),
        None => f.p.edf,
    }
}

fn weighted_rows(record: Option<usize>, pts: &[FitPoint], reference: Option<&[f64; 5]>) -> Rows {
    pts.iter()
        .map(|f| {
            let p = f.p;
            let avar = p.dev * p.dev;
            let ref_var = reference.map_or(avar, |c| model_var(c, &f.basis).max(0.1 * avar));
            let mut edf = p.edf;
            let mut rel_factor = 1.0;
            if let Some(n_phase) = record {
                if let Some(c) = reference {
                    edf = edf.min(model_edf(n_phase, f, c));
                }
                if !f.theo && p.m * STOP_RATIO > n_phase {
                    rel_factor = BEYOND_STOP_VARIANCE_FACTOR;
                }
            }
            let rel_var = (2.0 / edf + MODEL_ERROR_FLOOR * MODEL_ERROR_FLOOR) * rel_factor;
            let sw = 1.0 / (rel_var.sqrt() * ref_var);
            (f.basis.map(|a| a * sw), avar * sw)
        })
        .collect()
}

fn normal_equations(rows: &Rows, scale: &[f64; 5], set: &[usize]) -> (DMatrix<f64>, DVector<f64>) {
    let n = set.len();
    let ata = DMatrix::from_fn(n, n, |r, c| {
        let (i, j) = (set[r], set[c]);
        rows.iter()
            .map(|(a, _)| a[i] / scale[i] * a[j] / scale[j])
            .sum()
    });
    let atb = DVector::from_fn(n, |r, _| {
        let i = set[r];
        rows.iter().map(|(a, b)| a[i] / scale[i] * b).sum()
    });
    (ata, atb)
}

/// Best passive-set solution: (cost, coefficients, passive set, inverse normal matrix).
type Candidate = (f64, [f64; 5], Vec<usize>, DMatrix<f64>);

/// One NNLS pass: weighted residual sum of squares, coefficients (Q^2 .. R^2), passive set,
/// inverse of its scaled normal matrix, column scales.
struct Pass {
    rss: f64,
    c: [f64; 5],
    set: Vec<usize>,
    inv: DMatrix<f64>,
    scale: [f64; 5],
}

/// One exact NNLS solve over every non-empty passive set of allowed terms.
fn nnls_pass(
    record: Option<usize>,
    pts: &[FitPoint],
    reference: Option<&[f64; 5]>,
    allowed: &[bool; 5],
) -> Result<Pass, NoiseError> {
    let rows = weighted_rows(record, pts, reference);
    // Column scaling for conditioning.
    let scale: [f64; 5] = std::array::from_fn(|j| {
        rows.iter()
            .map(|(a, _)| a[j] * a[j])
            .sum::<f64>()
            .sqrt()
            .max(f64::MIN_POSITIVE)
    });
    let normal = |set: &[usize]| normal_equations(&rows, &scale, set);
    let cost = |c: &[f64; 5]| -> f64 {
        rows.iter()
            .map(|(a, b)| {
                let r = b - (0..5).map(|j| a[j] * c[j]).sum::<f64>();
                r * r
            })
            .sum()
    };
    let mut best: Option<Candidate> = None;
    for mask in 1u32..32 {
        let set: Vec<usize> = (0..5).filter(|j| mask & (1 << j) != 0).collect();
        if set.len() > pts.len() || set.iter().any(|&j| !allowed[j]) {
            continue;
        }
        let (ata, atb) = normal(&set);
        let Some((x, inv)) = solve(&ata, &atb) else {
            continue;
        };
        if x.iter().any(|&v| v < 0.0) {
            continue;
        }
        let mut c = [0.0; 5];
        for (&j, v) in set.iter().zip(&x) {
            c[j] = v / scale[j];
        }
        let r = cost(&c);
        if best.as_ref().is_none_or(|b| r < b.0) {
            best = Some((r, c, set, inv));
        }
    }
    let Some((rss, c, set, inv)) = best else {
        return Err(NoiseError::TooFewPoints {
            n_points: pts.len(),
        });
    };
    Ok(Pass {
        rss,
        c,
        set,
        inv,
        scale,
    })
}

/// Reads N, B, K off the curve by slope (tolerance +-0.15 on the slope).
pub fn slope_readoffs(curve: &DevCurve) -> SlopeReadoffs {
    let p = &curve.points;
    let slopes: Vec<(usize, f64)> = (0..p.len())
        .filter_map(|i| {
            let (a, b) = (i.checked_sub(1)?, i + 1);
            let b = p.get(b)?;
            let s = (b.dev / p[a].dev).ln() / (b.tau_s / p[a].tau_s).ln();
            s.is_finite().then_some((i, s))
        })
        .collect();
    let nearest = |target: f64| {
        slopes
            .iter()
            .filter(|(_, s)| (s - target).abs() < 0.15)
            .min_by(|a, b| (a.1 - target).abs().total_cmp(&(b.1 - target).abs()))
            .map(|&(i, _)| &p[i])
    };
    SlopeReadoffs {
        n_u_per_sqrt_hz: nearest(-0.5).map(|q| q.dev * q.tau_s.sqrt()),
        b_u: p
            .iter()
            .map(|q| q.dev)
            .filter(|d| *d > 0.0)
            .min_by(f64::total_cmp)
            .map(|d| d / BIAS_INSTABILITY_FACTOR),
        k_u_sqrt_hz: nearest(0.5).map(|q| q.dev * (3.0 / q.tau_s).sqrt()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_model_curve_is_recovered() {
        let truth = [1e-6, 1e-3, 2e-4, 1e-5, 0.0];
        let points = (0..30)
            .map(|i| {
                let tau = 0.01 * 2f64.powi(i);
                let b = basis(tau);
                let dev = (0..5)
                    .map(|j| b[j] * truth[j] * truth[j])
                    .sum::<f64>()
                    .sqrt();
                DevPoint {
                    m: 1 << i,
                    tau_s: tau,
                    dev,
                    n_terms: 100,
                    edf: 100.0,
                    dev_lo: dev,
                    dev_hi: dev,
                }
            })
            .collect();
        let curve = DevCurve {
            kind: Kind::Oadev,
            tau0_s: 0.01,
            confidence: 0.683,
            points,
        };
        let t = fit_terms(&curve).unwrap();
        assert!((t.n_u_per_sqrt_hz.value / 1e-3 - 1.0).abs() < 1e-6, "{t:?}");
        assert!((t.b_u.value / 2e-4 - 1.0).abs() < 1e-6);
        assert!((t.k_u_sqrt_hz.value / 1e-5 - 1.0).abs() < 1e-6);
        assert!((t.q_u_s.value / 1e-6 - 1.0).abs() < 1e-4);
        assert!(t.r_u_per_s.value < 1e-9);
        assert!((t.adev(1.0) / fit_model_dev(&truth, 1.0) - 1.0).abs() < 1e-6);
        // The read-off overestimates B where the N and K terms overlap the floor: that bias is
        // why the fit exists.
        let r = slope_readoffs(&curve);
        let b = r.b_u.unwrap();
        assert!(b > 2e-4 && b < 2e-4 * 1.6, "{r:?}");
    }

    /// Theo1's expectation per term against what it must be: for white FM exactly the Allan
    /// variance at 0.75 m tau0 (Theo1 is Allan-compatible there); for a rate ramp exactly the
    /// Theo1 of the ramp's phase (deterministic, so the estimator itself is the truth); for a
    /// random walk the large-m bias ratio AVAR/Theo1 of the closed form,
    /// (1/3) 0.75 / (sum_u (2u^3 + 2(m-u)^3 - m^3 - (m-2u)^3) / (-6u)) / (0.75 m^2)) -> 2.698.
    #[test]
    fn theo1_basis_is_theo1s_expectation() {
        let tau0 = 0.01;
        for m in [10usize, 12, 100, 1366] {
            let g = theo1_basis(m, tau0);
            let tau = 0.75 * m as f64 * tau0;
            assert!((g[1] / basis(tau)[1] - 1.0).abs() < 1e-12, "m {m}: {g:?}");
            // x = R t^2 / 2 with R = 1 on n points.
            let n = 3 * m;
            let x: Vec<f64> = (0..n).map(|i| 0.5 * (i as f64 * tau0).powi(2)).collect();
            let theo = crate::allan::theo1_variance(&x, m, tau0).unwrap();
            assert!(
                (g[4] / theo - 1.0).abs() < 1e-9,
                "m {m}: {} vs {theo}",
                g[4]
            );
        }
        let m = 20_000;
        let g = theo1_basis(m, 1.0);
        let ratio = basis(0.75 * m as f64)[3] / g[3];
        assert!((ratio - 2.698).abs() < 2e-3, "{ratio}");
    }

    fn fit_model_dev(c: &[f64; 5], tau: f64) -> f64 {
        let b = basis(tau);
        (0..5).map(|j| b[j] * c[j] * c[j]).sum::<f64>().sqrt()
    }
}
