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
use imu_analysis::calibrate::{CalibrateOptions, CalibrationFit, FitResult, calibrate_recordings};
use imu_analysis::reference::Reference;
use imu_analysis::segment::SegmentKind;
use imu_cli::finite_f64;
use imu_cli::progress::read_input;
use imu_model::{Calibration, InputFile, Triad, TriadModel};
use imu_rec::mcap_read::has_mcap_magic;
use serde::Serialize;

mod print;
mod procedures;

use print::*;
use procedures::*;

/// Command line. A procedure (the `procedure` group) says where the true input comes from: one
/// `--plan` or `--reference` per recording, or `--reference-free`.
#[derive(Debug, Parser)]
#[command(version, about)]
#[command(group(ArgGroup::new("procedure").required(true).multiple(true)))]
struct Cli {
    /// Recordings: imud MCAP logs (the raw stream is fitted), rosbag2 MCAP or directories,
    /// text in any layout. imud's rotated files of one session are one recording, given as
    /// their directory or as files in any order: files told by their metadata to chain (same
    /// recorder prefix and device, consecutive file indices, each starting after the one before
    /// ends) are joined in time order, gaps reported. Other files are separate recordings of
    /// one unit (e.g. an index-table run and a rate-table run), fitted together into one
    /// calibration, each against its own reference; JSON `recordings[].input.files` lists the
    /// files of each.
    #[arg(required = true, value_name = "RECORDING")]
    recordings: Vec<PathBuf>,
    /// Test plan: the procedure and its nominal inputs, in order (format imud-plan/1; see
    /// config/plans/). Its steps are matched to the recording's segments and checked. With
    /// several recordings give one --plan or --reference per recording: they go to the
    /// recordings in the order given on the command line (a session of several files counts
    /// once, at its first file).
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
    let mut given: Vec<(usize, ReferenceArg)> = arg_indices(matches, "plan")
        .into_iter()
        .zip(&cli.plan)
        .map(|(i, p)| (i, ReferenceArg::Plan(p.clone())))
        .chain(
            arg_indices(matches, "reference")
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
    let offsets: Vec<(usize, f64)> = arg_indices(matches, "reference_offset_s")
        .into_iter()
        .zip(cli.reference_offset_s.iter().copied())
        .collect();
    attach_offsets(cli, &mut given, offsets)?;
    Ok(given.into_iter().map(|(_, r)| r).collect())
}

/// The command-line positions of argument `id`'s values.
fn arg_indices(matches: &ArgMatches, id: &str) -> Vec<usize> {
    matches
        .indices_of(id)
        .map(Iterator::collect)
        .unwrap_or_default()
}

/// Gives each `--reference-offset-s` (at its command-line position) to the reference log just
/// before it in `given` (references with their positions, in order), or to the only one.
fn attach_offsets(
    cli: &Cli,
    given: &mut [(usize, ReferenceArg)],
    offsets: Vec<(usize, f64)>,
) -> Result<()> {
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
    Ok(())
}

/// How many recordings `paths` can be, known before reading them: only imud MCAP files can be
/// joined into sessions (a directory is one recording already, text, a missing path and a
/// rosbag2 file never join), so at least the others plus one, at most one per path.
fn recording_count_bounds(paths: &[PathBuf]) -> (usize, usize) {
    let joinable = paths
        .iter()
        .filter(|p| p.is_file() && has_mcap_magic(p).unwrap_or(false))
        .count();
    (
        paths.len() - joinable + usize::from(joinable > 0),
        paths.len(),
    )
}

/// The reference count checked before reading: when it cannot match however the paths group,
/// the error is the one [`check_one_per_recording`] gives for each path as a recording.
fn precheck_reference_count(cli: &Cli, refs: &[ReferenceArg]) -> Result<()> {
    let (least, most) = recording_count_bounds(&cli.recordings);
    if (least..=most).contains(&refs.len()) {
        return Ok(());
    }
    let names: Vec<String> = cli
        .recordings
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    check_one_per_recording(&names, refs)
}

/// One reference per recording (named by `recordings`), or an error naming the first
/// recording without one.
fn check_one_per_recording(recordings: &[String], refs: &[ReferenceArg]) -> Result<()> {
    let (n_rec, n_ref) = (recordings.len(), refs.len());
    let listed = || {
        refs.iter()
            .map(ReferenceArg::flag)
            .collect::<Vec<_>>()
            .join(", ")
    };
    const HOW: &str = "give one --plan or --reference per recording; they go to the recordings \
                       in the order given (the rotated files of one imud session are one \
                       recording)";
    if n_ref < n_rec {
        bail!(
            "recording {} ({}) has no reference: {n_rec} recordings but {n_ref} reference{} ({}); \
             {HOW}",
            n_ref + 1,
            recordings[n_ref],
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
    Ok(())
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
    /// The files read (in time order), the IMU topic, the gaps between files.
    input: &'a imu_analysis::input::InputInfo,
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
    /// The files read (in time order), the IMU topic, the gaps between files.
    input: imu_analysis::input::InputInfo,
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

/// Starts hashing `paths` in the background (a directory: the files it stands for).
fn hash_in_background(paths: Vec<PathBuf>) -> Hashing {
    std::thread::spawn(move || {
        imu_analysis::input::session_files(&paths)?
            .iter()
            .map(|p| input_file(p))
            .collect()
    })
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
    let mut opts = match cli.model.as_deref() {
        Some(path) => CalibrateOptions::from_model(
            &Calibration::load(path)
                .with_context(|| format!("loading model {}", path.display()))?,
            duration_s,
        ),
        None => CalibrateOptions::default(),
    };
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

/// Provenance shared by both procedures: when, which tool, which inputs, the temperatures the
/// data covered, and the notes with the parameters that were held.
fn stamp(
    cal: &mut Calibration,
    (inputs, series): (Hashing, &[&imu_analysis::ImuSeries]),
    notes: &imu_analysis::note::Notes,
    held: Vec<String>,
) -> Result<()> {
    cal.provenance.temperature_range_c = series
        .iter()
        .flat_map(|s| s.temp.iter().map(|&(_, c)| c))
        .filter(|c| c.is_finite())
        .fold(None, |r: Option<[f64; 2]>, c| {
            Some(r.map_or([c, c], |[lo, hi]| [lo.min(c), hi.max(c)]))
        });
    cal.provenance.created = Some(imu_analysis::provenance::now_rfc3339());
    cal.provenance.tool = Some(format!("imu-calibrate {}", env!("CARGO_PKG_VERSION")));
    cal.provenance.inputs = inputs
        .join()
        .map_err(|_| anyhow::anyhow!("the input hashing thread panicked"))??;
    if !notes.is_empty() || !held.is_empty() {
        let mut text = notes.sentences().join("; ");
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

/// One recording: a file, or the files of one imud session joined.
pub(crate) struct Recording {
    /// Its paths as given, `a + b` for a session of several.
    name: String,
    series: imu_analysis::ImuSeries,
}

/// Reads every path (raw stream) and groups them into recordings
/// ([`imu_analysis::input::group_sessions`]), each checked to have samples.
fn read_recordings(cli: &Cli) -> Result<Vec<Recording>> {
    let mut parts = Vec::with_capacity(cli.recordings.len());
    for (k, path) in cli.recordings.iter().enumerate() {
        let options = cli
            .csv
            .input_options(&cli.recordings, k, Source::Raw)
            .map_err(imu_cli::UsageError)?;
        let series = read_input(std::slice::from_ref(path), &options)
            .with_context(|| format!("reading {}", path.display()))?;
        parts.push(series);
    }
    let groups = imu_analysis::input::group_sessions(parts).context("joining the recordings")?;
    groups
        .into_iter()
        .map(|(paths, series)| {
            let name = paths
                .iter()
                .map(|&k| cli.recordings[k].display().to_string())
                .collect::<Vec<_>>()
                .join(" + ");
            imu_cli::session::warn("imu-calibrate", &series);
            if series.is_empty() {
                bail!("{name}: no samples");
            }
            Ok(Recording { name, series })
        })
        .collect()
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

/// `--reference-free`: one recording (a file or the files of one imud session).
fn reference_free(cli: &Cli) -> Result<()> {
    if !cli.reference_offset_s.is_empty() {
        bail!("--reference-offset-s applies to a reference log (--reference LOG.csv)");
    }
    let (least, _) = recording_count_bounds(&cli.recordings);
    if least > 1 {
        bail!(
            "--reference-free takes one recording, got {least}: the still poses and the \
             moves between them must come from one power-on; record every pose in one file \
             or one imud session"
        );
    }
    let hashing = hash_in_background(
        cli.recordings
            .iter()
            .chain(&cli.csv.gyro_csv)
            .cloned()
            .collect(),
    );
    let mut recordings = read_recordings(cli)?;
    if recordings.len() != 1 {
        bail!(
            "--reference-free takes one recording, got {} ({}): the still poses and the moves \
             between them must come from one power-on; record every pose in one file or one \
             imud session",
            recordings.len(),
            recordings
                .iter()
                .map(|r| r.name.as_str())
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    let recording = recordings.pop().expect("one recording");
    run_reference_free(cli, &recording, hashing)
}

fn run(cli: &Cli, matches: &ArgMatches) -> Result<()> {
    // (clap's `requires` counts a flag's implicit `false` as present, so this is checked here.)
    if !cli.reference_free && (cli.gravity_m_s2.is_some() || cli.latitude_deg.is_some()) {
        bail!("--gravity-m-s2 and --latitude-deg apply to --reference-free only");
    }
    if cli.reference_free {
        return reference_free(cli);
    }
    let refs = reference_args(cli, matches)?;
    precheck_reference_count(cli, &refs)?;
    let turn_on = (
        per_axis(&cli.accel_turn_on_bias_m_s2, "--accel-turn-on-bias-m-s2")?,
        per_axis(&cli.gyro_turn_on_bias_rad_s, "--gyro-turn-on-bias-rad-s")?,
    );
    // Each path next to the reference at its position (as many references as paths unless
    // files of a session were given one by one).
    let n = cli.recordings.len().max(refs.len());
    let inputs = (0..n)
        .flat_map(|k| {
            let rec = cli.recordings.get(k).map(PathBuf::as_path);
            rec.into_iter().chain(refs.get(k).map(ReferenceArg::path))
        })
        .map(Path::to_path_buf)
        .chain(cli.csv.gyro_csv.iter().cloned())
        .collect();
    let hashing = hash_in_background(inputs);
    let recordings = read_recordings(cli)?;
    let names: Vec<String> = recordings.iter().map(|r| r.name.clone()).collect();
    check_one_per_recording(&names, &refs)?;
    let mut loaded = Vec::with_capacity(refs.len());
    for (recording, r) in recordings.into_iter().zip(&refs) {
        let reference = open_reference(r, &recording.series)?;
        loaded.push((recording, reference));
    }
    run_reference(cli, &loaded, &refs, turn_on, hashing)
}

fn main() -> std::process::ExitCode {
    imu_cli::main_with_matches::<Cli, ()>("imu-calibrate", |matches| {
        let cli = Cli::from_arg_matches(matches).map_err(imu_cli::UsageError::from_clap)?;
        run(&cli, matches)
    })
}
