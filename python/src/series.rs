//! Recordings: `read_series` reads any input the offline clients read (imud MCAP, rosbag2,
//! ROS 1 bag, text with the same options as their `--csv-*` flags) into a [`Series`], which
//! holds the library's `ImuSeries` so an analysis of a recording read once reads nothing again.
//! numpy arrays are made from it on request; `Series.from_arrays` makes one from numpy arrays.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use imu_analysis::ImuSeries;
use imu_analysis::Source;
use imu_analysis::input::{AccelUnit, ColumnRef, Columns, CsvOptions, GyroUnit, InputOptions};
use numpy::{
    PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::error::{IntoPy, to_py};

/// A recording as the analyses see it (the library's `ImuSeries`), shared, never changed.
#[pyclass(frozen, module = "imud._imud")]
pub struct Series {
    /// The samples, times, temperatures and where they came from.
    pub inner: Arc<ImuSeries>,
}

/// `"corrected"` or `"raw"`, as the clients' `--source`.
pub fn parse_source(s: &str) -> anyhow::Result<Source> {
    match s {
        "corrected" => Ok(Source::Corrected),
        "raw" => Ok(Source::Raw),
        _ => anyhow::bail!("source {s:?}: use \"corrected\" or \"raw\""),
    }
}

/// How to read text recordings, and the topic of an MCAP file or rosbag2 directory: the
/// clients' `CsvArgs` as keyword arguments.
#[derive(Clone, Debug, FromPyObject)]
#[pyo3(from_item_all)]
pub struct ReadOptions {
    /// `--source`.
    pub source: String,
    /// `--csv-time-scale-s`.
    pub time_scale_s: f64,
    /// `--rate-hz`.
    pub rate_hz: Option<f64>,
    /// `--start-s`.
    pub start_s: f64,
    /// `--csv-accel`.
    pub accel_unit: String,
    /// `--csv-gyro`.
    pub gyro_unit: String,
    /// `--gyro-csv`.
    pub gyro_file: Option<PathBuf>,
    /// `--columns`.
    pub columns: Option<Vec<String>>,
    /// `--gyro-columns`.
    pub gyro_columns: Option<Vec<String>>,
    /// `--label-column`.
    pub label_column: Option<String>,
    /// `--topic`.
    pub topic: Option<String>,
}

impl ReadOptions {
    /// The library's reading options, every text flag checked as clap checks it.
    fn input_options(&self) -> anyhow::Result<InputOptions> {
        let finite = |v: f64, what: &str| {
            anyhow::ensure!(v.is_finite(), "{what} {v} is not a finite number");
            Ok(v)
        };
        finite(self.time_scale_s, "time_scale_s")?;
        finite(self.start_s, "start_s")?;
        if let Some(r) = self.rate_hz {
            anyhow::ensure!(r.is_finite() && r > 0.0, "rate_hz {r} is not above zero");
            anyhow::ensure!(
                self.time_scale_s == 1.0,
                "rate_hz and time_scale_s exclude each other (text without a time column has no \
                 time unit)"
            );
        }
        let cols = |v: &Option<Vec<String>>| -> anyhow::Result<Option<Vec<ColumnRef>>> {
            v.as_ref()
                .map(|v| {
                    v.iter()
                        .map(|c| c.parse::<ColumnRef>().map_err(anyhow::Error::msg))
                        .collect()
                })
                .transpose()
        };
        Ok(InputOptions {
            source: parse_source(&self.source)?,
            csv: CsvOptions {
                time_scale_s: self.time_scale_s,
                rate_hz: self.rate_hz,
                start_s: self.start_s,
                accel: self
                    .accel_unit
                    .parse::<AccelUnit>()
                    .map_err(anyhow::Error::msg)
                    .context("accel_unit")?,
                gyro: self
                    .gyro_unit
                    .parse::<GyroUnit>()
                    .map_err(anyhow::Error::msg)
                    .context("gyro_unit")?,
                gyro_file: self.gyro_file.clone(),
            },
            columns: Columns {
                main: cols(&self.columns)?,
                gyro: cols(&self.gyro_columns)?,
                label: self
                    .label_column
                    .as_ref()
                    .map(|c| c.parse::<ColumnRef>().map_err(anyhow::Error::msg))
                    .transpose()?,
            },
            topic: self.topic.clone(),
        })
    }
}

/// Reads `paths` (one file, the files of one session, or a directory) as the clients do.
pub fn read(paths: &[PathBuf], options: &ReadOptions) -> anyhow::Result<ImuSeries> {
    let input = options.input_options()?;
    let shown = paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(" ");
    anyhow::ensure!(!paths.is_empty(), "no recording given");
    imu_analysis::input::read_input(paths, &input, &mut |_, _| {})
        .with_context(|| format!("reading {shown}"))
}

/// Reads a recording into a [`Series`] (the GIL released while reading).
#[pyfunction]
pub fn read_series(py: Python<'_>, paths: Vec<PathBuf>, options: ReadOptions) -> PyResult<Series> {
    let series = py.detach(|| read(&paths, &options)).py_err()?;
    Ok(Series {
        inner: Arc::new(series),
    })
}

#[pymethods]
impl Series {
    /// A series from numpy arrays: `time_s` (N,), `accel_m_s2` and `gyro_rad_s` (N, 3),
    /// `temperature_c` (N,) or None (NaN entries are no reading). The arrays are read in place
    /// (C-contiguous float64, no conversion); the series keeps its own copy, the layout the
    /// analyses take.
    #[staticmethod]
    #[pyo3(signature = (time_s, accel_m_s2, gyro_rad_s, temperature_c=None, origin=None))]
    fn from_arrays(
        time_s: PyReadonlyArray1<'_, f64>,
        accel_m_s2: PyReadonlyArray2<'_, f64>,
        gyro_rad_s: PyReadonlyArray2<'_, f64>,
        temperature_c: Option<PyReadonlyArray1<'_, f64>>,
        origin: Option<String>,
    ) -> PyResult<Series> {
        let t = contiguous(&time_s, "time_s")?;
        let n = t.len();
        let triad = |a: &PyReadonlyArray2<'_, f64>, name: &str| -> PyResult<Vec<[f64; 3]>> {
            if a.shape() != [n, 3] {
                return Err(to_py(anyhow::anyhow!(
                    "{name} has shape {:?}; expected ({n}, 3) like time_s",
                    a.shape()
                )));
            }
            let (rows, _) = contiguous(a, name)?.as_chunks::<3>();
            Ok(rows.to_vec())
        };
        let accel = triad(&accel_m_s2, "accel_m_s2")?;
        let gyro = triad(&gyro_rad_s, "gyro_rad_s")?;
        let temp = match &temperature_c {
            Some(c) => {
                let c = contiguous(c, "temperature_c")?;
                if c.len() != n {
                    return Err(to_py(anyhow::anyhow!(
                        "temperature_c has {} values for {n} samples",
                        c.len()
                    )));
                }
                t.iter()
                    .zip(c)
                    .filter(|(_, c)| c.is_finite())
                    .map(|(&t, &c)| (t, c))
                    .collect()
            }
            None => Vec::new(),
        };
        Ok(Series {
            inner: Arc::new(ImuSeries {
                t_s: t.to_vec(),
                accel_m_s2: accel,
                gyro_rad_s: gyro,
                temp,
                origin: origin.unwrap_or_else(|| "numpy arrays".into()),
                ..ImuSeries::default()
            }),
        })
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    /// Sample times, s from the first sample (a new array).
    fn time_s<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.inner.t_s)
    }

    /// Specific force, (N, 3), m/s^2 (a new array).
    fn accel_m_s2<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        triad_array(py, &self.inner.accel_m_s2)
    }

    /// Angular rate, (N, 3), rad/s (a new array).
    fn gyro_rad_s<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        triad_array(py, &self.inner.gyro_rad_s)
    }

    /// The temperature readings as recorded: (times s, degrees C), on the samples' time base.
    fn temperature_readings<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        let (t, c): (Vec<f64>, Vec<f64>) = self.inner.temp.iter().copied().unzip();
        (PyArray1::from_vec(py, t), PyArray1::from_vec(py, c))
    }

    /// Temperature at each sample, degrees C: the latest reading at or before it (NaN before
    /// the first), as the daemon holds the last temperature for the samples after it.
    fn temperature_c<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let s = &self.inner;
        let mut out = Vec::with_capacity(s.len());
        let mut k = 0;
        let mut last = f64::NAN;
        for &t in &s.t_s {
            while k < s.temp.len() && s.temp[k].0 <= t {
                last = s.temp[k].1;
                k += 1;
            }
            out.push(last);
        }
        PyArray1::from_vec(py, out)
    }

    /// Where the series came from, as JSON: origin, the files, topic and gaps (`input`), the
    /// absolute time of t = 0 (ns, and ISO 8601 `started_utc`), the sample rate, samples lost
    /// in time gaps, an early stop and an unfinished file, and what an imud recording says of
    /// itself: the device (`imud.device` metadata, `{}` without) and the calibration in force
    /// (`{"id", "toml", "file"}` or null).
    fn info_json(&self) -> PyResult<String> {
        let s = &self.inner;
        let v = serde_json::json!({
            "origin": s.origin,
            "input": s.input,
            "t0_ns": s.t0_ns,
            "started_utc": s.started_utc(),
            "missing_samples": s.missing_samples(),
            "device": s.input.device,
            "calibration_in_force": s.input.calibration,
            "sample_rate_hz": s.sample_rate_hz(),
            "stopped_early": s.stopped_early,
            "unfinished": s.unfinished,
            "motion_warning": s.motion_warning(),
        });
        Ok(v.to_string())
    }
}

/// A C-contiguous array's data in place, or an error naming the argument. (numpy's
/// `as_slice` also takes Fortran order, whose rows would be read as columns.)
pub fn contiguous<'a, D: numpy::ndarray::Dimension>(
    a: &'a numpy::PyReadonlyArray<'_, f64, D>,
    name: &str,
) -> PyResult<&'a [f64]> {
    let s = if a.is_c_contiguous() {
        a.as_slice().ok()
    } else {
        None
    };
    s.ok_or_else(|| {
        to_py(anyhow::anyhow!(
            "{name} is not C-contiguous float64: pass numpy.ascontiguousarray({name}, dtype=float)"
        ))
    })
}

/// (N, 3) rows as a new numpy array.
fn triad_array<'py>(py: Python<'py>, rows: &[[f64; 3]]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    PyArray1::from_slice(py, rows.as_flattened()).reshape([rows.len(), 3])
}
