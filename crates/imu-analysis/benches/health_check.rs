//! The offline health check's speed on a 1-hour 100 Hz recording (the fleet job's per-recording
//! cost, issue 29): `cargo bench -p imu-analysis --bench health_check --profile test` (or
//! without `--profile test` for release).
//!
//! The recording (`config/scenarios/health-hour.toml`: 150 rests of 20 s, moved for 4 s between
//! them, under its truth model as the calibration) is made once through imud's offline path
//! and cached under the target directory. Reading the MCAP is timed apart from the check.

use std::path::{Path, PathBuf};
use std::time::Instant;

use imu_analysis::health::{CheckOptions, check_series};
use imu_analysis::input::{CsvOptions, Source, read_any};
use imu_model::Calibration;
use imu_sim::SimOptions;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// The cached recording, made on first use.
fn recording() -> PathBuf {
    let dir = repo("target/bench-data/health-hour");
    let done = dir.join("recording.path");
    if let Ok(p) = std::fs::read_to_string(&done)
        && Path::new(p.trim()).is_file()
    {
        return PathBuf::from(p.trim());
    }
    let _ = std::fs::remove_dir_all(&dir);
    let mut sim = SimOptions::from_files(&repo("config/scenarios/health-hour.toml"), None).unwrap();
    sim.seed = 1;
    let mut config = imud::config::Config {
        name: "health-hour".into(),
        ..imud::config::Config::default()
    };
    config.log.dir = dir.clone();
    config.calibration.path = Some(repo("config/models/example-3dm-gx1.toml"));
    let t = Instant::now();
    let out = imud::offline::record(sim, &config).unwrap();
    eprintln!("recorded in {:.1} s", t.elapsed().as_secs_f64());
    let path = out.files[0].clone();
    std::fs::write(&done, path.display().to_string()).unwrap();
    path
}

fn main() {
    let path = recording();
    let calibration = Calibration::load(&repo("config/models/example-3dm-gx1.toml")).unwrap();
    let t = Instant::now();
    let series = read_any(&path, Source::Corrected, &CsvOptions::default()).unwrap();
    let read_s = t.elapsed().as_secs_f64();
    let options = CheckOptions::at(Some(40.0), 0.0, Some(9.80665), 1e-4);
    let mut best_s = f64::INFINITY;
    let mut windows = 0;
    for _ in 0..5 {
        let t = Instant::now();
        let c = check_series(&series, Some(&calibration), &options);
        best_s = best_s.min(t.elapsed().as_secs_f64());
        windows = c.windows.len();
        assert!(c.gyro_offset_rad_s.iter().all(|v| v.is_finite()));
    }
    let n = series.len() as f64;
    println!(
        "health check of {} samples ({windows} still windows): read {read_s:.3} s; check best of 5 {best_s:.4} s = {:.2} M samples/s",
        series.len(),
        n / best_s / 1e6
    );
}
