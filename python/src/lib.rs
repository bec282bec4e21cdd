//! `imud._imud`, the compiled half of the Python package `imud`: a thin binding over the
//! libraries. Each analysis calls the same library functions as its command-line client and
//! hands back the library's result structs as the JSON their serde serialization writes (the
//! same documents `--json` prints); `python/imud/*.py` turns those into dataclasses. Arrays
//! cross as numpy arrays, errors as `imud.ImudError` with the CLI's message, and the GIL is
//! released while the libraries work.
//!
//! Modules: `error` (the exception and the message chain), `series` (recordings: read through
//! imu-analysis's input module over imu-rec, and numpy views), `noise`, `health` (the
//! calibration health check, as `imu-analyze health`), `calibrate`,
//! `workbench` (diagnose and the ladder), `calibration` (the calibration file and its
//! vectorised correction).

mod calibrate;
mod calibration;
mod error;
mod health;
mod noise;
mod series;
mod workbench;

use pyo3::prelude::*;

/// The shipped example error model of a 3DM-GX1-class unit, as TOML text
/// (`imu_model::EXAMPLE_GX1_MODEL_TOML`): `imud --sim`'s truth, and the default units of
/// `imud.fleet.simulate`, so neither needs the source tree.
#[pyfunction]
fn example_model_toml() -> &'static str {
    imu_model::EXAMPLE_GX1_MODEL_TOML
}

/// The compiled module: registered under `imud._imud`.
#[pymodule]
fn _imud(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ImudError", m.py().get_type::<error::ImudError>())?;
    m.add_class::<series::Series>()?;
    m.add_class::<calibration::Calibration>()?;
    m.add_function(wrap_pyfunction!(series::read_series, m)?)?;
    m.add_function(wrap_pyfunction!(noise::noise_json, m)?)?;
    m.add_function(wrap_pyfunction!(health::health_check_json, m)?)?;
    m.add_function(wrap_pyfunction!(health::normal_gravity_m_s2, m)?)?;
    m.add_function(wrap_pyfunction!(example_model_toml, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate::calibrate_json, m)?)?;
    m.add_function(wrap_pyfunction!(workbench::diagnose_json, m)?)?;
    m.add_function(wrap_pyfunction!(workbench::ladder_json, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
