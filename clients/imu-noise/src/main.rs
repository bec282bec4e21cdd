//! `imu-noise`: Allan-family deviations (ADEV, OADEV, MDEV, HDEV, OHDEV, TDEV, TOTDEV, Theo1,
//! TheoH, with confidence intervals) and IEEE Std 952/1293 noise terms of a static recording, per sensor and
//! axis, as a table (or `--json`), SVG figures, a self-contained HTML report and a
//! Kalibr-compatible imu.yaml.
//!
//! The analysis is `imu_analysis::characterize::noise` (shared with Python's `imud.noise`).
//! Files: `table.rs` (the text output), `plots.rs` (the
//! figures, as SVG files and as the HTML report; drawn by `imu_analysis::render::allan`).

mod plots;
mod table;

use std::io::{IsTerminal, Write};
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Parser, ValueEnum};
use imu_analysis::Source;
use imu_analysis::characterize::noise::{self, AxisReport, NoiseRequest, TauArg, dedup_kinds};
use imu_analysis::input::{AccelUnit, GyroUnit};
use imu_cli::progress::read_input;
use imu_model::Triad;
use imu_stats::allan::{EdfMethod, Kind};
use imu_stats::noise_terms::NoiseTerms;

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
    /// times. Theo1 costs O(N m) per tau, TheoH's bias ratio O(N^2/7.5) (see BENCHMARKS.md).
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

/// Kalibr's imu.yaml from the noise terms (`rostopic` the IMU topic).
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
    let request = NoiseRequest {
        kinds: dedup_kinds(&cli.kind),
        taus: cli.taus.clone(),
        edf: cli.edf.into(),
        confidence: cli.confidence,
    };
    let progress = std::io::stderr().is_terminal();
    let mut reports = noise::analyse(&series, &request, |sensor, axis, n| {
        if progress {
            eprint!("\ranalysing {sensor} {axis} ({n} samples)...");
        }
    })?;
    if progress {
        eprintln!("\r{:60}\r", "");
    }
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

fn main() -> std::process::ExitCode {
    imu_cli::main("imu-noise", |cli: Cli| run(&cli))
}
