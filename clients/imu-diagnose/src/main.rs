//! `imu-diagnose`: the model workbench on the command line. Holds a calibration model against a
//! recording (is the residual consistent with the noise floor?), ranks the library effects that
//! would explain what is left, and runs the ladder that adds them one at a time, writing the
//! final calibration and a self-contained HTML report.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{ArgGroup, Args, Parser, Subcommand};
use imu_analysis::Source;
use imu_analysis::note::Notes;
use imu_analysis::reference::Reference;
use imu_analysis::render::html::{
    Section, diagnose_section, diagnose_section_with_base, inline_svgs, ladder_section, page,
    verdict_section,
};
use imu_analysis::workbench::{DiagnoseOptions, Ladder, LadderStep, TriadDiagnosis, Workbench};
use imu_analysis::{ImuSeries, segment::SegmentKind};
use imu_cli::finite_f64;
use imu_cli::progress::read_input;
use imu_model::{Calibration, EffectKind, InputFile, Triad, TriadModel};
use serde::Serialize;

mod text;
use text::{print_diagnosis, print_ladder};

/// Command line: `imu-diagnose RECORDING ...` diagnoses a model, `imu-diagnose ladder
/// RECORDING ...` runs the ladder.
#[derive(Debug, Parser)]
#[command(
    version,
    about,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    diagnose: DiagnoseArgs,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// From the base model, add the best claimed effect one at a time until accel and gyro are
    /// consistent with their noise floors; write the final calibration.
    Ladder(LadderArgs),
}

/// Arguments of the default (diagnose) command.
#[derive(Debug, Args)]
struct DiagnoseArgs {
    /// Recording: imud MCAP log (the raw stream is used), rosbag2 MCAP or directory, or text
    /// in any layout.
    #[arg(required = true)]
    recording: Option<PathBuf>,
    /// Further files of the same session (imud's rotated files): read with RECORDING as one
    /// recording, in time order, gaps reported. RECORDING may also be a session or rosbag2
    /// directory.
    #[arg(value_name = "MORE")]
    more: Vec<PathBuf>,
    #[command(flatten)]
    reference: RefArgs,
    /// Calibration-format file whose accel and gyro effects are the model under test (default:
    /// bias + scale + misalignment for both). Its `[accel.noise]`/`[gyro.noise]` tables (e.g.
    /// imu-noise's characterisation of a long static recording), if any, are the noise floor
    /// instead of the one measured from this recording's static segments.
    #[arg(long, value_name = "MODEL.toml")]
    model: Option<PathBuf>,
    /// Add an effect to the model: `gyro:g-sensitivity`, `accel:scale-nonlinearity`, or a bare
    /// effect id for every triad it applies to. Repeatable.
    #[arg(long = "add", value_name = "EFFECT")]
    add: Vec<String>,
    /// Write a self-contained HTML report here.
    #[arg(long, value_name = "REPORT.html")]
    report: Option<PathBuf>,
    /// Write the report's SVG charts into this directory (created if missing), numbered in
    /// the report's order.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Print one JSON document instead of tables.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    csv: imu_cli::CsvArgs,
}

/// Where the true input comes from, as for imu-calibrate: exactly one of a test plan or a
/// reference file.
#[derive(Debug, Args)]
#[group(skip)]
#[command(group(
    ArgGroup::new("truth-source")
        .required(true)
        .multiple(false)
        .args(["plan", "reference", "reference_free"])
))]
struct RefArgs {
    /// Test plan: the procedure and its nominal inputs, in order (format imud-plan/1; see
    /// config/plans/).
    #[arg(long, value_name = "PLAN.toml")]
    plan: Option<PathBuf>,
    /// The simulator's truth MCAP of this recording, or a time-stamped reference log (CSV,
    /// e.g. `t_s,wx_deg_s,wy_deg_s,wz_deg_s,fx_m_s2,fy_m_s2,fz_m_s2`) aligned in time by
    /// cross-correlation.
    #[arg(long, value_name = "TRUTH.mcap|LOG.csv")]
    reference: Option<PathBuf>,
    /// Clock offset of a reference log (log clock minus recording clock), s, instead of
    /// finding it.
    #[arg(
        long,
        value_name = "S",
        requires = "reference",
        allow_negative_numbers = true,
        value_parser = finite_f64
    )]
    reference_offset_s: Option<f64>,
    /// No reference: the unit was held still in many (30 or more) orientations and turned
    /// between them, as for `imu-calibrate --reference-free`. The accel is held against the
    /// gravity magnitude at each still pose (its axes define the frame), the gyro offsets (bias,
    /// g-sensitivity, temperature, warm-up) against the still poses with Earth's rate as their
    /// true rate; the gyro gains come from the moves between poses (the ladder's calibration
    /// fits them).
    #[arg(long)]
    reference_free: bool,
    /// Local gravity for --reference-free, m/s^2 (default: WGS-84 normal gravity at
    /// --latitude-deg, else 9.80665).
    #[arg(
        long,
        value_name = "M_S2",
        conflicts_with_all = ["plan", "reference"],
        value_parser = finite_f64
    )]
    gravity_m_s2: Option<f64>,
    /// Geodetic latitude for --reference-free, degrees: local gravity (unless given) and the
    /// vertical part of Earth's rate, the gyro's true rate at rest.
    #[arg(
        long,
        value_name = "DEG",
        conflicts_with_all = ["plan", "reference"],
        allow_negative_numbers = true,
        value_parser = finite_f64
    )]
    latitude_deg: Option<f64>,
}

impl RefArgs {
    /// The file that holds the reference (None: reference-free).
    fn path(&self) -> Option<&Path> {
        self.plan.as_deref().or(self.reference.as_deref())
    }

    /// Where the true input comes from, for the JSON output.
    fn describe(&self) -> String {
        self.path().map_or_else(
            || "reference-free (gravity magnitude, Earth rate)".to_string(),
            |p| p.display().to_string(),
        )
    }

    /// The workbench on `series`: against the reference, or reference-free.
    fn workbench<'a>(
        &self,
        series: &'a ImuSeries,
        reference: Option<&Reference>,
        opts: DiagnoseOptions,
    ) -> Result<Workbench<'a>> {
        Ok(match reference {
            Some(r) => Workbench::new(series, r, opts)?,
            None => Workbench::reference_free(series, self.gravity_m_s2, self.latitude_deg, opts)?,
        })
    }
}

/// Arguments of `imu-diagnose ladder`.
#[derive(Debug, Args)]
struct LadderArgs {
    /// Recording: imud MCAP log (the raw stream is used), rosbag2 MCAP or directory, or text
    /// in any layout.
    recording: PathBuf,
    /// Further files of the same session (imud's rotated files): read with RECORDING as one
    /// recording, in time order, gaps reported. RECORDING may also be a session or rosbag2
    /// directory.
    #[arg(value_name = "MORE")]
    more: Vec<PathBuf>,
    #[command(flatten)]
    reference: RefArgs,
    /// Calibration-format file whose accel and gyro effects are the first rung (default: bias +
    /// scale + misalignment for both). Its noise tables, if any, are the noise floor (see
    /// `--model` of the default command).
    #[arg(long, value_name = "MODEL.toml")]
    base: Option<PathBuf>,
    /// Write the final calibration here (loadable by imud).
    #[arg(short, long, value_name = "CALIBRATION.toml")]
    output: Option<PathBuf>,
    /// Write a self-contained HTML report here.
    #[arg(long, value_name = "REPORT.html")]
    report: Option<PathBuf>,
    /// Write the report's SVG charts into this directory (created if missing), numbered in
    /// the report's order.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Print one JSON document instead of tables.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    csv: imu_cli::CsvArgs,
}

/// One ranked candidate, flattened for JSON consumers.
#[derive(Debug, Serialize)]
struct CandidateRow {
    triad: Triad,
    effect: EffectKind,
    new_params: usize,
    f: f64,
    p_value: f64,
    delta_aic: f64,
    share_of_excess: Option<f64>,
    significant: bool,
    claimed: bool,
    /// The cross-validation of a candidate that won in-sample.
    #[serde(skip_serializing_if = "Option::is_none")]
    held_out: Option<imu_analysis::workbench::HeldOut>,
    /// `explanation` (the sentence) and `explanation_code`.
    #[serde(flatten)]
    explanation: imu_analysis::workbench::Explanation,
    model_change: String,
}

/// Each triad's verdict in words (JSON `verdict`) or its codes (JSON `verdict_codes`).
#[derive(Debug, Serialize)]
struct Verdicts<T> {
    accel: T,
    gyro: T,
}

impl Verdicts<String> {
    fn words(d: [&TriadDiagnosis; 2]) -> Self {
        Verdicts {
            accel: d[0].verdict.to_string(),
            gyro: d[1].verdict.to_string(),
        }
    }
}

impl Verdicts<Vec<&'static str>> {
    fn codes(d: [&TriadDiagnosis; 2]) -> Self {
        Verdicts {
            accel: d[0].verdict.codes(),
            gyro: d[1].verdict.codes(),
        }
    }
}

#[derive(Debug, Serialize)]
struct DiagnoseJson<'a> {
    recording: String,
    reference: String,
    model: Option<String>,
    /// Conventions and decisions (reference-free: gravity, Earth rate, gyro gains): `notes`
    /// (sentences) and `note_codes`.
    #[serde(flatten)]
    notes: &'a Notes,
    added: Vec<(Triad, EffectKind)>,
    verdict: Verdicts<String>,
    verdict_codes: Verdicts<Vec<&'static str>>,
    candidates: Vec<CandidateRow>,
    diagnoses: [&'a TriadDiagnosis; 2],
    report: Option<String>,
    /// Present when the recording was read without its footer: how far the read got.
    #[serde(skip_serializing_if = "Option::is_none")]
    input_unfinished: Option<serde_json::Value>,
    /// The files read (in time order), the IMU topic, the gaps between files.
    input: &'a imu_analysis::input::InputInfo,
}

#[derive(Debug, Serialize)]
struct LadderJson<'a> {
    recording: String,
    reference: String,
    base: Option<String>,
    /// Conventions and decisions behind the calibration: `notes` (sentences) and
    /// `note_codes`.
    #[serde(flatten)]
    notes: &'a Notes,
    output: Option<String>,
    report: Option<String>,
    added: Vec<(Triad, EffectKind)>,
    steps: &'a [LadderStep],
    verdict: Verdicts<String>,
    verdict_codes: Verdicts<Vec<&'static str>>,
    calibration: &'a Calibration,
    /// Present when the recording was read without its footer: how far the read got.
    #[serde(skip_serializing_if = "Option::is_none")]
    input_unfinished: Option<serde_json::Value>,
    /// The files read (in time order), the IMU topic, the gaps between files.
    input: &'a imu_analysis::input::InputInfo,
}

/// The model file's accel and gyro effects (a triad without effects gets the base model), and
/// the file itself (for its id and description).
fn load_model(path: Option<&Path>) -> Result<Calibration> {
    let mut cal = match path {
        Some(p) => {
            Calibration::load(p).with_context(|| format!("loading model {}", p.display()))?
        }
        None => Calibration::identity(),
    };
    cal.accel = if cal.accel.kinds().is_empty() {
        TriadModel::with_effects(&TriadModel::PAPER_BASE)
    } else {
        cal.accel.effects_only()
    };
    cal.gyro = if cal.gyro.kinds().is_empty() {
        TriadModel::with_effects(&TriadModel::PAPER_BASE)
    } else {
        cal.gyro.effects_only()
    };
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

/// The input's path and SHA-256.
fn input_file(path: &Path) -> Result<InputFile> {
    imu_analysis::provenance::input_file(path)
        .with_context(|| format!("reading {}", path.display()))
}

/// Reads the recording (`recording` and `more`, one session) and the reference.
fn read_inputs(
    (recording, more): (&Path, &[PathBuf]),
    r: &RefArgs,
    csv: &imu_cli::CsvArgs,
) -> Result<(ImuSeries, Option<Reference>)> {
    let paths: Vec<PathBuf> = std::iter::once(recording.to_path_buf())
        .chain(more.iter().cloned())
        .collect();
    let options = csv
        .input_options(&paths[..1], 0, Source::Raw)
        .map_err(imu_cli::UsageError)?;
    let series =
        read_input(&paths, &options).with_context(|| format!("reading {}", recording.display()))?;
    imu_cli::session::warn("imu-diagnose", &series);
    if series.is_empty() {
        bail!("{}: no samples", recording.display());
    }
    if r.reference_free {
        return Ok((series, None));
    }
    let reference = Reference::open(
        r.plan.as_deref(),
        r.reference.as_deref(),
        r.reference_offset_s,
        &series,
    )?
    .context("no reference: give --plan, --reference or --reference-free")?;
    Ok((series, Some(reference)))
}

fn effects_text(m: &[EffectKind]) -> String {
    m.iter().map(|k| k.id()).collect::<Vec<_>>().join(" + ")
}

/// The HTML report (`--report`) and its charts as SVG files `STEM-NN.svg` (`--plot`), if asked.
fn write_outputs(
    report: Option<&Path>,
    plot: Option<&Path>,
    (stem, title): (&str, &str),
    sections: impl FnOnce() -> Vec<Section>,
) -> Result<()> {
    if report.is_none() && plot.is_none() {
        return Ok(());
    }
    let html = page(title, &sections());
    if let Some(dir) = plot {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (i, svg) in inline_svgs(&html).into_iter().enumerate() {
            let path = dir.join(format!("{stem}-{:02}.svg", i + 1));
            std::fs::write(&path, format!("{svg}\n"))
                .with_context(|| format!("writing {}", path.display()))?;
        }
    }
    if let Some(path) = report {
        std::fs::write(path, html).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn candidate_rows(d: &TriadDiagnosis) -> impl Iterator<Item = CandidateRow> + '_ {
    d.candidates.iter().map(|c| CandidateRow {
        triad: c.triad,
        effect: c.effect,
        new_params: c.new_params,
        f: c.f,
        p_value: c.p_value,
        delta_aic: c.delta_aic,
        share_of_excess: c.share_of_excess,
        significant: c.significant,
        claimed: c.claimed,
        held_out: c.held_out.clone(),
        explanation: c.explanation.clone(),
        model_change: c.model_change.clone(),
    })
}

fn run_diagnose(a: &DiagnoseArgs) -> Result<()> {
    let Some(recording) = &a.recording else {
        bail!("a RECORDING and --plan, --reference or --reference-free are required");
    };
    let reference = &a.reference;
    let (model, added) = model_with_added(a)?;
    let (series, truth) = read_inputs((recording, &a.more), reference, &a.csv)?;
    let wb = reference
        .workbench(&series, truth.as_ref(), options(a.model.as_deref())?)
        .with_context(|| format!("segmenting {}", recording.display()))?;
    let accel = wb.diagnose(Triad::Accel, &model.accel)?;
    let gyro = wb.diagnose(Triad::Gyro, &model.gyro)?;

    write_outputs(
        a.report.as_deref(),
        a.plot.as_deref(),
        (
            "diagnose",
            &format!("imu-diagnose: {}", recording.display()),
        ),
        || {
            vec![
                verdict_section(&[&accel, &gyro]),
                diagnose_section(&accel, &wb.signal_values(Triad::Accel)),
                diagnose_section(&gyro, &wb.signal_values(Triad::Gyro)),
            ]
        },
    )?;

    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if a.json {
        let j = DiagnoseJson {
            recording: recording.display().to_string(),
            reference: reference.describe(),
            model: a.model.as_ref().map(|p| p.display().to_string()),
            notes: &wb.notes,
            added,
            verdict: Verdicts::words([&accel, &gyro]),
            verdict_codes: Verdicts::codes([&accel, &gyro]),
            candidates: candidate_rows(&accel)
                .chain(candidate_rows(&gyro))
                .collect(),
            diagnoses: [&accel, &gyro],
            report: a.report.as_ref().map(|p| p.display().to_string()),
            input_unfinished: series
                .unfinished
                .as_ref()
                .map(|u| imu_cli::unfinished::json(recording, u)),
            input: &series.input,
        };
        serde_json::to_writer_pretty(&mut out, &j)?;
        writeln!(out)?;
    } else {
        print_diagnose_text(&mut out, a, recording, &wb, &added, [&accel, &gyro])?;
    }
    out.flush()?;
    Ok(())
}

/// The model file's effects with the `--add` effects it lacks, and those added.
fn model_with_added(a: &DiagnoseArgs) -> Result<(Calibration, Vec<(Triad, EffectKind)>)> {
    let mut model = load_model(a.model.as_deref())?;
    let mut added = Vec::new();
    for spec in &a.add {
        for (t, k) in imu_cli::parse_effect(spec, "--add").map_err(imu_cli::UsageError)? {
            let m = if t == Triad::Gyro {
                &mut model.gyro
            } else {
                &mut model.accel
            };
            if !m.has(k) {
                m.add(k);
                added.push((t, k));
            }
        }
    }
    Ok((model, added))
}

/// `imu-diagnose` without `--json`: the segments, notes, added effects and both diagnoses.
fn print_diagnose_text(
    out: &mut impl Write,
    a: &DiagnoseArgs,
    recording: &Path,
    wb: &Workbench<'_>,
    added: &[(Triad, EffectKind)],
    [accel, gyro]: [&TriadDiagnosis; 2],
) -> Result<()> {
    let s = &wb.obs.segmentation;
    writeln!(
        out,
        "{}: {} static segments, {} rate plateaus",
        recording.display(),
        s.count(SegmentKind::Static),
        s.count(SegmentKind::Plateau)
    )?;
    for n in &wb.notes {
        writeln!(out, "note: {n}")?;
    }
    for (t, k) in added {
        writeln!(out, "added {t} {k}")?;
    }
    print_diagnosis(out, accel)?;
    print_diagnosis(out, gyro)?;
    if let Some(p) = &a.report {
        writeln!(out, "\nwrote {}", p.display())?;
    }
    Ok(())
}

fn run_ladder(a: &LadderArgs) -> Result<()> {
    let base = load_model(a.base.as_deref())?;
    let (series, truth) = read_inputs((&a.recording, &a.more), &a.reference, &a.csv)?;
    let wb = a
        .reference
        .workbench(&series, truth.as_ref(), options(a.base.as_deref())?)
        .with_context(|| format!("segmenting {}", a.recording.display()))?;
    let ladder = wb.ladder(&base)?;
    let added: Vec<(Triad, EffectKind)> = ladder.steps.iter().filter_map(|s| s.added).collect();
    let Ladder {
        steps,
        base_diagnoses,
        final_diagnoses,
        mut calibration,
        notes,
    } = ladder;
    stamp_ladder_calibration(a, &mut calibration, &final_diagnoses, &added)?;
    if let Some(path) = &a.output {
        calibration
            .save(path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    write_outputs(
        a.report.as_deref(),
        a.plot.as_deref(),
        (
            "ladder",
            &format!("imu-diagnose ladder: {}", a.recording.display()),
        ),
        || {
            let [accel, gyro] = &final_diagnoses;
            vec![
                verdict_section(&[accel, gyro]),
                ladder_section(&steps),
                diagnose_section_with_base(
                    accel,
                    Some(&base_diagnoses[0]),
                    &wb.signal_values(Triad::Accel),
                ),
                diagnose_section_with_base(
                    gyro,
                    Some(&base_diagnoses[1]),
                    &wb.signal_values(Triad::Gyro),
                ),
            ]
        },
    )?;

    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if a.json {
        let j = LadderJson {
            recording: a.recording.display().to_string(),
            reference: a.reference.describe(),
            base: a.base.as_ref().map(|p| p.display().to_string()),
            notes: &notes,
            output: a.output.as_ref().map(|p| p.display().to_string()),
            report: a.report.as_ref().map(|p| p.display().to_string()),
            added,
            steps: &steps,
            verdict: Verdicts::words([&final_diagnoses[0], &final_diagnoses[1]]),
            verdict_codes: Verdicts::codes([&final_diagnoses[0], &final_diagnoses[1]]),
            calibration: &calibration,
            input_unfinished: series
                .unfinished
                .as_ref()
                .map(|u| imu_cli::unfinished::json(&a.recording, u)),
            input: &series.input,
        };
        serde_json::to_writer_pretty(&mut out, &j)?;
        writeln!(out)?;
    } else {
        print_ladder_text(&mut out, a, &steps, &final_diagnoses, &notes)?;
    }
    out.flush()?;
    Ok(())
}

/// The ladder's calibration: its id (without a base model), description and provenance (the
/// inputs with their hashes, what was added and the final verdicts).
fn stamp_ladder_calibration(
    a: &LadderArgs,
    cal: &mut Calibration,
    final_diagnoses: &[TriadDiagnosis; 2],
    added: &[(Triad, EffectKind)],
) -> Result<()> {
    if a.base.is_none() {
        cal.id = Some("imu-diagnose-ladder".into());
    }
    cal.description = Some(format!(
        "accel {}; gyro {} (model workbench ladder)",
        effects_text(&final_diagnoses[0].effects),
        effects_text(&final_diagnoses[1].effects)
    ));
    cal.provenance.created = Some(imu_analysis::provenance::now_rfc3339());
    cal.provenance.tool = Some(format!("imu-diagnose {}", env!("CARGO_PKG_VERSION")));
    cal.provenance.procedure = Some(if a.reference.reference_free {
        "imu-diagnose ladder --reference-free".into()
    } else {
        "imu-diagnose ladder".into()
    });
    let mut inputs = vec![input_file(&a.recording)?];
    if let Some(r) = a.reference.path() {
        inputs.push(input_file(r)?);
    }
    if let Some(b) = &a.base {
        inputs.push(input_file(b)?);
    }
    cal.provenance.inputs = inputs;
    cal.provenance.notes = Some(format!(
        "added: {}; accel: {} gyro: {}",
        if added.is_empty() {
            "nothing".to_string()
        } else {
            added
                .iter()
                .map(|(t, k)| format!("{t} {k}"))
                .collect::<Vec<_>>()
                .join(", ")
        },
        final_diagnoses[0].verdict,
        final_diagnoses[1].verdict
    ));
    Ok(())
}

/// `imu-diagnose ladder` without `--json`: the steps, the final verdicts and the notes.
fn print_ladder_text(
    out: &mut impl Write,
    a: &LadderArgs,
    steps: &[LadderStep],
    final_diagnoses: &[TriadDiagnosis; 2],
    notes: &Notes,
) -> Result<()> {
    print_ladder(out, steps)?;
    writeln!(out)?;
    for d in final_diagnoses {
        writeln!(out, "{}", d.verdict)?;
    }
    for n in notes {
        writeln!(out, "note: {n}")?;
    }
    if let Some(p) = &a.output {
        writeln!(out, "\nwrote {}", p.display())?;
    }
    if let Some(p) = &a.report {
        writeln!(out, "wrote {}", p.display())?;
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    imu_cli::main("imu-diagnose", |cli: Cli| match &cli.command {
        Some(Command::Ladder(a)) => run_ladder(a),
        None => run_diagnose(&cli.diagnose),
    })
}
