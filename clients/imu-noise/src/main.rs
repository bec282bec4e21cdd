//! `imu-noise`: Allan-family deviations (ADEV, OADEV, MDEV, HDEV, OHDEV, TDEV, TOTDEV, Theo1,
//! TheoH, with confidence intervals) and IEEE Std 952/1293 noise terms of a static recording, per sensor and
//! axis, as a table (or `--json`), SVG figures, a self-contained HTML report and a
//! Kalibr-compatible imu.yaml.
//!
//! Files: `taus.rs` (the `--taus` argument), `table.rs` (the text output), `plots.rs` (the
//! figures, as SVG files and as the HTML report; drawn by `imu_analysis::render::allan`).

mod plots;
mod table;
mod taus;

use std::io::{IsTerminal, Write};
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Parser, ValueEnum};
use imu_analysis::input::{AccelUnit, GyroUnit};
use imu_analysis::render::allan::DisplayTerms;
use imu_analysis::{ImuSeries, Source};
use imu_cli::progress::read_input;
use imu_model::Triad;
use imu_stats::allan::{self, DevPoint, EdfMethod, Kind, NoiseType, Options, TauSet};
use imu_stats::noise_terms::{
    FitOptions, NoiseTerms, SlopeReadoffs, fit_terms_with, slope_readoffs,
};
use serde::Serialize;
use taus::TauArg;

/// Command line.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    /// Recording: imud MCAP log, rosbag2 MCAP or directory (sensor_msgs/msg/Imu), or text in
    /// any layout. Several files (imud's rotated files of one session), or their directory, are
    /// one recording: read in time order, gaps between files reported.
    #[arg(required = true, value_name = "RECORDING")]
    recording: Vec<PathBuf>,
    /// Print JSON instead of the table.
    #[arg(long)]
    json: bool,
    /// Write a Kalibr-compatible imu.yaml here.
    #[arg(long, value_name = "IMU.yaml")]
    kalibr: Option<PathBuf>,
    /// Write SVG figures into this directory, one per sensor with a panel per axis: the OADEV
    /// with the fitted terms (allan-SENSOR.svg) and each other --kind (dev-KIND-SENSOR.svg).
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Write a self-contained HTML report here: the input, the fitted terms and every figure.
    #[arg(long, value_name = "REPORT.html")]
    report: Option<PathBuf>,
    /// Deviations to compute, comma-separated: adev, oadev, mdev, hdev, ohdev, tdev, totdev,
    /// theo1, theoh. Theo1 reaches averaging times to 75 % of the record (tau = 0.75 m tau0);
    /// TheoH is OADEV to 10 % of it and bias-removed Theo1 beyond. Both read --taus as averaging
    /// times. Theo1 costs O(N m) per tau, TheoH's bias ratio O(N^3/900) (seconds at 20k samples).
    #[arg(long, value_delimiter = ',', default_value = "oadev")]
    kind: Vec<Kind>,
    /// Two-sided confidence level of the bounds (0.683 is "1 sigma", Stable32's default).
    #[arg(long, default_value = "0.683", value_parser = confidence_level)]
    confidence: f64,
    /// How the bounds' degrees of freedom are computed: `greenhall` (Greenhall's EDF with the
    /// noise type identified per tau as Stable32 does: lag-1 autocorrelation, then the B1 ratio
    /// or the previous tau's type at the longest taus) or `sp1065` (closed forms with the noise
    /// type from the local slope).
    #[arg(long, value_enum, default_value = "greenhall")]
    edf: EdfArg,
    /// Which stream of an imud recording to analyse.
    #[arg(long, value_enum, default_value = "corrected")]
    source: SourceArg,
    /// Tau set: `octave`, `decade` (Stable32's 1, 2, 4 x 10^k), `all`, `N-per-decade` (e.g.
    /// `10-per-decade`), or taus in seconds (`1,2,4,10`; each rounded to a whole number of
    /// sample periods). The noise-term fit uses this set too, or 8-per-decade for a list.
    #[arg(long, default_value = "8-per-decade")]
    taus: TauArg,
    /// ROS topic written into the Kalibr file.
    #[arg(long, default_value = "/imu/data")]
    rostopic: String,
    #[command(flatten)]
    csv: imu_cli::CsvArgs,
    /// CSV: accelerometer columns are in g (the same as `--csv-accel g`).
    #[arg(long, hide = true)]
    csv_accel_g: bool,
    /// CSV: gyro columns are in deg/s (the same as `--csv-gyro deg/s`).
    #[arg(long, hide = true)]
    csv_gyro_deg_s: bool,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum SourceArg {
    Corrected,
    Raw,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum EdfArg {
    Greenhall,
    Sp1065,
}

impl From<EdfArg> for EdfMethod {
    fn from(a: EdfArg) -> Self {
        match a {
            EdfArg::Greenhall => EdfMethod::Greenhall,
            EdfArg::Sp1065 => EdfMethod::Sp1065,
        }
    }
}

fn confidence_level(s: &str) -> Result<f64, String> {
    let c = imu_cli::args::finite_f64(s)?;
    if c > 0.0 && c < 1.0 {
        Ok(c)
    } else {
        Err(format!("confidence {c} must lie strictly between 0 and 1"))
    }
}

/// One deviation curve of one axis, every point with the noise type its bounds assumed.
#[derive(Debug, Serialize)]
struct KindReport {
    kind: Kind,
    /// Unit of `dev`, `dev_lo`, `dev_hi` (TDEV: the rate unit times seconds).
    unit: String,
    edf_method: EdfMethod,
    confidence: f64,
    points: Vec<PointReport>,
}

#[derive(Debug, Serialize)]
struct PointReport {
    #[serde(flatten)]
    point: DevPoint,
    /// Power-law noise type the EDF assumed, and its exponent alpha (S_y ~ f^alpha).
    noise: NoiseType,
    alpha: i32,
}

/// Result for one sensor axis.
#[derive(Debug, Serialize)]
struct AxisReport {
    sensor: Triad,
    axis: &'static str,
    /// Unit of the rate data (U) that the `*_u*` fields are expressed in.
    unit: &'static str,
    sample_rate_hz: f64,
    fit: NoiseTerms,
    slope_readoffs: SlopeReadoffs,
    /// Discrete per-sample white-noise sigma, N sqrt(rate), U.
    white_per_sample_u: f64,
    /// Discrete per-sample random-walk step, K / sqrt(rate), U.
    random_walk_step_per_sample_u: f64,
    /// Display units: N, B, K in deg/sqrt(h), deg/h, deg/h/sqrt(h) (gyro) or
    /// micro-g/sqrt(Hz), micro-g, micro-g*sqrt(Hz) (accel).
    display: DisplayTerms,
    /// The OADEV curve the terms were fitted to.
    curve: allan::DevCurve,
    /// Every `--kind` asked for.
    deviations: Vec<KindReport>,
    /// Present when the recording was read without its footer (a killed writer): how far the
    /// read got (the same facts as the warning on stderr).
    #[serde(skip_serializing_if = "Option::is_none")]
    input_unfinished: Option<serde_json::Value>,
    /// The files read (in time order), the IMU topic, the gaps between files.
    input: imu_analysis::input::InputInfo,
}

/// What to compute, from the command line.
struct Request {
    kinds: Vec<Kind>,
    taus: TauArg,
    edf: EdfMethod,
    confidence: f64,
}

fn analyse(series: &ImuSeries, req: &Request) -> Result<Vec<AxisReport>> {
    let rate_hz = series.sample_rate_hz();
    anyhow::ensure!(
        rate_hz.is_finite() && rate_hz > 0.0,
        "cannot determine the sample rate of {} ({} samples)",
        series.origin,
        series.len()
    );
    let opts = Options {
        taus: req.taus.resolve(rate_hz)?,
        edf: req.edf,
        confidence: req.confidence,
        noise: None,
    };
    let fit_opts = Options {
        taus: match &req.taus {
            TauArg::Set(set) => set.clone(),
            TauArg::Seconds(_) => TauSet::PerDecade(8),
        },
        ..opts.clone()
    };
    let progress = std::io::stderr().is_terminal();
    let mut out = Vec::new();
    for (sensor, data) in [
        (Triad::Accel, &series.accel_m_s2),
        (Triad::Gyro, &series.gyro_rad_s),
    ] {
        let unit = sensor.unit();
        for (i, axis) in ["x", "y", "z"].into_iter().enumerate() {
            if progress {
                eprint!("\ranalysing {sensor} {axis} ({} samples)...", data.len());
            }
            let y: Vec<f64> = data.iter().map(|v| v[i]).collect();
            let context = || format!("Allan deviation of {sensor} {axis}");
            let curve = allan::deviation(Kind::Oadev, &y, 1.0 / rate_hz, &fit_opts)
                .with_context(context)?;
            let deviations = req
                .kinds
                .iter()
                .map(|&kind| kind_report(kind, unit, &y, rate_hz, &opts))
                .collect::<Result<Vec<_>>>()
                .with_context(context)?;
            let fit = fit_terms_with(&curve, &FitOptions::default())
                .with_context(|| format!("noise terms of {sensor} {axis}"))?;
            out.push(AxisReport {
                sensor,
                axis,
                unit,
                sample_rate_hz: rate_hz,
                slope_readoffs: slope_readoffs(&curve),
                white_per_sample_u: fit.white_per_sample_u(rate_hz),
                random_walk_step_per_sample_u: fit.random_walk_step_per_sample_u(rate_hz),
                display: DisplayTerms::of(sensor, &fit),
                fit,
                curve,
                deviations,
                input_unfinished: None,
                input: series.input.clone(),
            });
        }
    }
    if progress {
        eprintln!("\r{:60}\r", "");
    }
    Ok(out)
}

fn kind_report(
    kind: Kind,
    unit: &str,
    y: &[f64],
    rate_hz: f64,
    opts: &Options,
) -> Result<KindReport> {
    let (curve, noise) = allan::deviation_with_noise(kind, y, 1.0 / rate_hz, opts)
        .with_context(|| kind.name().to_uppercase())?;
    Ok(KindReport {
        kind,
        unit: if kind == Kind::Tdev {
            format!("{unit}*s")
        } else {
            unit.to_string()
        },
        edf_method: opts.edf,
        confidence: opts.confidence,
        points: curve
            .points
            .into_iter()
            .zip(noise)
            .map(|(point, noise)| PointReport {
                point,
                noise,
                alpha: noise.alpha(),
            })
            .collect(),
    })
}

fn kalibr_yaml(reports: &[AxisReport], rostopic: &str) -> String {
    // Kalibr wants one value per sensor: take the worst (largest) axis.
    let worst = |sensor: Triad, f: &dyn Fn(&NoiseTerms) -> f64| {
        reports
            .iter()
            .filter(|r| r.sensor == sensor)
            .map(|r| f(&r.fit))
            .fold(0.0, f64::max)
    };
    let rate = reports.first().map_or(0.0, |r| r.sample_rate_hz);
    format!(
        "# Kalibr IMU noise model, written by imu-noise (continuous-time values, largest axis).\n\
         # *_noise_density is the white noise N; *_random_walk is the RATE random walk K\n\
         # (Kalibr's \"random walk\"), NOT the bias instability B.\n\
         # Accelerometers\n\
         accelerometer_noise_density: {:.6e}   # [ m / s^2 / sqrt(Hz) ]\n\
         accelerometer_random_walk: {:.6e}     # [ m / s^3 / sqrt(Hz) ]\n\
         # Gyroscopes\n\
         gyroscope_noise_density: {:.6e}       # [ rad / s / sqrt(Hz) ]\n\
         gyroscope_random_walk: {:.6e}         # [ rad / s^2 / sqrt(Hz) ]\n\
         rostopic: {rostopic}\n\
         update_rate: {rate:.3}                  # [ Hz ]\n",
        worst(Triad::Accel, &|t| t.n_u_per_sqrt_hz.value),
        worst(Triad::Accel, &|t| t.k_u_sqrt_hz.value),
        worst(Triad::Gyro, &|t| t.n_u_per_sqrt_hz.value),
        worst(Triad::Gyro, &|t| t.k_u_sqrt_hz.value),
    )
}

fn run(cli: &Cli) -> Result<()> {
    let source = match cli.source {
        SourceArg::Corrected => Source::Corrected,
        SourceArg::Raw => Source::Raw,
    };
    let mut input = cli
        .csv
        .input_options(&cli.recording[..1], 0, source)
        .map_err(imu_cli::UsageError)?;
    if cli.csv_accel_g {
        input.csv.accel = AccelUnit::G;
    }
    if cli.csv_gyro_deg_s {
        input.csv.gyro = GyroUnit::DegPerSecond;
    }
    let shown = cli
        .recording
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(" ");
    if std::io::stderr().is_terminal() {
        eprint!("reading {shown}...");
    }
    let series = read_input(&cli.recording, &input).with_context(|| format!("reading {shown}"))?;
    let unfinished = imu_cli::session::warn("imu-noise", &series);
    if let Some(w) = series.motion_warning() {
        eprintln!("imu-noise: warning: {shown}: {w}");
    }
    let request = Request {
        kinds: dedup_kinds(&cli.kind),
        taus: cli.taus.clone(),
        edf: cli.edf.into(),
        confidence: cli.confidence,
    };
    let mut reports = analyse(&series, &request)?;
    for r in &mut reports {
        r.input_unfinished.clone_from(&unfinished);
    }
    if let Some(dir) = &cli.plot {
        plots::write_figures(dir, &reports)?;
    }
    if let Some(path) = &cli.report {
        plots::write_report(path, &shown, &series, &reports)?;
    }
    if let Some(path) = &cli.kalibr {
        std::fs::write(path, kalibr_yaml(&reports, &cli.rostopic))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let mut out = std::io::stdout().lock();
    if cli.json {
        serde_json::to_writer_pretty(&mut out, &reports)?;
        writeln!(out)?;
    } else {
        table::print(&reports, &mut out)?;
    }
    out.flush()?;
    Ok(())
}

/// The kinds in the order given, each once.
fn dedup_kinds(kinds: &[Kind]) -> Vec<Kind> {
    let mut out: Vec<Kind> = Vec::new();
    for &k in kinds {
        if !out.contains(&k) {
            out.push(k);
        }
    }
    out
}

fn main() -> std::process::ExitCode {
    imu_cli::main("imu-noise", |cli: Cli| run(&cli))
}
