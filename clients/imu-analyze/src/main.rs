//! imu-analyze: the thermal, impact and dynamic tests of Aslan & Saranli (3.1.3/3.2.3, 3.3,
//! 3.4) on a recording, printed as text or JSON, with optional SVG plots and an HTML section;
//! and `health`, the daemon's live calibration health checks run offline over a recording.

use std::io::{self, IsTerminal, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand, ValueEnum};

use imu_analysis::characterize::units::DisplayUnit;
use imu_analysis::characterize::{dynamic, impact, thermal};
use imu_analysis::health::{CheckOptions, HealthCheck, check_series};
use imu_analysis::input::{ImuSeries, Source};
use imu_analysis::render::html::{self, Section};
use imu_analysis::render::number::{number, p_value};
use imu_analysis::render::svg::Figure;
use imu_cli::finite_f64;
use imu_cli::progress::read_input;

/// Offline thermal, impact and dynamic tests of IMU recordings.
#[derive(Debug, Parser)]
#[command(name = "imu-analyze", version, about)]
struct Args {
    #[command(subcommand)]
    command: Command,
}

/// Input and output options shared by every analysis.
#[derive(Debug, clap::Args)]
struct Output {
    #[command(flatten)]
    csv: imu_cli::CsvArgs,
    /// Print the full result as JSON on stdout instead of a text summary.
    #[arg(long)]
    json: bool,
    /// Write SVG charts into this directory (created if missing).
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Write a self-contained HTML report here (inline SVG).
    // `--html`: its old name, kept as a hidden alias.
    #[arg(long, value_name = "REPORT.html", alias = "html")]
    report: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SourceArg {
    /// The calibrated stream.
    Corrected,
    /// The raw counts scaled by the GainScales only.
    Raw,
}

impl From<SourceArg> for Source {
    fn from(s: SourceArg) -> Self {
        match s {
            SourceArg::Corrected => Source::Corrected,
            SourceArg::Raw => Source::Raw,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum DynamicSource {
    /// Raw and calibrated side by side (the calibration's effect on the drift).
    Both,
    /// The calibrated stream only.
    Corrected,
    /// The raw stream only.
    Raw,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Axis {
    X,
    Y,
    Z,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Warm-up test: output vs temperature and time, warm-up time constant, temperature
    /// coefficients and whether a thermal model is warranted (paper 3.1.3 / 3.2.3).
    Thermal {
        /// The recording (imud MCAP, rosbag2 MCAP or directory with sensor_msgs/msg/Imu, or
        /// text in any layout); several files of one session (imud's rotated files), or their
        /// directory, are one recording.
        #[arg(required = true)]
        recording: Vec<PathBuf>,
        /// Which stream of an imud recording to analyse.
        #[arg(long, value_enum, default_value = "raw")]
        source: SourceArg,
        /// Time bin width, s.
        #[arg(long, default_value_t = 60.0, value_parser = finite_f64)]
        bin_s: f64,
        #[command(flatten)]
        output: Output,
    },
    /// Impact test: detect shocks, peak responses, cross-axis coupling and settling times
    /// (paper 3.3, Figures 10-11).
    Impact {
        /// The recording (one or more files of one session, or a directory).
        #[arg(required = true)]
        recording: Vec<PathBuf>,
        /// Which stream of an imud recording to analyse.
        #[arg(long, value_enum, default_value = "raw")]
        source: SourceArg,
        /// Detection threshold in robust standard deviations of the accel magnitude.
        #[arg(long, default_value_t = 10.0, value_parser = finite_f64)]
        threshold_sigmas: f64,
        #[command(flatten)]
        output: Output,
    },
    /// Dynamic test: integrate the gyro about the rotation axis and compare with the table
    /// angle, after removing the timing offset (paper 3.4, Figures 12-13).
    Dynamic {
        /// The recording (one or more files of one session, or a directory).
        #[arg(required = true)]
        recording: Vec<PathBuf>,
        /// The reference: an imu-sim truth file (.mcap) or a CSV of `time_s, angle_deg`.
        #[arg(long, value_name = "TRUTH.mcap|ANGLE.csv")]
        reference: PathBuf,
        /// Rotation axis in sensor axes.
        #[arg(long, value_enum, default_value = "z")]
        axis: Axis,
        /// Which streams to compare with the reference.
        #[arg(long, value_enum, default_value = "both")]
        source: DynamicSource,
        /// Largest timing offset searched, s.
        #[arg(long, default_value_t = 1.0, value_parser = finite_f64)]
        max_offset_s: f64,
        #[command(flatten)]
        output: Output,
    },
    /// Calibration health: the daemon's live health checks run offline (each still window held
    /// against gravity and Earth's rate, the sequential tests and their states), and the offset
    /// of the calibrated stream from physics over all still windows (true bias = the
    /// calibration's bias + offset).
    Health {
        /// The recording (one or more files of one session, or a directory).
        #[arg(required = true)]
        recording: Vec<PathBuf>,
        /// Which stream of an imud recording to check (the corrected one is what the daemon's
        /// health sees).
        #[arg(long, value_enum, default_value = "corrected")]
        source: SourceArg,
        /// The calibration in force: its noise tables give the expected scatter (without it
        /// the scatter is learned from the first still windows).
        #[arg(long, value_name = "FILE")]
        calibration: Option<PathBuf>,
        /// Latitude, deg: normal gravity and the vertical part of Earth's rate (without it and
        /// --gravity-m-s2, gravity is learned from the first still windows: changes only).
        #[arg(long, value_parser = finite_f64, allow_hyphen_values = true)]
        latitude_deg: Option<f64>,
        /// Height above the ellipsoid, m (normal gravity's free-air term) [default: 0].
        #[arg(long, value_parser = finite_f64, allow_hyphen_values = true)]
        height_m: Option<f64>,
        /// Local gravity, m/s^2, when known better than normal gravity.
        #[arg(long, value_parser = finite_f64)]
        gravity_m_s2: Option<f64>,
        /// False-alarm rate per still window and triad [default: 1e-4, the daemon's].
        #[arg(long, value_parser = finite_f64)]
        false_alarm_p: Option<f64>,
        #[command(flatten)]
        csv: imu_cli::CsvArgs,
        /// Print the full result as JSON on stdout instead of a text summary.
        #[arg(long)]
        json: bool,
    },
}

fn main() -> std::process::ExitCode {
    imu_cli::main("imu-analyze", |args: Args| run(&args))
}

/// A status line on stderr while a file is read; silent when stderr is not a terminal. The
/// line is written again when done, as a progress bar may have replaced it meanwhile.
struct Progress {
    line: Option<String>,
}

impl Progress {
    fn start(what: &str, path: &Path) -> Self {
        let line = io::stderr().is_terminal().then(|| {
            let mib = std::fs::metadata(path).map_or(0.0, |m| m.len() as f64 / 1048576.0);
            format!("{what} {} ({mib:.1} MiB) ...", path.display())
        });
        if let Some(l) = &line {
            eprint!("\r{l}");
        }
        Self { line }
    }

    fn done(self, message: &str) {
        if let Some(l) = &self.line {
            eprintln!("\r{l} {message}");
        }
    }
}

/// What the JSON output says about the input: the files, topic and gaps of the first read, and
/// the note of an input read without its footer.
#[derive(Default)]
struct ReadNotes {
    unfinished: Option<serde_json::Value>,
    input: Option<serde_json::Value>,
}

/// The result with the input's files, topic and gaps after its own fields.
#[derive(serde::Serialize)]
struct WithInput<'a, T: serde::Serialize> {
    #[serde(flatten)]
    result: &'a T,
    input: &'a Option<serde_json::Value>,
}

/// Reads one recording (one or more files); an input read without its footer, and gaps
/// between files, are warned about once and noted for the JSON output.
fn read(
    paths: &[PathBuf],
    source: Source,
    csv: &imu_cli::CsvArgs,
    notes: &mut ReadNotes,
) -> Result<ImuSeries> {
    let p = Progress::start("reading", &paths[0]);
    let options = csv
        .input_options(&paths[..1], 0, source)
        .map_err(imu_cli::UsageError)?;
    let s = read_input(paths, &options)
        .with_context(|| format!("reading {} ({source:?} stream)", paths[0].display()))?;
    p.done(&format!(
        "{} samples, {} temperature readings",
        s.len(),
        s.temp.len()
    ));
    if notes.input.is_none() {
        notes.unfinished = imu_cli::session::warn("imu-analyze", &s);
        notes.input = Some(serde_json::to_value(&s.input).context("encoding the input")?);
    }
    Ok(s)
}

fn emit(
    output: &Output,
    json: &impl serde::Serialize,
    text: &str,
    section: Section,
    charts: &[Figure],
    stem: &str,
    notes: ReadNotes,
) -> Result<()> {
    let with_input = &WithInput {
        result: json,
        input: &notes.input,
    };
    if let Some(dir) = &output.plot {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (i, c) in charts.iter().enumerate() {
            let path = dir.join(format!("{stem}-{:02}.svg", i + 1));
            std::fs::write(&path, c.to_svg())
                .with_context(|| format!("writing {}", path.display()))?;
        }
    }
    if let Some(path) = &output.report {
        let page = html::page(&section.title, std::slice::from_ref(&section));
        std::fs::write(path, page).with_context(|| format!("writing {}", path.display()))?;
    }
    print(output.json, with_input, text, notes.unfinished)
}

/// The result on stdout: its JSON (with the input's note when it was read without its footer)
/// or the text.
fn print(
    as_json: bool,
    json: &impl serde::Serialize,
    text: &str,
    unfinished: Option<serde_json::Value>,
) -> Result<()> {
    let mut out = io::stdout().lock();
    if as_json {
        if let Some(note) = unfinished {
            // Only then through a Value (whose map sorts the keys): a complete input's document
            // keeps its field order.
            let mut value = serde_json::to_value(json).context("encoding the result as JSON")?;
            if let Some(map) = value.as_object_mut() {
                map.insert("input_unfinished".into(), note);
            }
            serde_json::to_writer_pretty(&mut out, &value).context("writing JSON to stdout")?;
        } else {
            serde_json::to_writer_pretty(&mut out, json).context("writing JSON to stdout")?;
        }
        writeln!(out).context("writing to stdout")?;
    } else {
        out.write_all(text.as_bytes())
            .context("writing to stdout")?;
    }
    out.flush().context("writing to stdout")?;
    Ok(())
}

fn run(args: &Args) -> Result<()> {
    match &args.command {
        Command::Thermal {
            recording,
            source,
            bin_s,
            output,
        } => run_thermal(recording, (*source).into(), *bin_s, output),
        Command::Impact {
            recording,
            source,
            threshold_sigmas,
            output,
        } => run_impact(recording, (*source).into(), *threshold_sigmas, output),
        Command::Dynamic {
            recording,
            reference,
            axis,
            source,
            max_offset_s,
            output,
        } => {
            let options = dynamic::DynamicOptions {
                axis: *axis as usize,
                max_offset_s: *max_offset_s,
                ..Default::default()
            };
            run_dynamic(recording, reference, *source, &options, output)
        }
        Command::Health {
            recording,
            source,
            calibration,
            latitude_deg,
            height_m,
            gravity_m_s2,
            false_alarm_p,
            csv,
            json,
        } => {
            let defaults = CheckOptions::default();
            let options = CheckOptions::at(
                *latitude_deg,
                height_m.unwrap_or(defaults.height_m),
                *gravity_m_s2,
                false_alarm_p.unwrap_or(defaults.false_alarm_p),
            );
            options.validate().map_err(imu_cli::UsageError)?;
            run_health(
                recording,
                (*source).into(),
                calibration.as_deref(),
                &options,
                csv,
                *json,
            )
        }
    }
}

/// `imu-analyze health`.
fn run_health(
    recording: &[PathBuf],
    source: Source,
    calibration: Option<&Path>,
    options: &CheckOptions,
    csv: &imu_cli::CsvArgs,
    json: bool,
) -> Result<()> {
    let calibration = calibration
        .map(|p| {
            imu_model::Calibration::load(p).with_context(|| format!("loading {}", p.display()))
        })
        .transpose()?;
    let mut notes = ReadNotes::default();
    let series = read(recording, source, csv, &mut notes)?;
    let r = check_series(&series, calibration.as_ref(), options);
    let with_input = WithInput {
        result: &r,
        input: &notes.input,
    };
    print(json, &with_input, &health_text(&r), notes.unfinished)
}

/// The text summary of a health check: a table of the still windows, then the state and the
/// offsets with their standard deviations.
fn health_text(r: &HealthCheck) -> String {
    let mut text = format!(
        "{} still windows ({:.0} s still, longest rest {:.0} s), {} plateaus skipped; noise from {}, gravity {} m/s^2{}\n",
        r.windows.len(),
        r.still_s,
        r.longest_still_s,
        r.plateaus,
        r.noise_source,
        number(r.gravity_m_s2),
        if r.gravity_learned {
            " (learned: changes only)"
        } else {
            ""
        }
    );
    text.push_str(&format!(
        "{:>9} {:>6} {:>12} {:>10} {:>12} {:>10} {:>9} {:>9}  state\n",
        "start s", "dur s", "|f|-g m/s2", "std", "|w-W| rad/s", "std", "accel p", "gyro p"
    ));
    for w in &r.windows {
        let g = imu_model::Vec3::from(w.gyro_residual_rad_s).norm();
        let gs = (w.gyro_std_rad_s.iter().map(|s| s * s).sum::<f64>() / 3.0).sqrt();
        text.push_str(&format!(
            "{:>9.1} {:>6.1} {:>+12.3e} {:>10.2e} {:>12.3e} {:>10.2e} {:>9} {:>9}  {}\n",
            w.start_s,
            w.duration_s,
            w.accel_residual_m_s2,
            w.accel_std_m_s2,
            g,
            gs,
            p_value(w.accel_p),
            p_value(w.gyro_p),
            w.state
        ));
    }
    text.push_str(&format!(
        "state {} (accel {}, gyro {}), {} rejecting windows\n",
        r.state, r.accel_state, r.gyro_state, r.rejections
    ));
    let axes = |v: &[f64; 3], s: &[f64; 3]| {
        (0..3)
            .map(|i| format!("{} {:+.3e} +/- {:.1e}", ["x", "y", "z"][i], v[i], s[i]))
            .collect::<Vec<_>>()
            .join(", ")
    };
    text.push_str(&format!(
        "accel offset ({}), m/s^2: {}\n",
        if r.accel_offset_3d {
            "3-D"
        } else {
            "along gravity only"
        },
        axes(&r.accel_offset_m_s2, &r.accel_offset_std_m_s2)
    ));
    match &r.accel_scale_fit {
        Some(f) => {
            text.push_str(&format!(
                "accel scale error ({} rests, reduced chi^2 {:.2}): {}\n",
                f.windows,
                f.reduced_chi2,
                axes(&f.scale_error, &f.scale_error_std),
            ));
            text.push_str(&format!(
                "  fitted with accel offset, m/s^2: {}\n",
                axes(&f.offset_m_s2, &f.offset_std_m_s2)
            ));
        }
        None => text.push_str(
            "accel scale: not calibrated by these rests (7 or more, each axis up and down)\n",
        ),
    }
    text.push_str(&format!(
        "gyro offset, rad/s: {}\n",
        axes(&r.gyro_offset_rad_s, &r.gyro_offset_std_rad_s)
    ));
    text
}

/// `imu-analyze thermal`.
fn run_thermal(recording: &[PathBuf], source: Source, bin_s: f64, output: &Output) -> Result<()> {
    let mut unfinished = ReadNotes::default();
    if !(bin_s.is_finite() && bin_s > 0.0) {
        bail!("--bin-s must be a positive number of seconds, got {bin_s}");
    }
    let series = read(recording, source, &output.csv, &mut unfinished)?;
    // The thermal analysis reads output drift as temperature dependence: motion would
    // masquerade as a thermal effect.
    if let Some(w) = series.motion_warning() {
        eprintln!("imu-analyze: warning: {}: {w}", series.origin);
    }
    let r = thermal::analyze(
        &series,
        &thermal::ThermalOptions {
            bin_s,
            ..Default::default()
        },
    )
    .context("thermal analysis")?;
    let text = thermal_text(&r);
    let charts = thermal::charts(&r);
    let section = html::thermal_section(&r, &charts);
    emit(output, &r, &text, section, &charts, "thermal", unfinished)
}

/// The text summary of a thermal analysis: the recommendation, then per axis the coefficient
/// in mg/K or deg/h/K with the coloured-noise test and the verdict.
fn thermal_text(r: &thermal::ThermalReport) -> String {
    let mut text = format!(
        "{}\n{:.1} .. {:.1} deg C over {:.0} s",
        r.recommendation, r.temp_range_c[0], r.temp_range_c[1], r.duration_s
    );
    if let Some(w) = &r.warmup {
        text.push_str(&format!(
            ", warm-up tau {} +/- {} s",
            number(w.tau_s),
            number(w.tau_std_s)
        ));
    }
    text.push('\n');
    for a in &r.axes {
        let u = DisplayUnit::of_sensor(&a.sensor);
        let l = u.label();
        text.push_str(&format!(
            "{:5} {}: {} +/- {} {l}/K (t {:+.2}, p {}), change over range {} {l} vs bin scatter {} {l}{}: {}\n",
            a.sensor,
            a.axis,
            u.format(a.bias_coeff_per_k),
            u.format(a.bias_coeff_std_per_k),
            a.linear.t_stats[1],
            p_value(a.linear.p_values[1]),
            u.format(a.predicted_change),
            u.format(a.bin_noise),
            a.scale_coeff_per_k
                .map_or(String::new(), |s| format!(", as scale {} ppm/K", number(s * 1e6))),
            a.verdict.word().to_uppercase()
        ));
    }
    text.push_str(&r.confounding.note);
    text.push('\n');
    text
}

/// `imu-analyze impact`.
fn run_impact(
    recording: &[PathBuf],
    source: Source,
    threshold_sigmas: f64,
    output: &Output,
) -> Result<()> {
    let mut unfinished = ReadNotes::default();
    let series = read(recording, source, &output.csv, &mut unfinished)?;
    let r = impact::analyze(
        &series,
        &impact::ImpactOptions {
            threshold_sigmas,
            ..Default::default()
        },
    )
    .context("impact analysis")?;
    let text = impact_text(&r);
    let charts = impact::charts(&series, &r);
    let section = html::impact_section(&r, &charts);
    emit(output, &r, &text, section, &charts, "impact", unfinished)
}

/// The text summary of an impact analysis.
fn impact_text(r: &impact::ImpactReport) -> String {
    let mut text = format!(
        "{} impacts, struck axis {}\n",
        r.events.len(),
        r.struck_axis.map_or("-", |a| ["x", "y", "z"][a])
    );
    for i in 0..3 {
        let s = &r.summary;
        text.push_str(&format!(
            "{}: accel peak {:+.3} +/- {:.3} m/s^2, coupling {:+.3e} +/- {:.1e}, settling {:.3} s; gyro peak {:+.2e} rad/s, coupling {:+.2e} (rad/s)/(m/s^2), settling {:.3} s\n",
            ["x", "y", "z"][i],
            s.accel_peak_m_s2[i].mean,
            s.accel_peak_m_s2[i].std,
            r.pooled_accel_coupling[i].value,
            r.pooled_accel_coupling[i].std_error,
            s.accel_settling_s[i].mean,
            s.gyro_peak_rad_s[i].mean,
            r.pooled_gyro_coupling_rad_s_per_m_s2[i].value,
            s.gyro_settling_s[i].mean,
        ));
    }
    text
}

/// `imu-analyze dynamic`: the raw and/or corrected stream against the reference angle.
fn run_dynamic(
    recording: &[PathBuf],
    reference: &Path,
    source: DynamicSource,
    options: &dynamic::DynamicOptions,
    output: &Output,
) -> Result<()> {
    let mut unfinished = ReadNotes::default();
    let reference = read_reference(reference)?;
    let want = |s: DynamicSource| source == DynamicSource::Both || source == s;
    let mut runs = [None, None];
    for (k, (flag, src)) in [
        (DynamicSource::Raw, Source::Raw),
        (DynamicSource::Corrected, Source::Corrected),
    ]
    .into_iter()
    .enumerate()
    {
        if !want(flag) {
            continue;
        }
        match read(recording, src, &output.csv, &mut unfinished) {
            Ok(series) => {
                runs[k] = Some(
                    dynamic::analyze(&series, &reference, options)
                        .with_context(|| format!("dynamic analysis of the {src:?} stream"))?,
                );
            }
            Err(e) if source == DynamicSource::Both => {
                eprintln!("imu-analyze: warning: skipping the {src:?} stream: {e:#}");
            }
            Err(e) => return Err(e),
        }
    }
    let [raw, corrected] = runs;
    if raw.is_none() && corrected.is_none() {
        bail!(
            "{}: neither the raw nor the corrected stream could be read",
            recording[0].display()
        );
    }
    let r = dynamic::compare(&reference, raw, corrected);
    let text = format!("{}\n", r.summary);
    let charts = dynamic::charts(&r);
    let section = html::dynamic_section(&r, &charts);
    emit(output, &r, &text, section, &charts, "dynamic", unfinished)
}

fn read_reference(path: &Path) -> Result<dynamic::Reference> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("csv") | Some("txt") => dynamic::Reference::read_csv(path)
            .with_context(|| format!("reading the reference angle CSV {}", path.display())),
        _ => {
            let p = Progress::start("reading truth", path);
            let truth = imu_rec::truth::read_truth(path).with_context(|| {
                format!(
                    "reading the reference truth file {} (a CSV must end in .csv)",
                    path.display()
                )
            })?;
            p.done(&format!("{} samples", truth.samples.len()));
            if truth.samples.is_empty() {
                bail!("{}: the truth file has no samples", path.display());
            }
            Ok(dynamic::Reference::from_truth(
                &truth,
                &path.display().to_string(),
            ))
        }
    }
}
