//! `imud.noise`: what `imu-noise --json` computes for each sensor axis (the OADEV the noise
//! terms are fitted to, the terms, the slope read-offs, every deviation kind asked for with the
//! noise type its bounds assumed), by the library's `characterize::noise::analyse` as the CLI,
//! as the same JSON document.

use anyhow::Result;
use imu_analysis::ImuSeries;
use imu_analysis::characterize::noise::{self, NoiseRequest, TauArg, dedup_kinds};
use imu_stats::allan::{EdfMethod, Kind};
use pyo3::prelude::*;
use serde_json::Value;

use crate::error::IntoPy;
use crate::series::Series;

/// The noise analysis of every sensor axis, as `imu-noise --json`'s array of axis reports
/// (without `input_unfinished`, which the Python layer takes from the recording): the library's
/// analysis, as the CLI calls it.
pub fn analyse(
    series: &ImuSeries,
    kinds: &[Kind],
    taus: &str,
    edf: EdfMethod,
    confidence: f64,
) -> Result<Value> {
    let request = NoiseRequest {
        kinds: dedup_kinds(kinds),
        taus: taus.parse::<TauArg>().map_err(anyhow::Error::msg)?,
        edf,
        confidence,
    };
    let reports = noise::analyse(series, &request, |_, _, _| {})?;
    Ok(serde_json::to_value(reports)?)
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
