//! `imu-calibrate`: fit accel and gyro error models (bias, scale, misalignment, optionally
//! g-sensitivity and more) from the static positions and rate plateaus of a recording, against
//! a reference giving the true input, and write an imud calibration file.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::Parser;
use imu_analysis::Source;
use imu_analysis::fit::{
    CalibrateOptions, CalibrationFit, FitResult, bias_drift_from_noise, calibrate,
};
use imu_analysis::input::CsvOptions;
use imu_analysis::progress::read_any;
use imu_analysis::segment::SegmentKind;
use imu_model::{Calibration, InputFile, Triad, TriadModel};
use serde::Serialize;

/// Command line.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    /// Recording: imud MCAP log (the raw stream is fitted), rosbag2 MCAP or CSV.
    recording: PathBuf,
    /// Reference for the true input: the simulator's truth MCAP of this recording.
    #[arg(long, value_name = "TRUTH.mcap")]
    reference: PathBuf,
    /// Calibration-format file whose accel and gyro effects say what to fit (values are the
    /// starting point; default: bias + scale + misalignment for both). Its `[accel.noise]` and
    /// `[gyro.noise]` (e.g. from imu-noise) widen the bias standard errors by the bias wander.
    #[arg(long, value_name = "MODEL.toml")]
    model: Option<PathBuf>,
    /// Truth model to compare the fit with (prints fitted vs true in standard errors).
    #[arg(long, value_name = "TRUTH_MODEL.toml")]
    truth: Option<PathBuf>,
    /// Write the calibration here.
    #[arg(short, long, value_name = "CALIBRATION.toml")]
    output: Option<PathBuf>,
    /// Print JSON instead of tables.
    #[arg(long)]
    json: bool,
}

/// One row of the fitted-vs-true comparison.
#[derive(Debug, Serialize)]
struct TruthRow {
    triad: Triad,
    name: String,
    unit: String,
    fitted: f64,
    truth: f64,
    std_error: Option<f64>,
    error_in_se: Option<f64>,
}

#[derive(Debug, Serialize)]
struct JsonOut<'a> {
    recording: String,
    reference: String,
    output: Option<String>,
    fit: &'a CalibrationFit,
    truth_comparison: Option<Vec<TruthRow>>,
}

/// The input's path and SHA-256, hashed as a stream (recordings can be hundreds of MB).
fn input_file(path: &Path) -> Result<InputFile> {
    use sha2::Digest;
    let mut file =
        std::fs::File::open(path).with_context(|| format!("reading {}", path.display()))?;
    let mut hasher = sha2::Sha256::new();
    std::io::copy(&mut file, &mut hasher).with_context(|| format!("reading {}", path.display()))?;
    let digest = hasher.finalize();
    Ok(InputFile {
        path: path.display().to_string(),
        sha256: Some(digest.iter().map(|b| format!("{b:02x}")).collect()),
    })
}

/// Current UTC time as RFC 3339 text (whole seconds).
fn now_rfc3339() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// Fit options from the model file: its accel and gyro effects, and, from its noise tables (a
/// noise characterisation such as imu-noise's), the bias wander over a recording of
/// `duration_s` that no residual can show and the covariance of the segment means.
fn options(model: Option<&Path>, duration_s: f64) -> Result<CalibrateOptions> {
    let mut opts = CalibrateOptions::default();
    if let Some(path) = model {
        let m =
            Calibration::load(path).with_context(|| format!("loading model {}", path.display()))?;
        if !m.accel.kinds().is_empty() {
            opts.accel = effects_only(&m.accel);
        }
        if !m.gyro.kinds().is_empty() {
            opts.gyro = effects_only(&m.gyro);
        }
        let drift = |t: &TriadModel| {
            t.noise
                .as_ref()
                .map(|n| bias_drift_from_noise(n, duration_s))
        };
        opts.accel_bias_drift_m_s2 = drift(&m.accel);
        opts.gyro_bias_drift_rad_s = drift(&m.gyro);
        opts.accel_noise = m.accel.noise.clone();
        opts.gyro_noise = m.gyro.noise.clone();
    }
    Ok(opts)
}

/// The effects and values of a model, without its noise and residual statistics.
fn effects_only(m: &TriadModel) -> TriadModel {
    let mut out = m.clone();
    out.noise = None;
    out.residual_rms = None;
    out.set_std_errors(None);
    out
}

fn truth_rows(fit: &FitResult, truth: &TriadModel) -> Vec<TruthRow> {
    let names = truth.param_names(fit.triad);
    let values = truth.params();
    (0..fit.params.len())
        .map(|i| {
            let t = names
                .iter()
                .position(|n| *n == fit.names[i])
                .map_or(0.0, |k| values[k]);
            let se = fit.std_errors[i];
            TruthRow {
                triad: fit.triad,
                name: fit.names[i].clone(),
                unit: fit.units[i].clone(),
                fitted: fit.params[i],
                truth: t,
                std_error: se,
                error_in_se: se.map(|s| (fit.params[i] - t) / s),
            }
        })
        .collect()
}

fn print_fit(out: &mut impl Write, fit: &FitResult) -> std::io::Result<()> {
    writeln!(
        out,
        "\n{} ({} segments, {} free parameters, reduced chi2 {:.2}, {} iterations{})",
        fit.triad,
        fit.residuals.len(),
        fit.free.len(),
        fit.reduced_chi2,
        fit.iterations,
        if fit.converged { "" } else { ", NOT converged" }
    )?;
    writeln!(
        out,
        "  {:<36} {:>13} {:>11}  unit",
        "parameter", "value", "std error"
    )?;
    for i in 0..fit.params.len() {
        let se = fit.std_errors[i].map_or_else(|| "not fitted".to_string(), |s| format!("{s:.3e}"));
        writeln!(
            out,
            "  {:<36} {:>13.5e} {:>11}  {}",
            fit.names[i], fit.params[i], se, fit.units[i]
        )?;
    }
    let unit = fit.triad.unit();
    writeln!(
        out,
        "  residual RMS x {:.3e}  y {:.3e}  z {:.3e}  {unit}",
        fit.residual_rms[0], fit.residual_rms[1], fit.residual_rms[2]
    )?;
    for w in &fit.warnings {
        writeln!(out, "  warning: {w}")?;
    }
    Ok(())
}

fn print_tables(
    out: &mut impl Write,
    fit: &CalibrationFit,
    truth: Option<&[TruthRow]>,
) -> std::io::Result<()> {
    let s = &fit.segmentation;
    writeln!(
        out,
        "segments: {} static, {} rate plateaus (window {} samples; thresholds: accel std {:.3e} m/s^2, gyro std {:.3e} rad/s)",
        s.count(SegmentKind::Static),
        s.count(SegmentKind::Plateau),
        s.window_samples,
        s.accel_std_threshold_m_s2,
        s.gyro_std_threshold_rad_s
    )?;
    for n in &fit.notes {
        writeln!(out, "note: {n}")?;
    }
    print_fit(out, &fit.accel)?;
    print_fit(out, &fit.gyro)?;
    if let Some(rows) = truth {
        writeln!(out, "\nfitted vs truth")?;
        writeln!(
            out,
            "  {:<5} {:<36} {:>13} {:>13} {:>8}  unit",
            "triad", "parameter", "fitted", "truth", "err/SE"
        )?;
        for r in rows {
            let z = r
                .error_in_se
                .map_or_else(|| "-".to_string(), |z| format!("{z:.2}"));
            writeln!(
                out,
                "  {:<5} {:<36} {:>13.5e} {:>13.5e} {:>8}  {}",
                r.triad.to_string(),
                r.name,
                r.fitted,
                r.truth,
                z,
                r.unit
            )?;
        }
    }
    Ok(())
}

fn run(cli: &Cli) -> Result<()> {
    let series = read_any(&cli.recording, Source::Raw, &CsvOptions::default())
        .with_context(|| format!("reading {}", cli.recording.display()))?;
    if series.is_empty() {
        bail!("{}: no samples", cli.recording.display());
    }
    // Streamed while fitting: a 6-hour truth file would take 0.5 GB in memory.
    let truth = imu_analysis::reference::Reference::TruthFile(cli.reference.clone());
    let duration_s = series.t_s[series.len() - 1] - series.t_s[0];
    let opts = options(cli.model.as_deref(), duration_s)?;
    let mut fit = calibrate(&series, &truth, &opts)
        .with_context(|| format!("calibrating {}", cli.recording.display()))?;

    let cal = &mut fit.calibration;
    cal.description = Some(format!(
        "accel and gyro fitted from {} static segments and {} rate plateaus",
        fit.segmentation.count(SegmentKind::Static),
        fit.segmentation.count(SegmentKind::Plateau)
    ));
    cal.provenance.created = Some(now_rfc3339());
    cal.provenance.tool = Some(format!("imu-calibrate {}", env!("CARGO_PKG_VERSION")));
    cal.provenance.procedure = Some(
        "automatic static/plateau segmentation; weighted Levenberg-Marquardt fit of segment means \
         to the reference's true input (Aslan & Saranli 3.1.2, 3.2.2, 3.2.3)"
            .into(),
    );
    cal.provenance.inputs = vec![input_file(&cli.recording)?, input_file(&cli.reference)?];
    if !fit.notes.is_empty()
        || !fit.accel.unobservable.is_empty()
        || !fit.gyro.unobservable.is_empty()
    {
        let held: Vec<String> = fit
            .accel
            .unobservable
            .iter()
            .map(|u| format!("accel {}", u.name))
            .chain(
                fit.gyro
                    .unobservable
                    .iter()
                    .map(|u| format!("gyro {}", u.name)),
            )
            .collect();
        let mut text = fit.notes.join("; ");
        if !held.is_empty() {
            if !text.is_empty() {
                text.push_str("; ");
            }
            text.push_str(&format!(
                "not observable, held at start value: {}",
                held.join(", ")
            ));
        }
        cal.provenance.notes = Some(text);
    }
    if let Some(path) = &cli.output {
        cal.save(path)
            .with_context(|| format!("writing {}", path.display()))?;
    }

    let truth_rows = match &cli.truth {
        Some(path) => {
            let t = Calibration::load(path)
                .with_context(|| format!("loading truth {}", path.display()))?;
            let mut rows = truth_rows(&fit.accel, &t.accel);
            rows.extend(truth_rows(&fit.gyro, &t.gyro));
            Some(rows)
        }
        None => None,
    };

    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if cli.json {
        let j = JsonOut {
            recording: cli.recording.display().to_string(),
            reference: cli.reference.display().to_string(),
            output: cli.output.as_ref().map(|p| p.display().to_string()),
            fit: &fit,
            truth_comparison: truth_rows,
        };
        serde_json::to_writer_pretty(&mut out, &j)?;
        writeln!(out)?;
    } else {
        print_tables(&mut out, &fit, truth_rows.as_deref())?;
        if let Some(p) = &cli.output {
            writeln!(out, "\nwrote {}", p.display())?;
        }
    }
    out.flush()?;
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let broken_pipe = e.chain().any(|c| {
                c.downcast_ref::<std::io::Error>()
                    .map(std::io::Error::kind)
                    .or_else(|| {
                        c.downcast_ref::<serde_json::Error>()
                            .and_then(serde_json::Error::io_error_kind)
                    })
                    == Some(std::io::ErrorKind::BrokenPipe)
            });
            if broken_pipe {
                return ExitCode::SUCCESS;
            }
            eprintln!("imu-calibrate: error: {e:#}");
            ExitCode::from(1)
        }
    }
}
