//! Fit time and peak memory of a calibration from a 6-hour 100 Hz multi-position recording
//! (issue 4 item 9: under 5 s and 500 MB including reading the MCAP):
//! `cargo bench -p imu-analysis --bench calibrate_6h`.
//!
//! The recording (and its truth file) is made once through imud's offline path and cached under
//! the target directory. The measurement runs in a fresh child process, so its peak resident
//! set (`VmHWM`) is that of reading, segmenting and fitting alone, not of the simulation.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use imu_analysis::calibrate::{CalibrateOptions, bias_drift_from_noise, calibrate};
use imu_analysis::input::{CsvOptions, Source, read_any};
use imu_analysis::reference::Reference;
use imu_analysis::segment::{SegmentKind, SegmentOptions, detect};
use imu_model::{Calibration, EffectKind};

/// Two 6-position index-table sweeps (15 min per position), then each axis on a vertical rate
/// table (+/-40, +/-80 deg/s, 6 min per plateau) between 10-minute still positions with that axis
/// up and down, and a last still position: 6 hours.
const SCENARIO: &str = r#"
name = "calibration-6h"
rate-hz = 100.0
latitude-deg = 40.0
transition-s = 10.0

[[segment]]
kind = "static"
orientation = { x = "north", z = "up" }
duration-s = 600.0
[[segment]]
kind = "index-table"
axis = "x"
step-deg = 60.0
positions = 6
dwell-s = 900.0
move-s = 10.0
[[segment]]
kind = "static"
orientation = { y = "north", z = "up" }
duration-s = 600.0
[[segment]]
kind = "index-table"
axis = "y"
step-deg = 60.0
positions = 6
dwell-s = 900.0
move-s = 10.0

[[segment]]
kind = "static"
orientation = { z = "up", x = "north" }
duration-s = 600.0
[[segment]]
kind = "rate-steps"
axis = "z"
rates-deg-s = [40, 80, -40, -80, 0]
dwell-s = 360.0
accel-deg-s2 = 40.0
[[segment]]
kind = "static"
orientation = { z = "down", x = "north" }
duration-s = 600.0
[[segment]]
kind = "static"
orientation = { x = "up", y = "north" }
duration-s = 600.0
[[segment]]
kind = "rate-steps"
axis = "x"
rates-deg-s = [40, 80, -40, -80, 0]
dwell-s = 360.0
accel-deg-s2 = 40.0
[[segment]]
kind = "static"
orientation = { x = "down", y = "north" }
duration-s = 600.0
[[segment]]
kind = "static"
orientation = { y = "up", z = "north" }
duration-s = 600.0
[[segment]]
kind = "rate-steps"
axis = "y"
rates-deg-s = [40, 80, -40, -80, 0]
dwell-s = 360.0
accel-deg-s2 = 40.0
[[segment]]
kind = "static"
orientation = { y = "down", z = "north" }
duration-s = 600.0
[[segment]]
kind = "static"
orientation = { x = "north", z = "up" }
duration-s = 420.0
"#;

fn truth_model_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/example-3dm-gx1.toml")
}

/// The cached recording and truth file, made on first use.
fn recording() -> (PathBuf, PathBuf) {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("calibrate-6h-v2");
    let done = dir.join("done");
    let truth = dir.join("truth.mcap");
    if let Ok(name) = std::fs::read_to_string(&done) {
        return (dir.join("log").join(name.trim()), truth);
    }
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("cache dir");
    let scenario = dir.join("scenario.toml");
    std::fs::write(&scenario, SCENARIO).expect("scenario");
    let mut sim = imu_sim::SimOptions::from_files(&scenario, Some(&truth_model_path()))
        .expect("scenario and truth model");
    sim.seed = 6;
    sim.truth_out = Some(truth.clone());
    let mut config = imud::config::Config::default();
    config.log.dir = dir.join("log");
    config.name = "cal6h".into();
    // One file: no size rotation for the benchmark.
    config.log.rotate_size_mib = 1 << 20;
    eprintln!(
        "generating the 6-hour recording once (cached in {})",
        dir.display()
    );
    let t = Instant::now();
    let out = imud::offline::record(sim, &config).expect("offline recording");
    eprintln!(
        "  {} samples in {:.0} s",
        out.samples,
        t.elapsed().as_secs_f64()
    );
    assert_eq!(out.files.len(), 1, "{:?}", out.files);
    let name = out.files[0]
        .file_name()
        .expect("file name")
        .to_string_lossy();
    std::fs::write(&done, name.as_bytes()).expect("marker");
    (out.files[0].clone(), truth)
}

/// Peak resident set of this process, kB (`VmHWM`).
fn peak_rss_kb() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        })
        .unwrap_or(0)
}

/// The measured work, in this (fresh) process: prints one `key value` line per measurement.
/// What `imu-calibrate REC --reference TRUTH --model M` does: read the raw stream, then
/// `calibrate` (segmentation, the truth file streamed into segment means, the two fits); then,
/// untimed in the total, the parts of `calibrate` again one by one for the breakdown.
fn measure(recording: &Path, truth: &Path) {
    let model = Calibration::load(&truth_model_path()).expect("model");
    let t = Instant::now();
    let series = read_any(recording, Source::Raw, &CsvOptions::default()).expect("read");
    let read_s = t.elapsed().as_secs_f64();
    let rss_after_read_kb = peak_rss_kb();

    let duration_s = series.t_s[series.len() - 1];
    let drift = |n: &Option<imu_model::NoiseModel>| {
        n.as_ref().map(|n| bias_drift_from_noise(n, duration_s))
    };
    let mut opts = CalibrateOptions {
        accel_noise: model.accel.noise.clone(),
        gyro_noise: model.gyro.noise.clone(),
        accel_bias_drift_m_s2: drift(&model.accel.noise),
        gyro_bias_drift_rad_s: drift(&model.gyro.noise),
        ..CalibrateOptions::default()
    };
    opts.accel.add(EffectKind::ScaleNonlinearity);
    opts.gyro.add(EffectKind::GSensitivity);
    let reference = Reference::TruthFile(truth.to_path_buf());
    let t = Instant::now();
    let fit = calibrate(&series, &reference, &opts).expect("calibrate");
    let calibrate_s = t.elapsed().as_secs_f64();
    let peak_kb = peak_rss_kb();

    let t = Instant::now();
    let segmentation = detect(&series, &SegmentOptions::default()).expect("segments");
    let segment_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    reference
        .segment_truth(&series, &segmentation.segments)
        .expect("truth");
    let truth_s = t.elapsed().as_secs_f64();

    println!("samples {}", series.len());
    println!("duration_h {:.2}", duration_s / 3600.0);
    println!("file_mib {:.1}", file_mib(recording));
    println!("truth_file_mib {:.1}", file_mib(truth));
    println!(
        "segments {} static, {} plateaus",
        segmentation.count(SegmentKind::Static),
        segmentation.count(SegmentKind::Plateau)
    );
    println!(
        "fit_iterations accel {} gyro {}",
        fit.accel.iterations, fit.gyro.iterations
    );
    println!("total_s {:.3}", read_s + calibrate_s);
    println!("read_s {read_s:.3}");
    println!("calibrate_s {calibrate_s:.3}");
    println!("segmentation_alone_s {segment_s:.3}");
    println!("truth_stream_alone_s {truth_s:.3}");
    println!(
        "peak_rss_after_read_mib {:.1}",
        rss_after_read_kb as f64 / 1024.0
    );
    println!("peak_rss_mib {:.1}", peak_kb as f64 / 1024.0);
}

fn file_mib(p: &Path) -> f64 {
    std::fs::metadata(p).map_or(0.0, |m| m.len() as f64 / 1048576.0)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--measure") {
        measure(Path::new(&args[i + 1]), Path::new(&args[i + 2]));
        return;
    }
    let (recording, truth) = recording();
    println!("calibrate_6h ({})", recording.display());
    // Three fresh processes (the machine may be shared): every run, then the median.
    const RUNS: usize = 3;
    let mut runs: Vec<Vec<(String, String)>> = Vec::new();
    for _ in 0..RUNS {
        let out = Command::new(std::env::current_exe().expect("own path"))
            .arg("--measure")
            .arg(&recording)
            .arg(&truth)
            .output()
            .expect("measurement process");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        runs.push(
            String::from_utf8_lossy(&out.stdout)
                .lines()
                .filter_map(|l| l.split_once(' '))
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
        );
    }
    for (i, (key, first)) in runs[0].iter().enumerate() {
        let values: Vec<&str> = runs.iter().map(|r| r[i].1.as_str()).collect();
        let mut numbers: Vec<f64> = values.iter().filter_map(|v| v.parse().ok()).collect();
        if numbers.len() == RUNS && values.iter().any(|v| *v != first) {
            numbers.sort_by(f64::total_cmp);
            println!(
                "{key:<22} {}   median {}",
                values.join(" "),
                numbers[RUNS / 2]
            );
        } else {
            println!("{key:<22} {first}");
        }
    }
}
