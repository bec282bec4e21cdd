//! `imud.health_check`: what `imu-analyze health --json` computes (the daemon's live
//! calibration health checks run offline over a recording, and the offset of the stream from
//! physics over all its still windows), by the library's `health::check_series` as the CLI,
//! as the same JSON document.

use anyhow::Result;
use imu_analysis::health::{CheckOptions, check_series};
use pyo3::prelude::*;

use crate::calibration::Calibration;
use crate::error::IntoPy;
use crate::series::Series;

/// The health check of `series` (the stream `calibration` corrected) as JSON (the GIL released
/// while it runs).
#[pyfunction]
#[pyo3(signature = (series, calibration, latitude_deg, height_m, gravity_m_s2, false_alarm_p))]
pub fn health_check_json(
    py: Python<'_>,
    series: &Series,
    calibration: Option<PyRef<'_, Calibration>>,
    latitude_deg: Option<f64>,
    height_m: f64,
    gravity_m_s2: Option<f64>,
    false_alarm_p: f64,
) -> PyResult<String> {
    let inner = series.inner.clone();
    let calibration = calibration.map(|c| c.inner.clone());
    py.detach(move || -> Result<String> {
        let options = CheckOptions::at(latitude_deg, height_m, gravity_m_s2, false_alarm_p);
        options.validate().map_err(anyhow::Error::msg)?;
        let check = check_series(&inner, calibration.as_ref(), &options);
        Ok(serde_json::to_string(&check)?)
    })
    .py_err()
}

/// WGS-84 normal gravity at `latitude_deg` and `height_m` above the ellipsoid, m/s^2: the one
/// formula (`imu_model::earth`) the health check, the calibration fits and the simulator use.
#[pyfunction]
#[pyo3(signature = (latitude_deg, height_m = 0.0))]
pub fn normal_gravity_m_s2(latitude_deg: f64, height_m: f64) -> f64 {
    imu_model::earth::normal_gravity_m_s2(latitude_deg, height_m)
}
