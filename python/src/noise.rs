//! `imud.noise`: what `imu-noise --json` computes for each sensor axis (the OADEV the noise
//! terms are fitted to, the terms, the slope read-offs, every deviation kind asked for with the
//! noise type its bounds assumed), by the same library calls, as the same JSON document.

use anyhow::{Context, Result};
use imu_analysis::ImuSeries;
use imu_analysis::render::allan::DisplayTerms;
use imu_model::Triad;
use imu_stats::allan::{self, EdfMethod, Kind, Options, TauSet};
use imu_stats::noise_terms::{FitOptions, fit_terms_with, slope_readoffs};
use pyo3::prelude::*;
use serde_json::{Value, json};

use crate::error::IntoPy;
use crate::series::Series;

/// `--taus`: a named set, or taus in seconds each rounded to a whole number of sample periods.
/// Returns (the set for the kinds, the set for the noise-term fit: 8-per-decade for a list).
fn resolve_taus(arg: &str, rate_hz: f64) -> Result<(TauSet, TauSet)> {
    if let Ok(set) = arg.parse::<TauSet>() {
        return Ok((set.clone(), set));
    }
    anyhow::ensure!(
        arg.starts_with(|c: char| c.is_ascii_digit() || c == '.'),
        "bad tau set {arg:?}: use octave, decade, all, N-per-decade or a list of taus in seconds \
         such as 1,2,4,10"
    );
    let ms = arg
        .split(',')
        .map(|t| {
            let tau_s = match t.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => v,
                _ => anyhow::bail!(
                    "bad tau {t:?} in {arg:?}: each tau is a positive number of seconds"
                ),
            };
            let m = (tau_s * rate_hz).round();
            anyhow::ensure!(
                m >= 1.0,
                "tau {tau_s} s is shorter than the sample period {:.6} s",
                1.0 / rate_hz
            );
            Ok(m as usize)
        })
        .collect::<Result<Vec<usize>>>()?;
    Ok((TauSet::Factors(ms), TauSet::PerDecade(8)))
}

/// The noise analysis of every sensor axis, as `imu-noise --json`'s array of axis reports
/// (without `input_unfinished`, which the Python layer takes from the recording).
pub fn analyse(
    series: &ImuSeries,
    kinds: &[Kind],
    taus: &str,
    edf: EdfMethod,
    confidence: f64,
) -> Result<Value> {
    let rate_hz = series.sample_rate_hz();
    anyhow::ensure!(
        rate_hz.is_finite() && rate_hz > 0.0,
        "cannot determine the sample rate of {} ({} samples)",
        series.origin,
        series.len()
    );
    anyhow::ensure!(
        confidence > 0.0 && confidence < 1.0,
        "confidence {confidence} must lie strictly between 0 and 1"
    );
    let (kind_taus, fit_taus) = resolve_taus(taus, rate_hz)?;
    let opts = Options {
        taus: kind_taus,
        edf,
        confidence,
        noise: None,
    };
    let fit_opts = Options {
        taus: fit_taus,
        ..opts.clone()
    };
    let mut kinds_once: Vec<Kind> = Vec::new();
    for &k in kinds {
        if !kinds_once.contains(&k) {
            kinds_once.push(k);
        }
    }
    let mut out = Vec::new();
    for (sensor, data) in [
        (Triad::Accel, &series.accel_m_s2),
        (Triad::Gyro, &series.gyro_rad_s),
    ] {
        let unit = sensor.unit();
        for (i, axis) in ["x", "y", "z"].into_iter().enumerate() {
            let y: Vec<f64> = data.iter().map(|v| v[i]).collect();
            let context = || format!("Allan deviation of {sensor} {axis}");
            let curve = allan::deviation(Kind::Oadev, &y, 1.0 / rate_hz, &fit_opts)
                .with_context(context)?;
            let deviations = kinds_once
                .iter()
                .map(|&kind| kind_report(kind, unit, &y, rate_hz, &opts))
                .collect::<Result<Vec<_>>>()
                .with_context(context)?;
            let fit = fit_terms_with(&curve, &FitOptions::default())
                .with_context(|| format!("noise terms of {sensor} {axis}"))?;
            out.push(json!({
                "sensor": sensor,
                "axis": axis,
                "unit": unit,
                "sample_rate_hz": rate_hz,
                "fit": fit,
                "slope_readoffs": slope_readoffs(&curve),
                "white_per_sample_u": fit.white_per_sample_u(rate_hz),
                "random_walk_step_per_sample_u": fit.random_walk_step_per_sample_u(rate_hz),
                "display": DisplayTerms::of(sensor, &fit),
                "curve": curve,
                "deviations": deviations,
                "input": series.input,
            }));
        }
    }
    Ok(Value::Array(out))
}

/// One deviation kind of one axis, each point with its noise type and exponent.
fn kind_report(kind: Kind, unit: &str, y: &[f64], rate_hz: f64, opts: &Options) -> Result<Value> {
    let (curve, noise) = allan::deviation_with_noise(kind, y, 1.0 / rate_hz, opts)
        .with_context(|| kind.name().to_uppercase())?;
    let points = curve
        .points
        .into_iter()
        .zip(noise)
        .map(|(point, noise)| -> Result<Value> {
            let mut p = serde_json::to_value(point)?;
            if let Value::Object(m) = &mut p {
                m.insert("noise".into(), serde_json::to_value(noise)?);
                m.insert("alpha".into(), noise.alpha().into());
            }
            Ok(p)
        })
        .collect::<Result<Vec<Value>>>()?;
    let unit = if kind == Kind::Tdev {
        format!("{unit}*s")
    } else {
        unit.to_string()
    };
    Ok(json!({
        "kind": kind,
        "unit": unit,
        "edf_method": opts.edf,
        "confidence": opts.confidence,
        "points": points,
    }))
}

/// `edf`: `greenhall` or `sp1065`.
fn parse_edf(s: &str) -> Result<EdfMethod> {
    match s {
        "greenhall" => Ok(EdfMethod::Greenhall),
        "sp1065" => Ok(EdfMethod::Sp1065),
        _ => anyhow::bail!("edf {s:?}: use \"greenhall\" or \"sp1065\""),
    }
}

/// The noise analysis of `series` as JSON (the GIL released while it runs).
#[pyfunction]
pub fn noise_json(
    py: Python<'_>,
    series: &Series,
    kinds: Vec<String>,
    taus: String,
    edf: String,
    confidence: f64,
) -> PyResult<String> {
    let inner = series.inner.clone();
    py.detach(move || -> Result<String> {
        let kinds = kinds
            .iter()
            .map(|k| k.parse::<Kind>().map_err(anyhow::Error::msg))
            .collect::<Result<Vec<_>>>()?;
        let v = analyse(&inner, &kinds, &taus, parse_edf(&edf)?, confidence)?;
        Ok(serde_json::to_string(&v)?)
    })
    .py_err()
}
