//! `imud.diagnose` and `imud.ladder`: the model workbench of `imu-diagnose` (is the residual of
//! a model consistent with the noise floor, which library effects explain what is left, and the
//! ladder that adds them one at a time), with its options and the same library calls. The
//! diagnoses, steps and notes are the library's serialization, as in `imu-diagnose --json`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use imu_analysis::ImuSeries;
use imu_analysis::workbench::{DiagnoseOptions, Ladder, Workbench};
use imu_model::{Calibration, Triad, TriadModel};
use pyo3::prelude::*;
use serde_json::json;

use crate::calibrate::{ReferenceSpec, add_effects, open_reference};
use crate::calibration::Calibration as PyCalibration;
use crate::error::IntoPy;
use crate::series::Series;

/// The options shared by both calls, as keyword arguments.
#[derive(Debug, FromPyObject)]
#[pyo3(from_item_all)]
pub struct WorkbenchArgs {
    /// `--plan` or `--reference` (with its offset); None with `reference_free`.
    reference: Option<ReferenceSpec>,
    reference_free: bool,
    gravity_m_s2: Option<f64>,
    latitude_deg: Option<f64>,
    /// `--model` (diagnose) or `--base` (ladder).
    model: Option<PathBuf>,
    /// `--add` (diagnose only).
    add: Vec<String>,
}

/// The model file's accel and gyro effects (a triad without effects gets the base model).
fn load_model(path: Option<&Path>) -> Result<Calibration> {
    let mut cal = match path {
        Some(p) => {
            Calibration::load(p).with_context(|| format!("loading model {}", p.display()))?
        }
        None => Calibration::identity(),
    };
    for t in [&mut cal.accel, &mut cal.gyro] {
        *t = if t.kinds().is_empty() {
            TriadModel::with_effects(&TriadModel::PAPER_BASE)
        } else {
            t.effects_only()
        };
    }
    Ok(cal)
}

/// Workbench options: the model file's noise tables, if any, as the noise floor.
fn options(path: Option<&Path>) -> Result<DiagnoseOptions> {
    let mut opts = DiagnoseOptions::default();
    if let Some(p) = path {
        let cal = Calibration::load(p).with_context(|| format!("loading model {}", p.display()))?;
        opts.accel_noise = cal.accel.noise;
        opts.gyro_noise = cal.gyro.noise;
    }
    Ok(opts)
}

/// The workbench on `series`, against its reference or reference-free, and the model.
fn with_workbench<T>(
    series: &ImuSeries,
    a: &WorkbenchArgs,
    f: impl FnOnce(&Workbench<'_>) -> Result<T>,
) -> Result<T> {
    anyhow::ensure!(!series.is_empty(), "{}: no samples", series.origin);
    let opts = options(a.model.as_deref())?;
    let wb = match (&a.reference, a.reference_free) {
        (Some(r), false) => {
            anyhow::ensure!(
                a.gravity_m_s2.is_none() && a.latitude_deg.is_none(),
                "gravity_m_s2 and latitude_deg apply to reference_free only"
            );
            let reference = open_reference(r, series)?;
            Workbench::new(series, &reference, opts)
        }
        (None, true) => Workbench::reference_free(series, a.gravity_m_s2, a.latitude_deg, opts),
        _ => anyhow::bail!("give exactly one of plan, reference or reference_free"),
    }
    .with_context(|| format!("segmenting {}", series.origin))?;
    f(&wb)
}

/// Diagnoses the model against `series` (raw stream), the GIL released while it runs: JSON
/// `{"notes", "note_codes", "added", "verdict", "verdict_codes", "diagnoses": [accel, gyro]}`.
#[pyfunction]
pub fn diagnose_json(py: Python<'_>, series: &Series, args: WorkbenchArgs) -> PyResult<String> {
    let inner = series.inner.clone();
    py.detach(move || -> Result<String> {
        let mut model = load_model(args.model.as_deref())?;
        let added = add_effects(&mut model.accel, &mut model.gyro, &args.add)?;
        with_workbench(&inner, &args, |wb| {
            let accel = wb.diagnose(Triad::Accel, &model.accel)?;
            let gyro = wb.diagnose(Triad::Gyro, &model.gyro)?;
            Ok(json!({
                "notes": wb.notes.0,
                "note_codes": wb.notes.codes(),
                "added": added,
                "verdict": {"accel": accel.verdict.to_string(), "gyro": gyro.verdict.to_string()},
                "verdict_codes": {"accel": accel.verdict.codes(), "gyro": gyro.verdict.codes()},
                "diagnoses": [accel, gyro],
            })
            .to_string())
        })
    })
    .py_err()
}

/// Runs the ladder from the base model (`model`), the GIL released while it runs: JSON
/// `{"notes", "note_codes", "added", "steps", "verdict", "verdict_codes", "final_diagnoses"}` and
/// the final calibration.
#[pyfunction]
pub fn ladder_json(
    py: Python<'_>,
    series: &Series,
    args: WorkbenchArgs,
) -> PyResult<(String, PyCalibration)> {
    let inner = series.inner.clone();
    let (json, mut cal) = py
        .detach(move || -> Result<(String, Calibration)> {
            anyhow::ensure!(
                args.add.is_empty(),
                "the ladder adds effects itself: no add"
            );
            let base = load_model(args.model.as_deref())?;
            with_workbench(&inner, &args, |wb| {
                let Ladder {
                    steps,
                    final_diagnoses,
                    calibration,
                    notes,
                    ..
                } = wb.ladder(&base)?;
                let added: Vec<_> = steps.iter().filter_map(|s| s.added).collect();
                let j = json!({
                    "notes": notes.0,
                    "note_codes": notes.codes(),
                    "added": added,
                    "steps": steps,
                    "verdict": {
                        "accel": final_diagnoses[0].verdict.to_string(),
                        "gyro": final_diagnoses[1].verdict.to_string(),
                    },
                    "verdict_codes": {
                        "accel": final_diagnoses[0].verdict.codes(),
                        "gyro": final_diagnoses[1].verdict.codes(),
                    },
                    "final_diagnoses": final_diagnoses,
                });
                Ok((j.to_string(), calibration))
            })
        })
        .py_err()?;
    cal.provenance.tool = Some(format!("imud-python {}", env!("CARGO_PKG_VERSION")));
    Ok((json, PyCalibration { inner: cal }))
}
