//! `imu-noise`: Allan deviation and IEEE Std 952/1293 noise terms of a static recording, per
//! sensor and axis, as a table (or `--json`), SVG plots and a Kalibr-compatible imu.yaml.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::{Parser, ValueEnum};
use imu_analysis::input::{AccelUnit, GyroUnit};
use imu_analysis::render::svg::{Chart, Series, Style, write_svg};
use imu_analysis::{ImuSeries, Source};
use imu_cli::progress::read_input;
use imu_stats::allan::{self, Kind, Options, TauSet};
use imu_stats::noise_terms::{NoiseTerms, SlopeReadoffs, fit_terms, slope_readoffs};
use serde::Serialize;

const G_M_S2: f64 = 9.80665;
const RAD_TO_DEG: f64 = 180.0 / std::f64::consts::PI;

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
    /// Write one SVG per sensor/axis into this directory.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Which stream of an imud recording to analyse.
    #[arg(long, value_enum, default_value = "corrected")]
    source: SourceArg,
    /// Tau set: `octave`, `all` or `N-per-decade` (e.g. `10-per-decade`).
    #[arg(long, default_value = "8-per-decade")]
    taus: TauSet,
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

/// Result for one sensor axis.
#[derive(Debug, Serialize)]
struct AxisReport {
    sensor: &'static str,
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
    display: Display,
    curve: allan::DevCurve,
    /// Present when the recording was read without its footer (a killed writer): how far the
    /// read got (the same facts as the warning on stderr).
    #[serde(skip_serializing_if = "Option::is_none")]
    input_unfinished: Option<serde_json::Value>,
    /// The files read (in time order), the IMU topic, the gaps between files.
    input: imu_analysis::input::InputInfo,
}

#[derive(Debug, Serialize)]
struct Display {
    n: f64,
    n_unit: &'static str,
    b: f64,
    b_unit: &'static str,
    k: f64,
    k_unit: &'static str,
}

fn display(sensor: &str, t: &NoiseTerms) -> Display {
    let (n, b, k) = (t.n_u_per_sqrt_hz.value, t.b_u.value, t.k_u_sqrt_hz.value);
    if sensor == "gyro" {
        // rad/s/sqrt(Hz) = rad/sqrt(s) -> deg/sqrt(h): x 180/pi x 60.
        Display {
            n: n * RAD_TO_DEG * 60.0,
            n_unit: "deg/sqrt(h)",
            b: b * RAD_TO_DEG * 3600.0,
            b_unit: "deg/h",
            k: k * RAD_TO_DEG * 3600.0 * 60.0,
            k_unit: "deg/h/sqrt(h)",
        }
    } else {
        let ug = 1e6 / G_M_S2;
        Display {
            n: n * ug,
            n_unit: "micro-g/sqrt(Hz)",
            b: b * ug,
            b_unit: "micro-g",
            k: k * ug,
            k_unit: "micro-g*sqrt(Hz)",
        }
    }
}

fn analyse(series: &ImuSeries, taus: TauSet) -> Result<Vec<AxisReport>> {
    let rate_hz = series.sample_rate_hz();
    anyhow::ensure!(
        rate_hz.is_finite() && rate_hz > 0.0,
        "cannot determine the sample rate of {} ({} samples)",
        series.origin,
        series.len()
    );
    let opts = Options {
        taus,
        ..Options::default()
    };
    let progress = std::io::stderr().is_terminal();
    let mut out = Vec::new();
    for (sensor, unit, data) in [
        ("accel", "m/s^2", &series.accel_m_s2),
        ("gyro", "rad/s", &series.gyro_rad_s),
    ] {
        for (i, axis) in ["x", "y", "z"].into_iter().enumerate() {
            if progress {
                eprint!("\ranalysing {sensor} {axis} ({} samples)...", data.len());
            }
            let y: Vec<f64> = data.iter().map(|v| v[i]).collect();
            let curve = allan::deviation(Kind::Oadev, &y, 1.0 / rate_hz, &opts)
                .with_context(|| format!("Allan deviation of {sensor} {axis}"))?;
            let fit =
                fit_terms(&curve).with_context(|| format!("noise terms of {sensor} {axis}"))?;
            out.push(AxisReport {
                sensor,
                axis,
                unit,
                sample_rate_hz: rate_hz,
                slope_readoffs: slope_readoffs(&curve),
                white_per_sample_u: fit.white_per_sample_u(rate_hz),
                random_walk_step_per_sample_u: fit.random_walk_step_per_sample_u(rate_hz),
                display: display(sensor, &fit),
                fit,
                curve,
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

fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".into(), |v| format!("{v:.3e}"))
}

fn print_table(reports: &[AxisReport], w: &mut impl Write) -> std::io::Result<()> {
    writeln!(
        w,
        "Fitted IEEE terms (weighted NNLS on the Allan variance; +- 1 sigma); U = m/s^2 (accel), rad/s (gyro)"
    )?;
    writeln!(
        w,
        "{:<7}{:<3}{:>24}{:>24}{:>24}{:>12}{:>12}  display units",
        "sensor", "ax", "N [U/sqrt(Hz)]", "B [U]", "K [U*sqrt(Hz)]", "Q [U*s]", "R [U/s]"
    )?;
    for r in reports {
        let t = &r.fit;
        let pm = |x: &imu_stats::noise_terms::Term| format!("{:.3e}+-{:.1e}", x.value, x.sigma);
        writeln!(
            w,
            "{:<7}{:<3}{:>24}{:>24}{:>24}{:>12.2e}{:>12.2e}  N {:.4} {}, B {:.4} {}, K {:.4} {}",
            r.sensor,
            r.axis,
            pm(&t.n_u_per_sqrt_hz),
            pm(&t.b_u),
            pm(&t.k_u_sqrt_hz),
            t.q_u_s.value,
            t.r_u_per_s.value,
            r.display.n,
            r.display.n_unit,
            r.display.b,
            r.display.b_unit,
            r.display.k,
            r.display.k_unit,
        )?;
    }
    writeln!(
        w,
        "\nDiscrete per-sample values and classic slope read-offs (N at tau=1 on the -1/2 line, B = min ADEV/0.664, K at tau=3 on the +1/2 line):"
    )?;
    writeln!(
        w,
        "{:<7}{:<3}{:>10}{:>20}{:>22}{:>16}{:>16}{:>16}",
        "sensor",
        "ax",
        "rate [Hz]",
        "white/sample [U]",
        "RW step/sample [U]",
        "N read [U/rtHz]",
        "B read [U]",
        "K read [U*rtHz]"
    )?;
    for r in reports {
        writeln!(
            w,
            "{:<7}{:<3}{:>10.2}{:>20.3e}{:>22.3e}{:>16}{:>16}{:>16}",
            r.sensor,
            r.axis,
            r.sample_rate_hz,
            r.white_per_sample_u,
            r.random_walk_step_per_sample_u,
            opt(r.slope_readoffs.n_u_per_sqrt_hz),
            opt(r.slope_readoffs.b_u),
            opt(r.slope_readoffs.k_u_sqrt_hz),
        )?;
    }
    Ok(())
}

fn plot(dir: &Path, r: &AxisReport) -> Result<()> {
    let c = &r.curve;
    let pts = |f: &dyn Fn(&allan::DevPoint) -> f64| -> Vec<(f64, f64)> {
        c.points.iter().map(|p| (p.tau_s, f(p))).collect()
    };
    let mut series = vec![
        Series {
            name: format!("{:.0}% confidence", c.confidence * 100.0),
            points: pts(&|p| p.dev_lo),
            style: Style::Band {
                upper: pts(&|p| p.dev_hi),
            },
        },
        Series {
            name: "OADEV".into(),
            points: pts(&|p| p.dev),
            style: Style::Points,
        },
        Series {
            name: "fit".into(),
            points: pts(&|p| r.fit.adev(p.tau_s)),
            style: Style::Line,
        },
    ];
    for (k, name) in ["Q", "N", "B", "K", "R"].iter().enumerate() {
        let line: Vec<(f64, f64)> = c
            .points
            .iter()
            .map(|p| (p.tau_s, r.fit.term_adevs(p.tau_s)[k]))
            .collect();
        if line.iter().any(|p| p.1 > 0.0) {
            series.push(Series {
                name: format!("{name} term"),
                points: line,
                style: Style::Line,
            });
        }
    }
    let chart = Chart {
        title: format!("{} {}: overlapping Allan deviation", r.sensor, r.axis),
        x_label: "tau [s]".into(),
        y_label: format!("sigma(tau) [{}]", r.unit),
        log_x: true,
        log_y: true,
        series,
    };
    let path = dir.join(format!("adev-{}-{}.svg", r.sensor, r.axis));
    write_svg(&chart, &path).with_context(|| format!("writing {}", path.display()))
}

fn kalibr_yaml(reports: &[AxisReport], rostopic: &str) -> String {
    // Kalibr wants one value per sensor: take the worst (largest) axis.
    let worst = |sensor: &str, f: &dyn Fn(&NoiseTerms) -> f64| {
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
        worst("accel", &|t| t.n_u_per_sqrt_hz.value),
        worst("accel", &|t| t.k_u_sqrt_hz.value),
        worst("gyro", &|t| t.n_u_per_sqrt_hz.value),
        worst("gyro", &|t| t.k_u_sqrt_hz.value),
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
    let mut reports = analyse(&series, cli.taus)?;
    for r in &mut reports {
        r.input_unfinished.clone_from(&unfinished);
    }
    if let Some(dir) = &cli.plot {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for r in &reports {
            plot(dir, r)?;
        }
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
        print_table(&reports, &mut out)?;
    }
    out.flush()?;
    Ok(())
}

fn main() -> std::process::ExitCode {
    imu_cli::main("imu-noise", |cli: Cli| run(&cli))
}
