//! `imu-calibrate`: fit accel and gyro error models (bias, scale, misalignment, optionally
//! g-sensitivity and more) from the static positions and rate plateaus of one or more
//! recordings, each against a reference giving its true input (a test plan, a time-stamped
//! reference log, or the simulator's truth), or from many hand-held still poses and the moves
//! between them without any reference (`--reference-free`), and write an imud calibration file.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{ArgGroup, ArgMatches, FromArgMatches, Parser};
use imu_analysis::Source;
use imu_analysis::calibrate::reference_free::{
    ReferenceFreeFit, ReferenceFreeOptions, TriadFit, calibrate_reference_free, in_accel_frame,
};
use imu_analysis::calibrate::{
    CalibrateOptions, CalibrationFit, FitResult, bias_drift_from_noise, calibrate_recordings,
};
use imu_analysis::reference::Reference;
use imu_analysis::segment::SegmentKind;
use imu_cli::finite_f64;
use imu_cli::progress::read_any;
use imu_model::{Calibration, InputFile, Triad, TriadModel};
use serde::Serialize;

/// Command line. A procedure (the `procedure` group) says where the true input comes from: one
/// `--plan` or `--reference` per recording, or `--reference-free`.
#[derive(Debug, Parser)]
#[command(version, about)]
#[command(group(ArgGroup::new("procedure").required(true).multiple(true)))]
struct Cli {
    /// Recordings: imud MCAP logs (the raw stream is fitted), rosbag2 MCAP or CSV. Several
    /// recordings of one unit (e.g. an index-table run and a rate-table run, each in its own
    /// file) are fitted together into one calibration, each against its own reference.
    #[arg(required = true, value_name = "RECORDING")]
    recordings: Vec<PathBuf>,
    /// Test plan: the procedure and its nominal inputs, in order (format imud-plan/1; see
    /// config/plans/). Its steps are matched to the recording's segments and checked. With
    /// several recordings give one --plan or --reference per recording: they go to the
    /// recordings in the order given on the command line.
    #[arg(long, value_name = "PLAN.toml", group = "procedure")]
    plan: Vec<PathBuf>,
    /// Reference for the true input: the simulator's truth MCAP of this recording, or a
    /// time-stamped reference log (CSV with a header such as
    /// `t_s,wx_deg_s,wy_deg_s,wz_deg_s,fx_m_s2,fy_m_s2,fz_m_s2`, or a rate table's
    /// `t_s,rate_deg_s` with a `# table-axis = +z` line), aligned in time with the recording by
    /// cross-correlation. Told apart by content (MCAP magic bytes). One per recording, in order,
    /// like --plan.
    #[arg(long, value_name = "TRUTH.mcap|LOG.csv", group = "procedure")]
    reference: Vec<PathBuf>,
    /// Clock offset of a reference log (log clock minus recording clock, seconds from the
    /// recording's first sample) instead of finding it by cross-correlation. It applies to the
    /// --reference given just before it (with one recording and one --reference, anywhere).
    #[arg(long, value_name = "S", allow_negative_numbers = true, value_parser = finite_f64)]
    reference_offset_s: Vec<f64>,
    /// No reference: the unit was held still in many (30 or more) orientations and turned
    /// between them. The accelerometer is fitted to the gravity magnitude (its axes define the
    /// body frame), the gyro bias to the still poses, the gyro gains to the integrated moves.
    /// One recording only: the poses and the moves between them must come from one power-on.
    #[arg(long, group = "procedure", conflicts_with_all = ["plan", "reference"])]
    reference_free: bool,
    /// Local gravity for --reference-free, m/s^2 (default: WGS-84 normal gravity at
    /// --latitude-deg, else 9.80665).
    #[arg(long, value_name = "M_S2", value_parser = finite_f64)]
    gravity_m_s2: Option<f64>,
    /// Geodetic latitude for --reference-free, degrees: local gravity (unless given) and the
    /// vertical part of Earth's rate, removed from the gyro bias.
    #[arg(long, value_name = "DEG", allow_negative_numbers = true, value_parser = finite_f64)]
    latitude_deg: Option<f64>,
    /// Accel turn-on to turn-on bias repeatability, m/s^2 (1 sigma; one value for all axes or
    /// X,Y,Z): each recording's bias may differ from the fitted one (then the mean over the
    /// power-ons) by this much. Without it the bias is taken as common to all recordings.
    #[arg(
        long,
        value_name = "S|X,Y,Z",
        value_delimiter = ',',
        conflicts_with = "reference_free",
        value_parser = finite_f64
    )]
    accel_turn_on_bias_m_s2: Vec<f64>,
    /// Gyro turn-on to turn-on bias repeatability, rad/s (1 sigma; one value or X,Y,Z), like
    /// --accel-turn-on-bias-m-s2.
    #[arg(
        long,
        value_name = "S|X,Y,Z",
        value_delimiter = ',',
        conflicts_with = "reference_free",
        value_parser = finite_f64
    )]
    gyro_turn_on_bias_rad_s: Vec<f64>,
    /// Calibration-format file whose accel and gyro effects say what to fit (values are the
    /// starting point; default: bias + scale + misalignment for both). Its `[accel.noise]` and
    /// `[gyro.noise]` (e.g. from imu-noise) widen the bias standard errors by the bias wander.
    #[arg(long, value_name = "MODEL.toml")]
    model: Option<PathBuf>,
    /// Also fit this effect of the library: `accel:scale-nonlinearity`, `gyro:g-sensitivity`,
    /// or a bare effect id for accel and gyro wherever it applies (added to the --model file's
    /// effects, or to bias + scale + misalignment). Repeatable.
    #[arg(long = "add", value_name = "EFFECT")]
    add: Vec<String>,
    /// Truth model to compare the fit with (prints fitted vs true in standard errors).
    #[arg(long, value_name = "TRUTH_MODEL.toml")]
    truth: Option<PathBuf>,
    /// Write the calibration here.
    #[arg(short, long, value_name = "CALIBRATION.toml")]
    output: Option<PathBuf>,
    /// Print JSON instead of tables.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    csv: imu_cli::CsvArgs,
}

/// Where one recording's true input comes from, as given on the command line.
#[derive(Clone, Debug, PartialEq)]
enum ReferenceArg {
    /// `--plan FILE`.
    Plan(PathBuf),
    /// `--reference FILE`, with the `--reference-offset-s` that applies to it.
    Reference {
        path: PathBuf,
        offset_s: Option<f64>,
    },
}

impl ReferenceArg {
    fn path(&self) -> &Path {
        match self {
            ReferenceArg::Plan(p) | ReferenceArg::Reference { path: p, .. } => p,
        }
    }

    /// `--plan FILE` or `--reference FILE`, for messages.
    fn flag(&self) -> String {
        match self {
            ReferenceArg::Plan(p) => format!("--plan {}", p.display()),
            ReferenceArg::Reference { path, .. } => format!("--reference {}", path.display()),
        }
    }
}

/// The reference of each recording: the `--plan` and `--reference` arguments in command-line
/// order, the k-th for the k-th recording; each `--reference-offset-s` goes with the
/// `--reference` just before it (or with the only one).
fn reference_args(cli: &Cli, matches: &ArgMatches) -> Result<Vec<ReferenceArg>> {
    let indices = |id: &str| -> Vec<usize> {
        matches
            .indices_of(id)
            .map(Iterator::collect)
            .unwrap_or_default()
    };
    let mut given: Vec<(usize, ReferenceArg)> = indices("plan")
        .into_iter()
        .zip(&cli.plan)
        .map(|(i, p)| (i, ReferenceArg::Plan(p.clone())))
        .chain(
            indices("reference")
                .into_iter()
                .zip(&cli.reference)
                .map(|(i, p)| {
                    (
                        i,
                        ReferenceArg::Reference {
                            path: p.clone(),
                            offset_s: None,
                        },
                    )
                }),
        )
        .collect();
    given.sort_by_key(|(i, _)| *i);
    let offsets: Vec<(usize, f64)> = indices("reference_offset_s")
        .into_iter()
        .zip(cli.reference_offset_s.iter().copied())
        .collect();
    // One recording, one reference log, one offset: the order does not matter (as before
    // several recordings could be given).
    let only_reference = given.len() == 1 && offsets.len() == 1;
    for (at, offset_s) in offsets {
        let target = if only_reference {
            given
                .iter()
                .position(|(_, r)| matches!(r, ReferenceArg::Reference { .. }))
        } else {
            given.iter().rposition(|(i, _)| *i < at)
        };
        match target.map(|k| &mut given[k].1) {
            Some(ReferenceArg::Reference { offset_s: o, path }) => {
                if o.is_some() {
                    bail!(
                        "--reference-offset-s {offset_s} is the second offset for --reference {}: \
                         give one per reference log, right after it",
                        path.display()
                    );
                }
                *o = Some(offset_s);
            }
            Some(ReferenceArg::Plan(p)) => bail!(
                "--reference-offset-s {offset_s} follows --plan {}: a clock offset applies to the \
                 reference log (--reference LOG.csv) given just before it",
                p.display()
            ),
            None if cli.reference.is_empty() => {
                bail!("--reference-offset-s applies to a reference log (--reference LOG.csv)")
            }
            None => bail!(
                "--reference-offset-s {offset_s} comes before any --reference: with several \
                 references give each offset right after the reference log it applies to"
            ),
        }
    }
    let refs: Vec<ReferenceArg> = given.into_iter().map(|(_, r)| r).collect();
    let (n_rec, n_ref) = (cli.recordings.len(), refs.len());
    let listed = || {
        refs.iter()
            .map(ReferenceArg::flag)
            .collect::<Vec<_>>()
            .join(", ")
    };
    const HOW: &str = "give one --plan or --reference per recording; they go to the recordings \
                       in the order given";
    if n_ref < n_rec {
        bail!(
            "recording {} ({}) has no reference: {n_rec} recordings but {n_ref} reference{} ({}); \
             {HOW}",
            n_ref + 1,
            cli.recordings[n_ref].display(),
            if n_ref == 1 { "" } else { "s" },
            listed()
        );
    }
    if n_ref > n_rec {
        bail!(
            "{n_ref} references ({}) for {n_rec} recording{}: {HOW}",
            listed(),
            if n_rec == 1 { "" } else { "s" }
        );
    }
    Ok(refs)
}

/// A per-axis value given as one number for all axes or as X,Y,Z; None when not given.
fn per_axis(values: &[f64], flag: &str) -> Result<Option<[f64; 3]>> {
    let v = match values {
        [] => return Ok(None),
        [s] => [*s; 3],
        [x, y, z] => [*x, *y, *z],
        _ => bail!(
            "{flag} takes one value or three (X,Y,Z), got {}",
            values.len()
        ),
    };
    if v.iter().any(|x| !x.is_finite() || *x < 0.0) {
        bail!("{flag}: {v:?} must be standard deviations (0 or more)");
    }
    Ok(Some(v))
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
    /// Recordings read without their footer (killed writer): how far each read got.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    inputs_unfinished: Vec<serde_json::Value>,
}

/// One recording of a fit and what it contributed.
#[derive(Debug, Serialize)]
struct JsonRecording {
    recording: String,
    reference: String,
    reference_description: String,
    static_segments: usize,
    rate_plateaus: usize,
    /// Detected segments a plan's skip step left out.
    skipped_segments: usize,
    accel_points: usize,
    gyro_points: usize,
}

#[derive(Debug, Serialize)]
struct JsonOut<'a> {
    /// The recording, reference and its description when there is one recording (as before
    /// several could be given); `recordings` lists them all.
    #[serde(skip_serializing_if = "Option::is_none")]
    recording: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    reference: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    reference_description: Option<String>,
    recordings: Vec<JsonRecording>,
    output: Option<String>,
    fit: &'a CalibrationFit,
    truth_comparison: Option<Vec<TruthRow>>,
    /// Recordings read without their footer (killed writer): how far each read got.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    inputs_unfinished: Vec<serde_json::Value>,
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

/// Fit options from the model file and `--add`: the accel and gyro effects, and, from the
/// file's noise tables (a noise characterisation such as imu-noise's), the bias wander over a
/// recording of `duration_s` that no residual can show and the covariance of the segment means.
fn options(cli: &Cli, duration_s: f64) -> Result<CalibrateOptions> {
    let model = cli.model.as_deref();
    let mut opts = CalibrateOptions::default();
    if let Some(path) = model {
        let m =
            Calibration::load(path).with_context(|| format!("loading model {}", path.display()))?;
        if !m.accel.kinds().is_empty() {
            opts.accel = m.accel.effects_only();
        }
        if !m.gyro.kinds().is_empty() {
            opts.gyro = m.gyro.effects_only();
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
    for spec in &cli.add {
        for (t, k) in imu_cli::parse_effect(spec, "--add").map_err(imu_cli::UsageError)? {
            let m = if t == Triad::Gyro {
                &mut opts.gyro
            } else {
                &mut opts.accel
            };
            if !m.has(k) {
                m.add(k);
            }
        }
    }
    Ok(opts)
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

/// The parameter table: name, value, standard error (`missing` where there is none), unit.
fn print_params(
    out: &mut impl Write,
    names: &[String],
    params: &[f64],
    std_errors: &[Option<f64>],
    units: &[String],
    missing: &str,
) -> std::io::Result<()> {
    writeln!(
        out,
        "  {:<36} {:>13} {:>11}  unit",
        "parameter", "value", "std error"
    )?;
    for i in 0..params.len() {
        let se = std_errors[i].map_or_else(|| missing.to_string(), |s| format!("{s:.3e}"));
        writeln!(
            out,
            "  {:<36} {:>13.5e} {:>11}  {}",
            names[i], params[i], se, units[i]
        )?;
    }
    Ok(())
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
    print_params(
        out,
        &fit.names,
        &fit.params,
        &fit.std_errors,
        &fit.units,
        "not fitted",
    )?;
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
    let several = fit.recordings.len() > 1;
    for (k, r) in fit.recordings.iter().enumerate() {
        let s = &r.segmentation;
        let indent = if several {
            writeln!(out, "recording {}: {}", k + 1, r.origin)?;
            writeln!(out, "  reference: {}", r.reference)?;
            "  "
        } else {
            ""
        };
        writeln!(
            out,
            "{indent}segments: {} static, {} rate plateaus (window {} samples; thresholds: accel std {:.3e} m/s^2, gyro std {:.3e} rad/s)",
            s.count(SegmentKind::Static),
            s.count(SegmentKind::Plateau),
            s.window_samples,
            s.accel_std_threshold_m_s2,
            s.gyro_std_threshold_rad_s
        )?;
        if several {
            writeln!(
                out,
                "{indent}points: {} accel, {} gyro",
                r.accel_points.len(),
                r.gyro_points.len()
            )?;
        }
    }
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
    print_params(
        out,
        &fit.names,
        &fit.params,
        &fit.std_errors,
        &fit.units,
        "held",
    )?;
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

/// Reads recording `k` (raw stream) and checks it has samples.
fn read_recording(cli: &Cli, k: usize) -> Result<imu_analysis::ImuSeries> {
    let path = &cli.recordings[k];
    let options = cli
        .csv
        .options_for(&cli.recordings, k)
        .map_err(imu_cli::UsageError)?;
    let series = read_any(path, Source::Raw, &options)
        .with_context(|| format!("reading {}", path.display()))?;
    imu_cli::unfinished::warn("imu-calibrate", path, series.unfinished.as_ref());
    if series.is_empty() {
        bail!("{}: no samples", path.display());
    }
    Ok(series)
}

/// The reference one recording was given, opened against its series.
fn open_reference(r: &ReferenceArg, series: &imu_analysis::ImuSeries) -> Result<Reference> {
    let opened = match r {
        ReferenceArg::Plan(p) => Reference::open(Some(p), None, None, series)?,
        ReferenceArg::Reference { path, offset_s } => {
            Reference::open(None, Some(path), *offset_s, series)?
        }
    };
    opened.with_context(|| format!("{}: no reference", r.flag()))
}

fn run(cli: &Cli, matches: &ArgMatches) -> Result<()> {
    // (clap's `requires` counts a flag's implicit `false` as present, so this is checked here.)
    if !cli.reference_free && (cli.gravity_m_s2.is_some() || cli.latitude_deg.is_some()) {
        bail!("--gravity-m-s2 and --latitude-deg apply to --reference-free only");
    }
    if cli.reference_free {
        let [recording] = cli.recordings.as_slice() else {
            bail!(
                "--reference-free takes one recording, got {}: the still poses and the moves \
                 between them must come from one power-on; record every pose in one file",
                cli.recordings.len()
            );
        };
        if !cli.reference_offset_s.is_empty() {
            bail!("--reference-offset-s applies to a reference log (--reference LOG.csv)");
        }
        let hashing = hash_in_background(
            std::iter::once(recording.clone())
                .chain(cli.csv.gyro_csv.iter().cloned())
                .collect(),
        );
        let series = read_recording(cli, 0)?;
        return run_reference_free(cli, recording, &series, hashing);
    }
    let refs = reference_args(cli, matches)?;
    let turn_on = (
        per_axis(&cli.accel_turn_on_bias_m_s2, "--accel-turn-on-bias-m-s2")?,
        per_axis(&cli.gyro_turn_on_bias_rad_s, "--gyro-turn-on-bias-rad-s")?,
    );
    let inputs = cli
        .recordings
        .iter()
        .zip(&refs)
        .flat_map(|(rec, r)| [rec.clone(), r.path().to_path_buf()])
        .chain(cli.csv.gyro_csv.iter().cloned())
        .collect();
    let hashing = hash_in_background(inputs);
    let mut loaded = Vec::with_capacity(refs.len());
    for (k, r) in refs.iter().enumerate() {
        let series = read_recording(cli, k)?;
        let reference = open_reference(r, &series)?;
        loaded.push((series, reference));
    }
    run_reference(cli, &loaded, &refs, turn_on, hashing)
}

fn run_reference_free(
    cli: &Cli,
    recording: &Path,
    series: &imu_analysis::ImuSeries,
    hashing: Hashing,
) -> Result<()> {
    let duration_s = series.t_s[series.len() - 1] - series.t_s[0];
    let base = options(cli, duration_s)?;
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
        .with_context(|| format!("calibrating {} (reference-free)", recording.display()))?;
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
            recording: recording.display().to_string(),
            procedure: "reference-free",
            output: cli.output.as_ref().map(|p| p.display().to_string()),
            fit: &fit,
            truth_comparison: truth_rows,
            inputs_unfinished: series
                .unfinished
                .iter()
                .map(|u| imu_cli::unfinished::json(recording, u))
                .collect(),
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
    loaded: &[(imu_analysis::ImuSeries, Reference)],
    refs: &[ReferenceArg],
    (accel_turn_on_bias_m_s2, gyro_turn_on_bias_rad_s): (Option<[f64; 3]>, Option<[f64; 3]>),
    hashing: Hashing,
) -> Result<()> {
    let duration_s = loaded
        .iter()
        .map(|(s, _)| s.t_s[s.len() - 1] - s.t_s[0])
        .fold(0.0, f64::max);
    let mut opts = options(cli, duration_s)?;
    opts.accel_turn_on_bias_m_s2 = accel_turn_on_bias_m_s2;
    opts.gyro_turn_on_bias_rad_s = gyro_turn_on_bias_rad_s;
    let pairs: Vec<_> = loaded.iter().map(|(s, r)| (s, r)).collect();
    let names = cli
        .recordings
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ");
    let mut fit =
        calibrate_recordings(&pairs, &opts).with_context(|| format!("calibrating {names}"))?;

    let several = loaded.len() > 1;
    let (n_static, n_plateau) = (
        fit.count(SegmentKind::Static),
        fit.count(SegmentKind::Plateau),
    );
    let cal = &mut fit.calibration;
    cal.description = Some(format!(
        "accel and gyro fitted from {n_static} static segments and {n_plateau} rate plateaus{}",
        if several {
            format!(" of {} recordings", loaded.len())
        } else {
            String::new()
        }
    ));
    let described = if several {
        loaded
            .iter()
            .enumerate()
            .map(|(k, (_, r))| format!("recording {}: {}", k + 1, r.describe()))
            .collect::<Vec<_>>()
            .join("; ")
    } else {
        loaded[0].1.describe()
    };
    cal.provenance.procedure = Some(format!(
        "static/plateau segmentation; weighted Levenberg-Marquardt fit of segment means to the \
         true input from the {described} (Aslan & Saranli 3.1.2, 3.2.2, 3.2.3)"
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
        let recordings: Vec<JsonRecording> = fit
            .recordings
            .iter()
            .zip(&cli.recordings)
            .zip(refs)
            .map(|((r, path), arg)| JsonRecording {
                recording: path.display().to_string(),
                reference: arg.path().display().to_string(),
                reference_description: r.reference.clone(),
                static_segments: r.segmentation.count(SegmentKind::Static),
                rate_plateaus: r.segmentation.count(SegmentKind::Plateau),
                skipped_segments: r.segmentation.skipped.len(),
                accel_points: r.accel_points.len(),
                gyro_points: r.gyro_points.len(),
            })
            .collect();
        let (recording, reference, reference_description) = match recordings.as_slice() {
            [r] => (
                Some(r.recording.clone()),
                Some(r.reference.clone()),
                Some(r.reference_description.clone()),
            ),
            _ => (None, None, None),
        };
        let j = JsonOut {
            recording,
            reference,
            reference_description,
            recordings,
            output: cli.output.as_ref().map(|p| p.display().to_string()),
            fit: &fit,
            truth_comparison: truth_rows,
            inputs_unfinished: loaded
                .iter()
                .zip(&cli.recordings)
                .filter_map(|((s, _), path)| {
                    s.unfinished
                        .as_ref()
                        .map(|u| imu_cli::unfinished::json(path, u))
                })
                .collect(),
        };
        serde_json::to_writer_pretty(&mut out, &j)?;
        writeln!(out)?;
    } else {
        if !several {
            writeln!(out, "reference: {}", loaded[0].1.describe())?;
        }
        print_tables(&mut out, &fit, truth_rows.as_deref())?;
        if let Some(p) = &cli.output {
            writeln!(out, "\nwrote {}", p.display())?;
        }
    }
    out.flush()?;
    Ok(())
}

fn main() -> std::process::ExitCode {
    imu_cli::main_with_matches::<Cli, ()>("imu-calibrate", |matches| {
        let cli = Cli::from_arg_matches(matches).map_err(imu_cli::UsageError::from_clap)?;
        run(&cli, matches)
    })
}
