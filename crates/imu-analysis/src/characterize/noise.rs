//! The noise analysis of a static recording, per sensor and axis: the OADEV the IEEE Std
//! 952/1293 noise terms are fitted to, the terms, the slope read-offs, and every Allan-family
//! deviation asked for with the noise type its bounds assumed. One home for what `imu-noise`
//! and Python's `imud.noise` compute; the report serializes as `imu-noise --json`'s axis.

use imu_model::Triad;
use imu_stats::allan::{self, DevPoint, EdfMethod, Kind, NoiseType, Options, TauSet};
use imu_stats::noise_terms::{
    FitOptions, NoiseTerms, SlopeReadoffs, fit_terms_extended, slope_readoffs,
};
use serde::Serialize;

use crate::ImuSeries;
use crate::render::allan::DisplayTerms;

/// Failures of [`analyse`]; with `{:#}` they read as `imu-noise` always has (e.g.
/// `Allan deviation of gyro z: TDEV: ...`).
#[derive(Debug, thiserror::Error)]
pub enum NoiseError {
    /// No sample rate (too few samples, or no time span).
    #[error("cannot determine the sample rate of {origin} ({samples} samples)")]
    NoSampleRate {
        /// The recording.
        origin: String,
        /// Its samples.
        samples: usize,
    },
    /// A confidence level outside (0, 1).
    #[error("confidence {0} must lie strictly between 0 and 1")]
    Confidence(f64),
    /// A tau shorter than a sample period.
    #[error("tau {tau_s} s is shorter than the sample period {period_s:.6} s")]
    TauTooShort {
        /// The tau asked for, s.
        tau_s: f64,
        /// The sample period, s.
        period_s: f64,
    },
    /// A deviation failed: the OADEV the terms are fitted to (`kind` None) or a kind asked for.
    #[error(
        "Allan deviation of {sensor} {axis}{}",
        kind.map_or(String::new(), |k| format!(": {}", k.name().to_uppercase()))
    )]
    Deviation {
        /// The sensor.
        sensor: Triad,
        /// The axis.
        axis: &'static str,
        /// The kind asked for (None: the OADEV of the noise terms).
        kind: Option<Kind>,
        /// What failed.
        #[source]
        source: allan::AllanError,
    },
    /// The noise-term fit failed.
    #[error("noise terms of {sensor} {axis}")]
    Terms {
        /// The sensor.
        sensor: Triad,
        /// The axis.
        axis: &'static str,
        /// What failed.
        #[source]
        source: imu_stats::noise_terms::NoiseError,
    },
}

/// What `--taus` asked for.
#[derive(Debug, Clone, PartialEq)]
pub enum TauArg {
    /// A named set (`octave`, `decade`, `all`, `N-per-decade`).
    Set(TauSet),
    /// These taus, seconds (`1,2,4,10`).
    Seconds(Vec<f64>),
}

impl std::str::FromStr for TauArg {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if let Ok(set) = s.parse::<TauSet>() {
            return Ok(TauArg::Set(set));
        }
        if !s.starts_with(|c: char| c.is_ascii_digit() || c == '.') {
            return Err(format!(
                "bad tau set {s:?}: use octave, decade, all, N-per-decade or a list of taus in \
                 seconds such as 1,2,4,10"
            ));
        }
        let taus = s
            .split(',')
            .map(|t| match t.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
                _ => Err(format!(
                    "bad tau {t:?} in {s:?}: each tau is a positive number of seconds"
                )),
            })
            .collect::<Result<Vec<f64>, String>>()?;
        Ok(TauArg::Seconds(taus))
    }
}

impl TauArg {
    /// The library tau set at sample rate `rate_hz`: explicit taus become the nearest averaging
    /// factor (tau = m / rate); a tau shorter than half a sample period is an error.
    pub fn resolve(&self, rate_hz: f64) -> Result<TauSet, NoiseError> {
        match self {
            TauArg::Set(set) => Ok(set.clone()),
            TauArg::Seconds(taus) => {
                let ms = taus
                    .iter()
                    .map(|&tau_s| {
                        let m = (tau_s * rate_hz).round();
                        if m < 1.0 {
                            return Err(NoiseError::TauTooShort {
                                tau_s,
                                period_s: 1.0 / rate_hz,
                            });
                        }
                        Ok(m as usize)
                    })
                    .collect::<Result<Vec<usize>, NoiseError>>()?;
                Ok(TauSet::Factors(ms))
            }
        }
    }
}

/// One deviation kind of one axis.
#[derive(Debug, Serialize)]
pub struct KindReport {
    /// The deviation.
    pub kind: Kind,
    /// Unit of `dev`, `dev_lo`, `dev_hi` (TDEV: the rate unit times seconds).
    pub unit: String,
    /// How the equivalent degrees of freedom were found.
    pub edf_method: EdfMethod,
    /// Confidence level of the bounds.
    pub confidence: f64,
    /// The points, each with the noise type its bounds assumed.
    pub points: Vec<PointReport>,
}

/// One point of a deviation.
#[derive(Debug, Serialize)]
pub struct PointReport {
    /// The point.
    #[serde(flatten)]
    pub point: DevPoint,
    /// Power-law noise type the EDF assumed, and its exponent alpha (S_y ~ f^alpha).
    pub noise: NoiseType,
    /// Its exponent alpha.
    pub alpha: i32,
}

/// Result for one sensor axis.
#[derive(Debug, Serialize)]
pub struct AxisReport {
    /// The sensor.
    pub sensor: Triad,
    /// `x`, `y` or `z`.
    pub axis: &'static str,
    /// Unit of the rate data (U) that the `*_u*` fields are expressed in.
    pub unit: &'static str,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// The noise terms fitted to `curve`.
    pub fit: NoiseTerms,
    /// The slope read-offs of `curve`.
    pub slope_readoffs: SlopeReadoffs,
    /// Discrete per-sample white-noise sigma, N sqrt(rate), U.
    pub white_per_sample_u: f64,
    /// Discrete per-sample random-walk step, K / sqrt(rate), U.
    pub random_walk_step_per_sample_u: f64,
    /// Display units: N, B, K in deg/sqrt(h), deg/h, deg/h/sqrt(h) (gyro) or
    /// micro-g/sqrt(Hz), micro-g, micro-g*sqrt(Hz) (accel).
    pub display: DisplayTerms,
    /// The OADEV curve the terms were fitted to.
    pub curve: allan::DevCurve,
    /// Every kind asked for.
    pub deviations: Vec<KindReport>,
    /// Present when the recording was read without its footer (a killed writer): how far the
    /// read got (set by the caller, which reads the recording).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input_unfinished: Option<serde_json::Value>,
    /// The files read (in time order), the IMU topic, the gaps between files.
    pub input: crate::input::InputInfo,
}

/// What to compute.
#[derive(Clone, Debug)]
pub struct NoiseRequest {
    /// The deviation kinds, each once, in order (see [`dedup_kinds`]).
    pub kinds: Vec<Kind>,
    /// The taus.
    pub taus: TauArg,
    /// How the equivalent degrees of freedom are found.
    pub edf: EdfMethod,
    /// Confidence level of the bounds, in (0, 1).
    pub confidence: f64,
}

/// The kinds in the order given, each once.
pub fn dedup_kinds(kinds: &[Kind]) -> Vec<Kind> {
    let mut out: Vec<Kind> = Vec::new();
    for &k in kinds {
        if !out.contains(&k) {
            out.push(k);
        }
    }
    out
}

/// The noise analysis of every sensor axis of `series` (accel x, y, z, then gyro);
/// `progress(sensor, axis, samples)` is called before each axis.
pub fn analyse(
    series: &ImuSeries,
    req: &NoiseRequest,
    mut progress: impl FnMut(Triad, &str, usize),
) -> Result<Vec<AxisReport>, NoiseError> {
    let rate_hz = series.sample_rate_hz();
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(NoiseError::NoSampleRate {
            origin: series.origin.clone(),
            samples: series.len(),
        });
    }
    if !(req.confidence > 0.0 && req.confidence < 1.0) {
        return Err(NoiseError::Confidence(req.confidence));
    }
    let opts = Options {
        taus: req.taus.resolve(rate_hz)?,
        edf: req.edf,
        confidence: req.confidence,
        noise: None,
    };
    // Explicit taus are too few for the terms: the fit gets 8 per decade.
    let fit_opts = Options {
        taus: match &req.taus {
            TauArg::Set(set) => set.clone(),
            TauArg::Seconds(_) => TauSet::PerDecade(8),
        },
        ..opts.clone()
    };
    let mut out = Vec::new();
    for (sensor, data) in [
        (Triad::Accel, &series.accel_m_s2),
        (Triad::Gyro, &series.gyro_rad_s),
    ] {
        let unit = sensor.unit();
        for (i, axis) in ["x", "y", "z"].into_iter().enumerate() {
            progress(sensor, axis, data.len());
            let y: Vec<f64> = data.iter().map(|v| v[i]).collect();
            let failed = |kind: Option<Kind>| {
                move |source| NoiseError::Deviation {
                    sensor,
                    axis,
                    kind,
                    source,
                }
            };
            let curve = allan::deviation(Kind::Oadev, &y, 1.0 / rate_hz, &fit_opts)
                .map_err(failed(None))?;
            let deviations = req
                .kinds
                .iter()
                .map(|&kind| {
                    kind_report(kind, unit, &y, rate_hz, &opts).map_err(failed(Some(kind)))
                })
                .collect::<Result<Vec<_>, _>>()?;
            // A Theo1 curve already computed at the fit's taus is reused (its long taus cost
            // the most: O(N m) each).
            let computed = deviations
                .iter()
                .find(|d| d.kind == Kind::Theo1 && fit_opts.taus == opts.taus);
            let theo1 = match computed {
                Some(d) => Some(allan::DevCurve {
                    kind: Kind::Theo1,
                    tau0_s: 1.0 / rate_hz,
                    confidence: d.confidence,
                    points: d.points.iter().map(|p| p.point).collect(),
                }),
                None if req.kinds.iter().any(|k| k.is_theo()) => {
                    fit_extension(&y, rate_hz, &curve, &fit_opts)
                        .map_err(failed(Some(Kind::Theo1)))?
                }
                None => None,
            };
            let fit = fit_terms_extended(&curve, theo1.as_ref(), &FitOptions::default()).map_err(
                |source| NoiseError::Terms {
                    sensor,
                    axis,
                    source,
                },
            )?;
            out.push(AxisReport {
                sensor,
                axis,
                unit,
                sample_rate_hz: rate_hz,
                slope_readoffs: slope_readoffs(&curve),
                white_per_sample_u: fit.white_per_sample_u(rate_hz),
                random_walk_step_per_sample_u: fit.random_walk_step_per_sample_u(rate_hz),
                display: DisplayTerms::of(sensor, &fit),
                fit,
                curve,
                deviations,
                input_unfinished: None,
                input: series.input.clone(),
            });
        }
    }
    Ok(out)
}

/// The Theo1 curve that extends the fit's OADEV `curve` (asked for with `--kind theoh`, or
/// `theo1` at other taus than the fit's): Theo1 at the fit's tau set read as averaging times,
/// up to 75 % of the record, the same curve `--kind theo1` computes at those taus (so the fit
/// does not depend on which Theo kind was asked for; the points' noise identification looks
/// at their neighbours). The fit takes its points beyond the OADEV's longest tau. `None` when
/// the set has no tau there.
fn fit_extension(
    y: &[f64],
    rate_hz: f64,
    curve: &allan::DevCurve,
    fit_opts: &Options,
) -> Result<Option<allan::DevCurve>, allan::AllanError> {
    let longest = curve.points.last().map_or(0, |p| p.m);
    let beyond = fit_opts
        .taus
        .factors(3 * y.len() / 4)
        .into_iter()
        .any(|f| f > longest);
    if !beyond || y.len() < allan::THEO1_MIN_M {
        return Ok(None);
    }
    match allan::deviation(Kind::Theo1, y, 1.0 / rate_hz, fit_opts) {
        Ok(c) => Ok(Some(c)),
        Err(allan::AllanError::TooShort { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}

/// One deviation kind of one axis, each point with its noise type and exponent.
fn kind_report(
    kind: Kind,
    unit: &str,
    y: &[f64],
    rate_hz: f64,
    opts: &Options,
) -> Result<KindReport, allan::AllanError> {
    let (curve, noise) = allan::deviation_with_noise(kind, y, 1.0 / rate_hz, opts)?;
    Ok(KindReport {
        kind,
        unit: if kind == Kind::Tdev {
            format!("{unit}*s")
        } else {
            unit.to_string()
        },
        edf_method: opts.edf,
        confidence: opts.confidence,
        points: curve
            .points
            .into_iter()
            .zip(noise)
            .map(|(point, noise)| PointReport {
                point,
                noise,
                alpha: noise.alpha(),
            })
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_sets_and_lists() {
        assert_eq!("decade".parse(), Ok(TauArg::Set(TauSet::Decade)));
        assert_eq!(
            "1,2,4,10".parse(),
            Ok(TauArg::Seconds(vec![1.0, 2.0, 4.0, 10.0]))
        );
        assert_eq!("0.5".parse(), Ok(TauArg::Seconds(vec![0.5])));
        assert!("1,x".parse::<TauArg>().is_err());
        assert!("1,-2".parse::<TauArg>().is_err());
        assert!("octav".parse::<TauArg>().is_err());
        let set = TauArg::Seconds(vec![1.0, 0.25]).resolve(100.0).unwrap();
        assert_eq!(set, TauSet::Factors(vec![100, 25]));
        assert!(TauArg::Seconds(vec![0.001]).resolve(100.0).is_err());
    }
}
