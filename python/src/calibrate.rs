//! `imud.calibrate`: the fits of `imu-calibrate`, against references (plans, reference logs,
//! the simulator's truth; one or several recordings) or reference-free, with the same options
//! (model file, `--add`, turn-on bias repeatability, gravity, latitude), by the same library
//! calls. Returns the fit as the library serializes it (`imu-calibrate --json`'s `fit`) and the
//! fitted calibration.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use imu_analysis::ImuSeries;
use imu_analysis::calibrate::reference_free::{ReferenceFreeOptions, calibrate_reference_free};
use imu_analysis::calibrate::{CalibrateOptions, calibrate_recordings};
use imu_analysis::reference::Reference;
use imu_model::{Calibration, Triad, TriadModel};
use pyo3::prelude::*;
use serde_json::json;

use crate::calibration::Calibration as PyCalibration;
use crate::error::IntoPy;
use crate::series::Series;

/// Where one recording's true input comes from: `("plan", PATH, None)` or
/// `("reference", PATH, offset_s)`, as `--plan` / `--reference` [`--reference-offset-s`].
pub type ReferenceSpec = (String, PathBuf, Option<f64>);

/// Opens a reference against its recording, as `imu-calibrate` and `imu-diagnose` do.
pub fn open_reference(spec: &ReferenceSpec, series: &ImuSeries) -> Result<Reference> {
    let (kind, path, offset_s) = spec;
    let (plan, log) = match kind.as_str() {
        "plan" => {
            anyhow::ensure!(
                offset_s.is_none(),
                "a clock offset applies to a reference log, not to --plan {}",
                path.display()
            );
            (Some(path.as_path()), None)
        }
        "reference" => (None, Some(path.as_path())),
        _ => anyhow::bail!("reference kind {kind:?}: use \"plan\" or \"reference\""),
    };
    Reference::open(plan, log, *offset_s, series)?
        .with_context(|| format!("--{kind} {}: no reference", path.display()))
}

/// `--add EFFECT` specs added to `accel` and `gyro` (each once); returns those added.
pub fn add_effects(
    accel: &mut TriadModel,
    gyro: &mut TriadModel,
    add: &[String],
) -> Result<Vec<(Triad, imu_model::EffectKind)>> {
    let mut added = Vec::new();
    for spec in add {
        for (t, k) in imu_cli::parse_effect(spec, "add").map_err(anyhow::Error::msg)? {
            let m = if t == Triad::Gyro {
                &mut *gyro
            } else {
                &mut *accel
            };
            if !m.has(k) {
                m.add(k);
                added.push((t, k));
            }
        }
    }
    Ok(added)
}

/// Fit options from the model file and `add`, as `imu-calibrate`'s: the effects to fit, and
/// from the file's noise tables the bias wander over `duration_s` and the noise models.
fn options(model: Option<&Path>, add: &[String], duration_s: f64) -> Result<CalibrateOptions> {
    let mut opts = match model {
        Some(path) => CalibrateOptions::from_model(
            &Calibration::load(path)
                .with_context(|| format!("loading model {}", path.display()))?,
            duration_s,
        ),
        None => CalibrateOptions::default(),
    };
    add_effects(&mut opts.accel, &mut opts.gyro, add)?;
    Ok(opts)
}

/// A turn-on bias repeatability given as one value or X, Y, Z.
fn per_axis(values: Option<Vec<f64>>, name: &str) -> Result<Option<[f64; 3]>> {
    let Some(values) = values else {
        return Ok(None);
    };
    let v = match values.as_slice() {
        [s] => [*s; 3],
        [x, y, z] => [*x, *y, *z],
        _ => anyhow::bail!(
            "{name} takes one value or three (X,Y,Z), got {}",
            values.len()
        ),
    };
    anyhow::ensure!(
        v.iter().all(|x| x.is_finite() && *x >= 0.0),
        "{name}: {v:?} must be standard deviations (0 or more)"
    );
    Ok(Some(v))
}

fn duration_s(s: &ImuSeries) -> f64 {
    s.t_s[s.len() - 1] - s.t_s[0]
}

/// The options of one call, as keyword arguments.
#[derive(Debug, FromPyObject)]
#[pyo3(from_item_all)]
pub struct CalibrateArgs {
    references: Vec<ReferenceSpec>,
    reference_free: bool,
    gravity_m_s2: Option<f64>,
    latitude_deg: Option<f64>,
    accel_turn_on_bias_m_s2: Option<Vec<f64>>,
    gyro_turn_on_bias_rad_s: Option<Vec<f64>>,
    model: Option<PathBuf>,
    add: Vec<String>,
}

/// The fit, as JSON `{"procedure", "fit"}`, and its calibration.
fn calibrate(series: &[&ImuSeries], a: &CalibrateArgs) -> Result<(String, Calibration)> {
    for s in series {
        anyhow::ensure!(!s.is_empty(), "{}: no samples", s.origin);
    }
    if a.reference_free {
        anyhow::ensure!(
            a.references.is_empty(),
            "reference_free takes no plan or reference"
        );
        let [s] = series else {
            anyhow::bail!(
                "reference-free takes one recording, got {}: the still poses and the moves \
                 between them must come from one power-on",
                series.len()
            );
        };
        let base = options(a.model.as_deref(), &a.add, duration_s(s))?;
        let opts = ReferenceFreeOptions {
            accel: base.accel,
            gyro: base.gyro,
            gravity_m_s2: a.gravity_m_s2,
            latitude_deg: a.latitude_deg,
            accel_bias_drift_m_s2: base.accel_bias_drift_m_s2,
            gyro_bias_drift_rad_s: base.gyro_bias_drift_rad_s,
            ..ReferenceFreeOptions::default()
        };
        let fit = calibrate_reference_free(s, &opts)
            .with_context(|| format!("calibrating {} (reference-free)", s.origin))?;
        let j = json!({"procedure": "reference-free", "fit": fit});
        return Ok((j.to_string(), fit.calibration));
    }
    anyhow::ensure!(
        a.gravity_m_s2.is_none() && a.latitude_deg.is_none(),
        "gravity_m_s2 and latitude_deg apply to reference_free only"
    );
    anyhow::ensure!(
        a.references.len() == series.len(),
        "{} references for {} recordings: give one plan or reference per recording, in order",
        a.references.len(),
        series.len()
    );
    let references = series
        .iter()
        .zip(&a.references)
        .map(|(s, r)| open_reference(r, s))
        .collect::<Result<Vec<_>>>()?;
    let mut opts = options(
        a.model.as_deref(),
        &a.add,
        series.iter().map(|s| duration_s(s)).fold(0.0, f64::max),
    )?;
    opts.accel_turn_on_bias_m_s2 =
        per_axis(a.accel_turn_on_bias_m_s2.clone(), "accel_turn_on_bias_m_s2")?;
    opts.gyro_turn_on_bias_rad_s =
        per_axis(a.gyro_turn_on_bias_rad_s.clone(), "gyro_turn_on_bias_rad_s")?;
    let pairs: Vec<_> = series.iter().copied().zip(&references).collect();
    let names = series
        .iter()
        .map(|s| s.origin.as_str())
        .collect::<Vec<_>>()
        .join(", ");
    let fit =
        calibrate_recordings(&pairs, &opts).with_context(|| format!("calibrating {names}"))?;
    let j = json!({"procedure": "reference", "fit": fit});
    Ok((j.to_string(), fit.calibration))
}

/// Calibrates `series` (read from the raw stream), the GIL released while fitting.
#[pyfunction]
pub fn calibrate_json(
    py: Python<'_>,
    series: Vec<PyRef<'_, Series>>,
    args: CalibrateArgs,
) -> PyResult<(String, PyCalibration)> {
    let inner: Vec<_> = series.iter().map(|s| s.inner.clone()).collect();
    let (json, mut cal) = py
        .detach(move || {
            let refs: Vec<&ImuSeries> = inner.iter().map(|s| s.as_ref()).collect();
            calibrate(&refs, &args)
        })
        .py_err()?;
    cal.provenance.tool = Some(format!("imud-python {}", env!("CARGO_PKG_VERSION")));
    Ok((json, PyCalibration { inner: cal }))
}
