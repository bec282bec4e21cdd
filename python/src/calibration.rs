//! `imud.Calibration`: imud's calibration file (TOML) through the model crate's own loader and
//! writer, its parameters, and the correction the daemon applies, vectorised over numpy arrays
//! that are read in place.

use std::path::PathBuf;

use anyhow::Context;
use imu_model::{Measured, Triad, Vec3};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::error::{IntoPy, to_py};
use crate::series::contiguous;

/// An imud calibration (the model crate's `Calibration`).
#[pyclass(module = "imud._imud")]
pub struct Calibration {
    /// The calibration itself.
    pub inner: imu_model::Calibration,
}

/// `"accel"`, `"gyro"` or `"mag"`.
fn triad(name: &str) -> PyResult<Triad> {
    name.parse::<Triad>()
        .map_err(|e| to_py(anyhow::anyhow!("triad {name:?}: {e}")))
}

/// A temperature (or time) per sample: one value for all, or an array of N.
#[derive(FromPyObject)]
pub enum PerSample<'py> {
    /// One value for every sample.
    Scalar(f64),
    /// One value per sample.
    Array(PyReadonlyArray1<'py, f64>),
}

#[pymethods]
impl Calibration {
    /// The identity calibration (no effects).
    #[new]
    fn new() -> Self {
        Calibration {
            inner: imu_model::Calibration::identity(),
        }
    }

    /// Loads and validates an imud calibration file (errors name the file, line and key).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py
            .detach(|| {
                imu_model::Calibration::load(&path)
                    .with_context(|| format!("loading {}", path.display()))
            })
            .py_err()?;
        Ok(Calibration { inner })
    }

    /// Parses calibration TOML text; `source` names it in error messages.
    #[staticmethod]
    #[pyo3(signature = (text, source = "<string>"))]
    fn from_toml(text: &str, source: &str) -> PyResult<Self> {
        let inner = imu_model::Calibration::from_toml_str(text, source)
            .map_err(anyhow::Error::from)
            .py_err()?;
        Ok(Calibration { inner })
    }

    /// Writes the calibration file (the format imud loads and hot-reloads).
    fn save(&self, path: PathBuf) -> PyResult<()> {
        self.inner
            .save(&path)
            .with_context(|| format!("writing {}", path.display()))
            .py_err()
    }

    /// The calibration file's text.
    fn to_toml(&self) -> String {
        self.inner.to_toml_string()
    }

    /// The calibration as JSON (its serde serialization, as in `imu-diagnose ladder --json`).
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.inner)
            .map_err(anyhow::Error::from)
            .py_err()
    }

    /// The content id imud reports for the calibration in force.
    fn content_id(&self) -> String {
        self.inner.content_id()
    }

    /// Names of a triad's parameters (`bias.x`, ...), in the order of [`Calibration::params`].
    fn param_names(&self, triad_name: &str) -> PyResult<Vec<String>> {
        let t = triad(triad_name)?;
        Ok(self.inner.triad(t).param_names(t))
    }

    /// Values of a triad's parameters.
    fn params(&self, triad_name: &str) -> PyResult<Vec<f64>> {
        Ok(self.inner.triad(triad(triad_name)?).params())
    }

    /// Corrects measurements as the daemon does: `accel_m_s2` and `gyro_rad_s` (N, 3),
    /// C-contiguous float64, read in place; `temperature_c` one value or (N,) (default 25 degC;
    /// NaN means unknown, taken as 25 degC like the daemon); `time_s` (N,) seconds since power-on,
    /// which drives the warm-up terms and the lever arm's angular acceleration (the finite
    /// difference of the last two corrected rates, as the daemon's); without it 0 and no
    /// angular acceleration. Returns (accel, gyro, converged), new arrays.
    #[pyo3(signature = (accel_m_s2, gyro_rad_s, temperature_c=None, time_s=None))]
    #[allow(clippy::type_complexity)]
    fn correct<'py>(
        &self,
        py: Python<'py>,
        accel_m_s2: PyReadonlyArray2<'py, f64>,
        gyro_rad_s: PyReadonlyArray2<'py, f64>,
        temperature_c: Option<PerSample<'py>>,
        time_s: Option<PyReadonlyArray1<'py, f64>>,
    ) -> PyResult<(
        Bound<'py, numpy::PyArray2<f64>>,
        Bound<'py, numpy::PyArray2<f64>>,
        Bound<'py, PyArray1<bool>>,
    )> {
        let n = accel_m_s2.shape()[0];
        for (a, name) in [(&accel_m_s2, "accel_m_s2"), (&gyro_rad_s, "gyro_rad_s")] {
            if a.shape() != [n, 3] {
                return Err(to_py(anyhow::anyhow!(
                    "{name} has shape {:?}; expected ({n}, 3)",
                    a.shape()
                )));
            }
        }
        let accel = slice2(&accel_m_s2, "accel_m_s2")?;
        let gyro = slice2(&gyro_rad_s, "gyro_rad_s")?;
        let temps: Option<&[f64]>;
        let temp_scalar;
        match &temperature_c {
            None => {
                temps = None;
                temp_scalar = imu_model::units::REFERENCE_TEMP_C;
            }
            Some(PerSample::Scalar(c)) => {
                temps = None;
                temp_scalar = *c;
            }
            Some(PerSample::Array(a)) => {
                temps = Some(slice1(a, "temperature_c", n)?);
                temp_scalar = f64::NAN;
            }
        }
        let times = match &time_s {
            Some(t) => Some(slice1(t, "time_s", n)?),
            None => None,
        };
        let cal = &self.inner;
        let (a_out, g_out, ok) = py.detach(|| {
            let mut a_out = Vec::with_capacity(3 * n);
            let mut g_out = Vec::with_capacity(3 * n);
            let mut ok = Vec::with_capacity(n);
            let mut last: [Option<(f64, Vec3)>; 2] = [None, None];
            for i in 0..n {
                let temp = temps.map_or(temp_scalar, |t| t[i]);
                let temp = if temp.is_nan() {
                    imu_model::units::REFERENCE_TEMP_C
                } else {
                    temp
                };
                let t = times.map_or(0.0, |t| t[i]);
                let angular_accel = match last {
                    [Some((t0, w0)), Some((t1, w1))] if t1 > t0 => (w1 - w0) / (t1 - t0),
                    _ => Vec3::zeros(),
                };
                let m = Measured {
                    accel_m_s2: Vec3::from(accel[i]),
                    gyro_rad_s: Vec3::from(gyro[i]),
                    mag_gauss: Vec3::zeros(),
                };
                let c = cal.correct(&m, temp, t, angular_accel);
                if times.is_some() {
                    last = [last[1], Some((t, c.gyro_rad_s))];
                }
                a_out.extend_from_slice(c.accel_m_s2.as_slice());
                g_out.extend_from_slice(c.gyro_rad_s.as_slice());
                ok.push(c.converged);
            }
            (a_out, g_out, ok)
        });
        Ok((
            PyArray1::from_vec(py, a_out).reshape([n, 3])?,
            PyArray1::from_vec(py, g_out).reshape([n, 3])?,
            PyArray1::from_vec(py, ok),
        ))
    }
}

/// An (N, 3) array's rows, in place.
fn slice2<'a>(a: &'a PyReadonlyArray2<'_, f64>, name: &str) -> PyResult<&'a [[f64; 3]]> {
    Ok(contiguous(a, name)?.as_chunks::<3>().0)
}

/// An (N,) array, in place.
fn slice1<'a>(a: &'a PyReadonlyArray1<'_, f64>, name: &str, n: usize) -> PyResult<&'a [f64]> {
    let s = contiguous(a, name)?;
    if s.len() != n {
        return Err(to_py(anyhow::anyhow!(
            "{name} has {} values for {n} samples",
            s.len()
        )));
    }
    Ok(s)
}
