//! `imu-calibrate`: fit accel and gyro error models (bias, scale, misalignment, optionally
//! g-sensitivity and more) from the static positions and rate plateaus of a recording, against
//! a reference giving the true input (a test plan, a time-stamped reference log, or the
//! simulator's truth), or from many hand-held still poses and
//! the moves between them without any reference (`--reference-free`), and write an imud
//! calibration file.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{ArgGroup, Parser};
use imu_analysis::Source;
use imu_analysis::fit::{
    CalibrateOptions, CalibrationFit, FitResult, bias_drift_from_noise, calibrate,
};
use imu_analysis::input::CsvOptions;
use imu_analysis::progress::read_any;
use imu_analysis::reference::Reference;
use imu_analysis::reference_free::{
    ReferenceFreeFit, ReferenceFreeOptions, TriadFit, calibrate_reference_free, in_accel_frame,
};
use imu_analysis::segment::SegmentKind;
use imu_model::{Calibration, InputFile, Triad, TriadModel};
use serde::Serialize;

/// Command line. Exactly one procedure (the `procedure` group) says where the true input
/// comes from.
#[derive(Debug, Parser)]
#[command(version, about)]
#[command(group(ArgGroup::new("procedure").required(true).multiple(false)))]
struct Cli {
    /// Recording: imud MCAP log (the raw stream is fitted), rosbag2 MCAP or CSV.
    recording: PathBuf,
    /// Test plan: the procedure and its nominal inputs, in order (format imud-plan/1; see
    /// config/plans/). Its steps are matched to the recording's segments and checked.
    #[arg(long, value_name = "PLAN.toml", group = "procedure")]
    plan: Option<PathBuf>,
    /// Reference for the true input: the simulator's truth MCAP of this recording, or a
    /// time-stamped reference log (CSV with a header such as
    /// `t_s,wx_deg_s,wy_deg_s,wz_deg_s,fx_m_s2,fy_m_s2,fz_m_s2`), aligned in time with the
    /// recording by cross-correlation. Told apart by content (MCAP magic bytes).
    #[arg(long, value_name = "TRUTH.mcap|LOG.csv", group = "procedure")]
    reference: Option<PathBuf>,
    /// Clock offset of a reference log (log clock minus recording clock, seconds from the
    /// recording's first sample) instead of finding it by cross-correlation.
    #[arg(
        long,
        value_name = "S",
        requires = "reference",
        conflicts_with = "plan",
        allow_negative_numbers = true
    )]
    reference_offset_s: Option<f64>,
    /// No reference: the unit was held still in many (30 or more) orientations and turned
    /// between them. The accelerometer is fitted to the gravity magnitude (its axes define the
    /// body frame), the gyro bias to the still poses, the gyro gains to the integrated moves.
    #[arg(long, group = "procedure")]
    reference_free: bool,
    /// Local gravity for --reference-free, m/s^2 (default: WGS-84 normal gravity at
    /// --latitude-deg, else 9.80665).
    #[arg(long, value_name = "M_S2")]
    gravity_m_s2: Option<f64>,
    /// Geodetic latitude for --reference-free, degrees: local gravity (unless given) and the
    /// vertical part of Earth's rate, removed from the gyro bias.
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    latitude_deg: Option<f64>,
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
struct JsonOutReferenceFree<'a> {
    recording: String,
    procedure: &'static str,
    output: Option<String>,
    fit: &'a ReferenceFreeFit,
    /// The truth is expressed in the body frame the accelerometer defines (the fit's gauge).
    truth_comparison: Option<Vec<TruthRow>>,
}

#[derive(Debug, Serialize)]
struct JsonOut<'a> {
    recording: String,
    reference: String,
    reference_description: String,
    output: Option<String>,
    fit: &'a CalibrationFit,
    truth_comparison: Option<Vec<TruthRow>>,
}

/// The input files' hashes, computed while the recording is read and fitted (hundreds of MB
/// take a noticeable fraction of a second).
type Hashing = std::thread::JoinHandle<Result<Vec<InputFile>>>;

/// Starts hashing `paths` in the background.
fn hash_in_background(paths: Vec<PathBuf>) -> Hashing {
    std::thread::spawn(move || paths.iter().map(|p| input_file(p)).collect())
}

/// The input's path and SHA-256.
fn input_file(path: &Path) -> Result<InputFile> {
    imu_analysis::provenance::input_file(path)
        .with_context(|| format!("reading {}", path.display()))
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

/// Fitted vs true for every parameter (an effect absent from the truth has truth 0).
fn compare(
    triad: Triad,
    names: &[String],
    units: &[String],
    params: &[f64],
    std_errors: &[Option<f64>],
    truth: &TriadModel,
) -> Vec<TruthRow> {
    let truth_names = truth.param_names(triad);
    let values = truth.params();
    (0..params.len())
        .map(|i| {
            let t = truth_names
                .iter()
                .position(|n| *n == names[i])
                .map_or(0.0, |k| values[k]);
            let se = std_errors[i];
            TruthRow {
                triad,
                name: names[i].clone(),
                unit: units[i].clone(),
                fitted: params[i],
                truth: t,
                std_error: se,
                error_in_se: se.map(|s| (params[i] - t) / s),
            }
        })
        .collect()
}

fn truth_rows(fit: &FitResult, truth: &TriadModel) -> Vec<TruthRow> {
    compare(
        fit.triad,
        &fit.names,
        &fit.units,
        &fit.params,
        &fit.std_errors,
        truth,
    )
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
        print_truth(out, rows)?;
    }
    Ok(())
}

fn print_truth(out: &mut impl Write, rows: &[TruthRow]) -> std::io::Result<()> {
    {
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

/// One reference-free triad fit (parameters, standard errors, residuals, warnings).
fn print_triad_fit(out: &mut impl Write, fit: &TriadFit) -> std::io::Result<()> {
    writeln!(
        out,
        "\n{} ({} residuals, {} free parameters, reduced chi2 {:.2}, smallest normalised eigenvalue {:.1e}, {} iterations{})",
        fit.triad,
        fit.n_residuals,
        fit.free.len(),
        fit.reduced_chi2,
        fit.min_eigenvalue,
        fit.iterations,
        if fit.converged { "" } else { ", NOT converged" }
    )?;
    writeln!(
        out,
        "  {:<36} {:>13} {:>11}  unit",
        "parameter", "value", "std error"
    )?;
    for i in 0..fit.params.len() {
        let se = fit.std_errors[i].map_or_else(|| "held".to_string(), |s| format!("{s:.3e}"));
        writeln!(
            out,
            "  {:<36} {:>13.5e} {:>11}  {}",
            fit.names[i], fit.params[i], se, fit.units[i]
        )?;
    }
    writeln!(
        out,
        "  residual RMS {:.3e} {} ({})",
        fit.residual_rms, fit.residual_unit, fit.residual
    )?;
    for u in &fit.unobservable {
        writeln!(out, "  held: {}: {}", u.name, u.reason)?;
    }
    for w in &fit.warnings {
        writeln!(out, "  warning: {w}")?;
    }
    Ok(())
}

fn print_reference_free(
    out: &mut impl Write,
    fit: &ReferenceFreeFit,
    truth: Option<&[TruthRow]>,
) -> std::io::Result<()> {
    let s = &fit.segmentation;
    writeln!(
        out,
        "reference-free: {} still poses, {} moves (window {} samples; thresholds: accel std {:.3e} m/s^2, gyro std {:.3e} rad/s); g = {:.6} m/s^2",
        fit.poses.len(),
        fit.moves.len(),
        s.window_samples,
        s.accel_std_threshold_m_s2,
        s.gyro_std_threshold_rad_s,
        fit.gravity_m_s2
    )?;
    for n in &fit.notes {
        writeln!(out, "note: {n}")?;
    }
    print_triad_fit(out, &fit.accel)?;
    print_triad_fit(out, &fit.gyro)?;
    if let Some(rows) = truth {
        writeln!(
            out,
            "\nfitted vs truth (truth re-expressed in the body frame the accelerometer defines)"
        )?;
        print_truth(out, rows)?;
    }
    Ok(())
}

/// Provenance shared by both procedures: when, which tool, which inputs, and the notes with
/// the parameters that were held.
fn stamp(
    cal: &mut Calibration,
    inputs: Hashing,
    notes: &[String],
    held: Vec<String>,
) -> Result<()> {
    cal.provenance.created = Some(imu_analysis::provenance::now_rfc3339());
    cal.provenance.tool = Some(format!("imu-calibrate {}", env!("CARGO_PKG_VERSION")));
    cal.provenance.inputs = inputs
        .join()
        .map_err(|_| anyhow::anyhow!("the input hashing thread panicked"))??;
    if !notes.is_empty() || !held.is_empty() {
        let mut text = notes.join("; ");
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
    Ok(())
}

/// The reference named on the command line (a plan or a --reference file), and its file.
fn load_reference(
    cli: &Cli,
    series: &imu_analysis::ImuSeries,
) -> Result<Option<(Reference, PathBuf)>> {
    let r = Reference::open(
        cli.plan.as_deref(),
        cli.reference.as_deref(),
        cli.reference_offset_s,
        series,
    )?;
    let path = cli.plan.clone().or_else(|| cli.reference.clone());
    Ok(r.zip(path))
}

fn run(cli: &Cli) -> Result<()> {
    // (clap's `requires` counts a flag's implicit `false` as present, so this is checked here.)
    if !cli.reference_free && (cli.gravity_m_s2.is_some() || cli.latitude_deg.is_some()) {
        bail!("--gravity-m-s2 and --latitude-deg apply to --reference-free only");
    }
    let inputs = std::iter::once(&cli.recording)
        .chain(cli.plan.as_ref().or(cli.reference.as_ref()))
        .cloned()
        .collect();
    let hashing = hash_in_background(inputs);
    let series = read_any(&cli.recording, Source::Raw, &CsvOptions::default())
        .with_context(|| format!("reading {}", cli.recording.display()))?;
    if series.is_empty() {
        bail!("{}: no samples", cli.recording.display());
    }
    match load_reference(cli, &series)? {
        Some((reference, path)) => run_reference(cli, &series, &reference, &path, hashing),
        None => run_reference_free(cli, &series, hashing),
    }
}

fn run_reference_free(cli: &Cli, series: &imu_analysis::ImuSeries, hashing: Hashing) -> Result<()> {
    let duration_s = series.t_s[series.len() - 1] - series.t_s[0];
    let base = options(cli.model.as_deref(), duration_s)?;
    let opts = ReferenceFreeOptions {
        accel: base.accel,
        gyro: base.gyro,
        gravity_m_s2: cli.gravity_m_s2,
        latitude_deg: cli.latitude_deg,
        accel_bias_drift_m_s2: base.accel_bias_drift_m_s2,
        gyro_bias_drift_rad_s: base.gyro_bias_drift_rad_s,
        ..ReferenceFreeOptions::default()
    };
    let mut fit = calibrate_reference_free(series, &opts)
        .with_context(|| format!("calibrating {} (reference-free)", cli.recording.display()))?;
    // The gauge is a convention, not a limit of the data: listed in the notes, not as held.
    let held: Vec<String> = [&fit.accel, &fit.gyro]
        .iter()
        .flat_map(|f| {
            f.unobservable
                .iter()
                .filter(|u| !u.reason.starts_with("gauge"))
                .map(|u| format!("{} {}", f.triad, u.name))
        })
        .collect();
    stamp(&mut fit.calibration, hashing, &fit.notes, held)?;
    if let Some(path) = &cli.output {
        fit.calibration
            .save(path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let truth_rows = match &cli.truth {
        Some(path) => {
            let t = Calibration::load(path)
                .with_context(|| format!("loading truth {}", path.display()))?;
            let t = in_accel_frame(&t);
            let mut rows = Vec::new();
            for (f, m) in [(&fit.accel, &t.accel), (&fit.gyro, &t.gyro)] {
                rows.extend(compare(
                    f.triad,
                    &f.names,
                    &f.units,
                    &f.params,
                    &f.std_errors,
                    m,
                ));
            }
            Some(rows)
        }
        None => None,
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if cli.json {
        let j = JsonOutReferenceFree {
            recording: cli.recording.display().to_string(),
            procedure: "reference-free",
            output: cli.output.as_ref().map(|p| p.display().to_string()),
            fit: &fit,
            truth_comparison: truth_rows,
        };
        serde_json::to_writer_pretty(&mut out, &j)?;
        writeln!(out)?;
    } else {
        print_reference_free(&mut out, &fit, truth_rows.as_deref())?;
        if let Some(p) = &cli.output {
            writeln!(out, "\nwrote {}", p.display())?;
        }
    }
    out.flush()?;
    Ok(())
}

fn run_reference(
    cli: &Cli,
    series: &imu_analysis::ImuSeries,
    truth: &Reference,
    reference: &Path,
    hashing: Hashing,
) -> Result<()> {
    let duration_s = series.t_s[series.len() - 1] - series.t_s[0];
    let opts = options(cli.model.as_deref(), duration_s)?;
    let mut fit = calibrate(series, truth, &opts)
        .with_context(|| format!("calibrating {}", cli.recording.display()))?;

    let cal = &mut fit.calibration;
    cal.description = Some(format!(
        "accel and gyro fitted from {} static segments and {} rate plateaus",
        fit.segmentation.count(SegmentKind::Static),
        fit.segmentation.count(SegmentKind::Plateau)
    ));
    cal.provenance.procedure = Some(format!(
        "static/plateau segmentation; weighted Levenberg-Marquardt fit of segment means to the \
         true input from the {} (Aslan & Saranli 3.1.2, 3.2.2, 3.2.3)",
        truth.describe()
    ));
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
    stamp(cal, hashing, &fit.notes, held)?;
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
            reference: reference.display().to_string(),
            reference_description: truth.describe(),
            output: cli.output.as_ref().map(|p| p.display().to_string()),
            fit: &fit,
            truth_comparison: truth_rows,
        };
        serde_json::to_writer_pretty(&mut out, &j)?;
        writeln!(out)?;
    } else {
        writeln!(out, "reference: {}", truth.describe())?;
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
            if imu_analysis::cli::is_broken_pipe(e.chain()) {
                return ExitCode::SUCCESS;
            }
            eprintln!("imu-calibrate: error: {e:#}");
            ExitCode::from(1)
        }
    }
}
