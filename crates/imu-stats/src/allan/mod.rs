//! Allan-family deviations of rate ("fractional frequency") data: ADEV, OADEV, MDEV, HDEV,
//! OHDEV, TDEV, TOTDEV (NIST SP 1065 definitions), tau sets, EDF-based confidence intervals and a
//! bounded-memory streaming OADEV for multi-day recordings.
//!
//! Input is a rate series `y` (e.g. gyro rad/s or accel m/s^2) sampled every `tau0_s`. It is
//! integrated once into the phase `x[0] = 0, x[i+1] = tau0 * sum(y[0..=i])` (the same order of
//! operations as allantools, so results agree to rounding), and every deviation is then an O(N)
//! pass over `x` (MDEV/TDEV's inner m-term sums follow a running recurrence, O(1) a step).
//! The deviation comes out in the unit of `y`. Every kind sums all its taus in one fused
//! cache-blocked pass (`kernels.rs`, `passes.rs`) whose kernels pick the CPU's widest SIMD at
//! run time (AVX2 with FMA on x86-64 v3 and later, through the `pulp` crate, whose dispatch
//! keeps this crate free of `unsafe`); the build itself stays baseline x86-64.
//!
//! Confidence intervals ([`EdfMethod`]): either Greenhall's EDF algorithm with the noise type
//! identified per tau as Stable32 does (the lag-1 autocorrelation of the m-averaged frequency,
//! the B1 ratio or the previous tau's type, by how many averages remain), as Stable32 computes
//! them (`greenhall.rs`, `noise_id.rs`; total deviation by NIST SP 1065 Table 7), or
//! the closed-form NIST SP 1065 Table 5 approximations with the noise type from the local ADEV
//! slope (the default, because the bounded-memory [`StreamingOadev`] can compute it too; other
//! kinds than OADEV then get a plain count of difference terms). The chi-squared bounds use
//! the exact quantiles (`statrs`).
//!
//! Files: `taus.rs` (tau sets), `kernels.rs` (phase integration, the blocked SIMD OADEV sums),
//! `passes.rs` (the fused passes of the other kinds),
//! `confidence.rs` (SP 1065 EDF and the bounds), `greenhall.rs` (Greenhall's EDF),
//! `noise_id.rs` (lag-1 autocorrelation and B1 noise identification), `streaming.rs`
//! (bounded-memory OADEV).

mod confidence;
mod greenhall;
mod kernels;
mod noise_id;
mod passes;
mod streaming;
mod taus;
mod theo;
mod theo_lags;

use serde::Serialize;
use thiserror::Error;

pub use confidence::{confidence_interval, edf_oadev};
pub use greenhall::{Estimator, edf_greenhall, edf_totdev};
pub use kernels::phase_from_rate;
use kernels::{LongArray, PARALLEL_MIN_PHASE_POINTS, integrate_into, oadev_sums, sum_by};
pub use noise_id::{autocorrelation_alpha, b1_alpha};
pub use streaming::StreamingOadev;
pub use taus::TauSet;
pub use theo::{THEO1_MIN_M, edf_theo1, theo_br_ratio, theo1_m_for, theo1_variance};

/// Errors of the Allan-deviation computations.
#[derive(Debug, Error, PartialEq)]
pub enum AllanError {
    /// Fewer samples than the smallest averaging factor needs.
    #[error("too few samples: {n_samples} rate samples, need at least {needed}")]
    TooShort {
        /// Rate samples given.
        n_samples: usize,
        /// Rate samples needed.
        needed: usize,
    },
    /// The sample period is not a positive finite number.
    #[error("invalid sample period {tau0_s} s: must be positive and finite")]
    BadPeriod {
        /// The offending period, seconds.
        tau0_s: f64,
    },
}

/// Which deviation to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// Non-overlapping Allan deviation.
    Adev,
    /// Overlapping Allan deviation (the usual choice for IMU noise).
    Oadev,
    /// Modified Allan deviation.
    Mdev,
    /// Non-overlapping Hadamard deviation.
    Hdev,
    /// Overlapping Hadamard deviation.
    Ohdev,
    /// Time deviation, tau * MDEV / sqrt(3) (unit of y times seconds).
    Tdev,
    /// Total deviation (reflected-phase extension, NIST SP 1065 eq. 25).
    Totdev,
    /// Theo1 deviation (SP 1065 eq. 30) at tau = 0.75 m tau0, m even, 10 <= m <= N - 1:
    /// Allan-compatible up to 75 % of the record (`theo.rs`).
    Theo1,
    /// TheoH: OADEV up to 10 % of the record, bias-removed Theo1 (TheoBR) beyond, to 75 %.
    Theoh,
}

impl Kind {
    /// Every kind, in the order of the NIST reference tables.
    pub const ALL: [Kind; 7] = [
        Kind::Adev,
        Kind::Oadev,
        Kind::Mdev,
        Kind::Totdev,
        Kind::Hdev,
        Kind::Ohdev,
        Kind::Tdev,
    ];

    /// The Theo kinds (not in [`Kind::ALL`], whose order follows the NIST reference tables).
    pub const THEO: [Kind; 2] = [Kind::Theo1, Kind::Theoh];

    /// Whether this is Theo1 or TheoH, whose points' `m` is a Theo1 averaging factor at
    /// tau = 0.75 m tau0 (TheoH's OADEV points excepted).
    pub fn is_theo(self) -> bool {
        matches!(self, Kind::Theo1 | Kind::Theoh)
    }

    /// Largest averaging factor m for `n_phase` phase points.
    pub fn max_m(self, n_phase: usize) -> usize {
        let n = n_phase.saturating_sub(1);
        match self {
            Kind::Adev | Kind::Oadev | Kind::Totdev => n / 2,
            Kind::Mdev | Kind::Tdev | Kind::Hdev | Kind::Ohdev => n / 3,
            Kind::Theo1 | Kind::Theoh => n,
        }
    }

    /// The estimator's shape for Greenhall's EDF (`None` for TOTDEV and the Theo kinds, which
    /// have their own).
    pub fn estimator(self) -> Option<Estimator> {
        let (d, overlapping, modified) = match self {
            Kind::Adev => (2, false, false),
            Kind::Oadev => (2, true, false),
            Kind::Mdev | Kind::Tdev => (2, true, true),
            Kind::Hdev => (3, false, false),
            Kind::Ohdev => (3, true, false),
            Kind::Totdev | Kind::Theo1 | Kind::Theoh => return None,
        };
        Some(Estimator {
            d,
            overlapping,
            modified,
        })
    }

    /// Lower-case name (`oadev`), as on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Adev => "adev",
            Kind::Oadev => "oadev",
            Kind::Mdev => "mdev",
            Kind::Hdev => "hdev",
            Kind::Ohdev => "ohdev",
            Kind::Tdev => "tdev",
            Kind::Totdev => "totdev",
            Kind::Theo1 => "theo1",
            Kind::Theoh => "theoh",
        }
    }
}

impl std::str::FromStr for Kind {
    type Err = String;

    /// Parses the lower-case name (`adev`, `oadev`, ..., `totdev`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Kind::ALL
            .into_iter()
            .chain(Kind::THEO)
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown deviation {s:?}: use adev, oadev, mdev, hdev, ohdev, tdev, totdev, \
                     theo1 or theoh"
                )
            })
    }
}

/// Power-law noise type (of the rate data y), used to pick an EDF formula.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseType {
    /// White phase modulation (ADEV slope -1; in an IMU: quantization).
    WhitePm,
    /// Flicker phase modulation (ADEV slope -1, log-corrected).
    FlickerPm,
    /// White frequency modulation (slope -1/2; IMU angle/velocity random walk N).
    WhiteFm,
    /// Flicker frequency modulation (slope 0; IMU bias instability B).
    FlickerFm,
    /// Random-walk frequency modulation (slope +1/2; IMU rate random walk K).
    RandomWalkFm,
    /// Flicker-walk frequency modulation (ADEV slope +1; only the Hadamard variances converge).
    FlickerWalkFm,
    /// Random-run frequency modulation (ADEV slope +3/2; only the Hadamard variances converge).
    RandomRunFm,
}

impl NoiseType {
    /// The noise type whose ADEV log-log slope is nearest to `slope`.
    pub fn from_adev_slope(slope: f64) -> Self {
        if !slope.is_finite() || slope < -0.75 {
            NoiseType::WhitePm
        } else if slope < -0.25 {
            NoiseType::WhiteFm
        } else if slope < 0.25 {
            NoiseType::FlickerFm
        } else {
            NoiseType::RandomWalkFm
        }
    }

    /// The exponent alpha of the fractional-frequency spectrum S_y(f) ~ f^alpha.
    pub fn alpha(self) -> i32 {
        match self {
            NoiseType::WhitePm => 2,
            NoiseType::FlickerPm => 1,
            NoiseType::WhiteFm => 0,
            NoiseType::FlickerFm => -1,
            NoiseType::RandomWalkFm => -2,
            NoiseType::FlickerWalkFm => -3,
            NoiseType::RandomRunFm => -4,
        }
    }

    /// The noise type of exponent `alpha` (clamped into -4..=2).
    pub fn from_alpha(alpha: i32) -> Self {
        match alpha.clamp(-4, 2) {
            2 => NoiseType::WhitePm,
            1 => NoiseType::FlickerPm,
            0 => NoiseType::WhiteFm,
            -1 => NoiseType::FlickerFm,
            -2 => NoiseType::RandomWalkFm,
            -3 => NoiseType::FlickerWalkFm,
            _ => NoiseType::RandomRunFm,
        }
    }
}

/// How the equivalent degrees of freedom (and so the confidence intervals) are computed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum EdfMethod {
    /// NIST SP 1065 Table 5 closed forms for OADEV and TOTDEV (noise type from the local
    /// slope), the count of non-overlapping terms for the others; what [`StreamingOadev`]
    /// computes in bounded memory.
    #[default]
    Sp1065,
    /// Greenhall's EDF algorithm with Stable32's noise identification per tau, as
    /// Stable32 and allantools; the total deviation by SP 1065 Table 7.
    Greenhall,
}

/// One deviation value with its statistics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DevPoint {
    /// Averaging factor (tau = m tau0; for Theo1 and TheoH's TheoBR points the Theo1 factor,
    /// tau = 0.75 m tau0).
    pub m: usize,
    /// Averaging time, seconds.
    pub tau_s: f64,
    /// The deviation, in the unit of y (TDEV: unit of y times seconds).
    pub dev: f64,
    /// Number of difference terms averaged.
    pub n_terms: usize,
    /// Equivalent degrees of freedom of the variance estimate.
    pub edf: f64,
    /// Lower bound of the confidence interval on `dev`.
    pub dev_lo: f64,
    /// Upper bound of the confidence interval on `dev`.
    pub dev_hi: f64,
}

/// A deviation curve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DevCurve {
    /// Which deviation.
    pub kind: Kind,
    /// Sample period of the rate data, seconds.
    pub tau0_s: f64,
    /// Confidence level of `dev_lo`..`dev_hi` (e.g. 0.683).
    pub confidence: f64,
    /// Points in increasing tau.
    pub points: Vec<DevPoint>,
}

/// Options of [`deviation`].
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Averaging factors.
    pub taus: TauSet,
    /// How the EDF of each point is computed.
    pub edf: EdfMethod,
    /// Two-sided confidence level of the intervals (default 0.683, "1 sigma").
    pub confidence: f64,
    /// Noise type for the EDF; `None` identifies it per tau (by the method of `edf`).
    pub noise: Option<NoiseType>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            taus: TauSet::Octave,
            edf: EdfMethod::Sp1065,
            confidence: 0.683,
            noise: None,
        }
    }
}

fn check(n_y: usize, tau0_s: f64) -> Result<(), AllanError> {
    if !(tau0_s.is_finite() && tau0_s > 0.0) {
        return Err(AllanError::BadPeriod { tau0_s });
    }
    if n_y < 2 {
        return Err(AllanError::TooShort {
            n_samples: n_y,
            needed: 2,
        });
    }
    Ok(())
}

/// Variance and number of terms of one deviation at one m, from phase `x`. Returns `None` if m
/// is out of range.
fn variance_at(kind: Kind, x: &[f64], m: usize, tau0_s: f64) -> Option<(f64, usize)> {
    if m == 0 || m > kind.max_m(x.len()) || kind.is_theo() {
        return None;
    }
    let sum = kind_sums(kind, x, &[m])[0];
    Some(variance_from_sum(kind, x, m, sum, tau0_s))
}

/// The squared-difference sums of `kind` at every m of increasing `ms` (each within
/// `kind.max_m`), all taus in one fused pass (`kernels.rs`, `passes.rs`). TOTDEV's is its
/// interior, the OADEV sum (`variance_from_sum` adds the edges); not for the Theo kinds.
fn kind_sums(kind: Kind, x: &[f64], ms: &[usize]) -> Vec<f64> {
    match kind {
        Kind::Oadev | Kind::Totdev => oadev_sums(x, ms),
        Kind::Adev => passes::non_overlapping_sums::<2>(x, ms),
        Kind::Hdev => passes::non_overlapping_sums::<3>(x, ms),
        Kind::Ohdev => passes::overlapping_third_sums(x, ms),
        Kind::Mdev | Kind::Tdev => passes::modified_sums(x, ms),
        Kind::Theo1 | Kind::Theoh => vec![f64::NAN; ms.len()],
    }
}

/// Variance and number of terms of `kind` at `m` from its sum (`kind_sums`).
fn variance_from_sum(kind: Kind, x: &[f64], m: usize, sum: f64, tau0_s: f64) -> (f64, usize) {
    let n = x.len();
    let tau = m as f64 * tau0_s;
    match kind {
        Kind::Oadev | Kind::Adev => {
            let stride = if kind == Kind::Adev { m } else { 1 };
            let terms = (n - 1 - 2 * m) / stride + 1;
            (sum / (2.0 * terms as f64 * tau * tau), terms)
        }
        Kind::Hdev | Kind::Ohdev => {
            let stride = if kind == Kind::Hdev { m } else { 1 };
            let terms = (n - 1 - 3 * m) / stride + 1;
            (sum / (6.0 * terms as f64 * tau * tau), terms)
        }
        Kind::Mdev | Kind::Tdev => {
            let terms = n - 3 * m + 1;
            let mvar = sum / (2.0 * (m * m) as f64 * tau * tau * terms as f64);
            if kind == Kind::Tdev {
                (mvar * tau * tau / 3.0, terms)
            } else {
                (mvar, terms)
            }
        }
        Kind::Totdev => {
            let total = sum + totdev_edge_sum_sq(x, m);
            (total / (2.0 * (n - 2) as f64 * tau * tau), n - 2)
        }
        Kind::Theo1 | Kind::Theoh => (f64::NAN, 0),
    }
}

/// The total variance's sum over i in 1..=n-2 of (x*(i-m) - 2 x(i) + x*(i+m))^2 on the phase
/// reflected about both end points (x*(-j) = 2x(0) - x(j), x*(n-1+j) = 2x(n-1) - x(n-1-j)),
/// less its interior: for i in m..=n-1-m every point is a real one and the terms are exactly
/// the overlapping Allan variance's sum, which the caller takes from the OADEV kernel. What is
/// left are the 2(m-1) terms whose window reaches past an end (m <= (n-1)/2, so none reaches
/// past both).
fn totdev_edge_sum_sq(x: &[f64], m: usize) -> f64 {
    let n = x.len();
    let (first, last) = (x[0], x[n - 1]);
    let low = sum_by(1..m, |i| {
        let d = (2.0 * first - x[m - i]) - 2.0 * x[i] + x[i + m];
        d * d
    });
    let high = sum_by(n - m..n - 1, |i| {
        let d = x[i - m] - 2.0 * x[i] + (2.0 * last - x[2 * (n - 1) - i - m]);
        d * d
    });
    low + high
}

/// Computes one deviation of rate data `y` (sample period `tau0_s`) at the tau set in `options`.
pub fn deviation(
    kind: Kind,
    y: &[f64],
    tau0_s: f64,
    options: &Options,
) -> Result<DevCurve, AllanError> {
    deviation_with_noise(kind, y, tau0_s, options).map(|(curve, _)| curve)
}

/// As [`deviation`], also returning the noise type each point's EDF assumed.
pub fn deviation_with_noise(
    kind: Kind,
    y: &[f64],
    tau0_s: f64,
    options: &Options,
) -> Result<(DevCurve, Vec<NoiseType>), AllanError> {
    check(y.len(), tau0_s)?;
    let mut x = LongArray::zeros(y.len() + 1);
    integrate_into(y, tau0_s, &mut x);
    deviation_from_phase_with_noise(kind, &x, tau0_s, options)
}

/// As [`deviation`], from phase data `x` (integrated rate, unit of y times seconds).
pub fn deviation_from_phase(
    kind: Kind,
    x: &[f64],
    tau0_s: f64,
    options: &Options,
) -> Result<DevCurve, AllanError> {
    deviation_from_phase_with_noise(kind, x, tau0_s, options).map(|(curve, _)| curve)
}

/// As [`deviation_from_phase`], also returning the noise type each point's EDF assumed.
pub fn deviation_from_phase_with_noise(
    kind: Kind,
    x: &[f64],
    tau0_s: f64,
    options: &Options,
) -> Result<(DevCurve, Vec<NoiseType>), AllanError> {
    check(x.len().saturating_sub(1), tau0_s)?;
    let mut points = if kind.is_theo() {
        theo_points(kind, x, tau0_s, &options.taus)?
    } else {
        let factors = averaging_factors(kind, x.len(), &options.taus)?;
        deviation_points(kind, x, tau0_s, &factors)
    };
    let noise = assign_intervals(kind, x, tau0_s, &mut points, options);
    let curve = DevCurve {
        kind,
        tau0_s,
        confidence: options.confidence,
        points,
    };
    Ok((curve, noise))
}

/// The tau set's factors for this kind and length; an error if there are none.
fn averaging_factors(kind: Kind, n_phase: usize, taus: &TauSet) -> Result<Vec<usize>, AllanError> {
    let factors = taus.factors(kind.max_m(n_phase));
    if factors.is_empty() {
        return Err(AllanError::TooShort {
            n_samples: n_phase - 1,
            needed: if matches!(kind, Kind::Adev | Kind::Oadev | Kind::Totdev) {
                2
            } else {
                3
            },
        });
    }
    Ok(factors)
}

/// The Theo1 factors for a tau set read as averaging times f tau0: each f mapped to the even
/// m nearest 4f/3 (`theo1_m_for`), kept if 10 <= m <= N - 1 and f >= `from`.
fn theo1_factors(n_phase: usize, taus: &TauSet, from: usize) -> Vec<usize> {
    let max_f = (0.75 * (n_phase.saturating_sub(1)) as f64) as usize;
    let mut ms: Vec<usize> = taus
        .factors(max_f)
        .into_iter()
        .filter(|&f| f >= from)
        .map(theo1_m_for)
        .filter(|&m| m >= THEO1_MIN_M && m < n_phase)
        .collect();
    ms.dedup();
    ms
}

/// The factor k tau0 up to which TheoH is OADEV: the largest factor of the tau set at most
/// 10 % of the record ((N - 1) tau0), SP 1065 section 5.2.15. `None` if there is none.
fn theoh_split(n_phase: usize, taus: &TauSet) -> Option<usize> {
    taus.factors(n_phase.saturating_sub(1) / 10).last().copied()
}

/// Theo1's or TheoH's points, intervals not yet set. The tau set is read as averaging times:
/// Theo1 at the even m with 0.75 m nearest each factor; TheoH as OADEV at the factors below
/// k (`theoh_split`) and TheoBR from k to 75 % of the record.
fn theo_points(
    kind: Kind,
    x: &[f64],
    tau0_s: f64,
    taus: &TauSet,
) -> Result<Vec<DevPoint>, AllanError> {
    let n = x.len();
    let too_short = AllanError::TooShort {
        n_samples: n - 1,
        needed: THEO1_MIN_M,
    };
    let theo_point = |m: usize, scale: f64| {
        let var = theo::theo1_variance(x, m, tau0_s).map_or(0.0, |v| v * scale);
        DevPoint {
            m,
            tau_s: 0.75 * m as f64 * tau0_s,
            dev: var.max(0.0).sqrt(),
            n_terms: n - m,
            edf: 0.0,
            dev_lo: 0.0,
            dev_hi: 0.0,
        }
    };
    let points: Vec<DevPoint> = match kind {
        Kind::Theoh => {
            let split = theoh_split(n, taus);
            let below: Vec<usize> = split.map_or(Vec::new(), |k| {
                taus.factors(k).into_iter().filter(|&m| m < k).collect()
            });
            let mut pts = if below.is_empty() {
                Vec::new()
            } else {
                deviation_points(Kind::Oadev, x, tau0_s, &below)
            };
            let ratio = theo::theo_br_ratio(x, |ms| {
                oadev_sums(x, ms)
                    .into_iter()
                    .zip(ms)
                    .map(|(sum, &m)| variance_from_sum(Kind::Oadev, x, m, sum, 1.0).0)
                    .collect()
            })
            .ok_or(AllanError::TooShort {
                n_samples: n - 1,
                needed: 89,
            })?;
            let theo_ms = theo1_factors(n, taus, split.unwrap_or(1));
            pts.extend(theo_ms.into_iter().map(|m| theo_point(m, ratio)));
            pts
        }
        _ => theo1_factors(n, taus, 1)
            .into_iter()
            .map(|m| theo_point(m, 1.0))
            .collect(),
    };
    if points.is_empty() {
        return Err(too_short);
    }
    Ok(points)
}

/// Whether point `p` of a `kind` curve is a Theo1/TheoBR one (its tau is 0.75 m tau0, which is
/// never m tau0, so TheoH's OADEV points are told apart exactly).
fn is_theo_point(kind: Kind, p: &DevPoint, tau0_s: f64) -> bool {
    kind.is_theo() && p.tau_s != p.m as f64 * tau0_s
}

/// The deviation at every factor, intervals not yet set: every tau's sum in one fused pass.
fn deviation_points(kind: Kind, x: &[f64], tau0_s: f64, factors: &[usize]) -> Vec<DevPoint> {
    let ms: Vec<usize> = factors
        .iter()
        .copied()
        .filter(|&m| m >= 1 && m <= kind.max_m(x.len()))
        .collect();
    let sums = kind_sums(kind, x, &ms);
    ms.iter()
        .zip(sums)
        .map(|(&m, sum)| {
            let (var, n_terms) = variance_from_sum(kind, x, m, sum, tau0_s);
            DevPoint {
                m,
                tau_s: m as f64 * tau0_s,
                dev: var.max(0.0).sqrt(),
                n_terms,
                edf: 0.0,
                dev_lo: 0.0,
                dev_hi: 0.0,
            }
        })
        .collect()
}

/// Sets each point's EDF and confidence bounds by `options.edf`; returns the noise types used.
fn assign_intervals(
    kind: Kind,
    x: &[f64],
    tau0_s: f64,
    points: &mut [DevPoint],
    options: &Options,
) -> Vec<NoiseType> {
    let n = x.len();
    let noise: Vec<NoiseType> = match (options.noise, options.edf) {
        (Some(t), _) => vec![t; points.len()],
        (None, EdfMethod::Sp1065) => slope_noise_types(kind, points),
        (None, EdfMethod::Greenhall) if kind.is_theo() => {
            // Identified at each point's own averaging time, as for OADEV.
            let proxies: Vec<DevPoint> = points
                .iter()
                .map(|p| DevPoint {
                    m: (p.tau_s / tau0_s).round().max(1.0) as usize,
                    ..*p
                })
                .collect();
            identified_noise_types(Kind::Oadev, x, &proxies)
        }
        (None, EdfMethod::Greenhall) => identified_noise_types(kind, x, points),
    };
    for (p, &t) in points.iter_mut().zip(&noise) {
        let theo_point = is_theo_point(kind, p, tau0_s);
        // TheoH's short taus are OADEV points.
        let as_kind = if kind.is_theo() && !theo_point {
            Kind::Oadev
        } else {
            kind
        };
        p.edf = match options.edf {
            _ if theo_point => edf_theo1(t.alpha(), p.m, n),
            EdfMethod::Sp1065 => sp1065_edf(as_kind, n, p, t),
            EdfMethod::Greenhall => match as_kind.estimator() {
                Some(est) => edf_greenhall(t.alpha(), est, p.m, n),
                None => edf_totdev(t.alpha(), p.m, n),
            },
        };
        let (lo, hi) = confidence_interval(p.dev, p.edf, options.confidence);
        p.dev_lo = lo;
        p.dev_hi = hi;
    }
    noise
}

/// Noise type per tau from the local log-log slope of this curve (TDEV shifted by -1 to the
/// ADEV slope).
fn slope_noise_types(kind: Kind, points: &[DevPoint]) -> Vec<NoiseType> {
    (0..points.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(points.len() - 1));
            let slope = if a == b {
                -0.5
            } else {
                (points[b].dev / points[a].dev).ln() / (points[b].tau_s / points[a].tau_s).ln()
            };
            let s = if kind == Kind::Tdev {
                slope - 1.0
            } else {
                slope
            };
            NoiseType::from_adev_slope(s)
        })
        .collect()
}

/// Noise type per tau as Stable32 identifies it for the EDF (`noise_id.rs`):
/// - at least 30 points of the phase decimated by m: the lag-1 autocorrelation of the m-averaged
///   frequency;
/// - fewer, for the non-overlapping ADEV and HDEV (whose own analysis points are then fewer than
///   30 too): the B1 ratio with R(n), down to `noise_id::B1_MIN_POINTS` averages;
/// - otherwise (the overlapping kinds and TOTDEV, whose analysis points stay many, and the last
///   few taus of every kind): the type of the nearest identified tau, which at the long end is the
///   previous one. A series too short to identify anywhere is taken as white FM.
///
/// Checked against the two long Stable32 tables distributed with allantools (a Cs 5071A, 556,990
/// phase points at decade taus to m = 100,000, and a GPS receiver, 241,218 points at octave taus
/// to m = 32,768; `tests/allan_stable32_long.rs`): the identified type equals Stable32's at every
/// tau of every kind but the GPS TOTDEV's last two (see that test).
fn identified_noise_types(kind: Kind, x: &[f64], points: &[DevPoint]) -> Vec<NoiseType> {
    let d_max = kind.estimator().map_or(2, |e| e.d);
    let non_overlapping = matches!(kind, Kind::Adev | Kind::Hdev);
    let identify = |m: usize| {
        noise_id::autocorrelation_alpha(x, m, d_max).or_else(|| {
            if !non_overlapping {
                return None;
            }
            noise_id::b1_alpha(x, m, d_max, || {
                let mvar = variance_at(Kind::Mdev, x, m, 1.0).map_or(0.0, |v| v.0);
                let avar = variance_at(Kind::Adev, x, m, 1.0).map_or(0.0, |v| v.0);
                if avar > 0.0 { mvar / avar } else { 0.0 }
            })
        })
    };
    let ms: Vec<usize> = points.iter().map(|p| p.m).collect();
    // Each identification is a strided pass over the phase: long records split the taus over
    // two threads, as the deviations do.
    let ids: Vec<Option<i32>> = if x.len() >= PARALLEL_MIN_PHASE_POINTS && ms.len() > 1 {
        std::thread::scope(|scope| {
            let other = scope.spawn(|| {
                ms.iter()
                    .skip(1)
                    .step_by(2)
                    .map(|&m| identify(m))
                    .collect::<Vec<_>>()
            });
            let mine: Vec<_> = ms.iter().step_by(2).map(|&m| identify(m)).collect();
            let theirs = other.join().expect("noise identification worker panicked");
            let mut all = Vec::with_capacity(ms.len());
            for i in 0..ms.len() {
                all.push(if i % 2 == 0 {
                    mine[i / 2]
                } else {
                    theirs[i / 2]
                });
            }
            all
        })
    } else {
        ms.iter().map(|&m| identify(m)).collect()
    };
    let lowest = kind.estimator().map_or(-2, |e| greenhall::min_alpha(e.d));
    (0..ids.len())
        .map(|i| {
            let nearest = (0..ids.len())
                .filter_map(|j| ids[j].map(|a| (i.abs_diff(j), j > i, a)))
                .min_by_key(|&(dist, later, _)| (dist, later))
                .map_or(0, |(_, _, a)| a);
            NoiseType::from_alpha(nearest.clamp(lowest, 2))
        })
        .collect()
}

/// The SP 1065 EDF of one point (see [`EdfMethod::Sp1065`]).
fn sp1065_edf(kind: Kind, n: usize, p: &DevPoint, noise: NoiseType) -> f64 {
    match kind {
        Kind::Oadev | Kind::Totdev => edf_oadev(n, p.m, noise),
        // Conservative: one degree of freedom per non-overlapping difference.
        Kind::Adev | Kind::Hdev => p.n_terms as f64,
        Kind::Ohdev | Kind::Mdev | Kind::Tdev => ((n - 1) / p.m).saturating_sub(2).max(1) as f64,
        Kind::Theo1 | Kind::Theoh => edf_theo1(noise.alpha(), p.m, n),
    }
}

#[cfg(test)]
mod tests;
