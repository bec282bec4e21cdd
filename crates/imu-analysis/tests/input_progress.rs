//! The progress callback of the input readers: monotone byte counts from 0 to the file size,
//! and the same series as the plain readers.

use std::path::Path;

use imu_analysis::input::{CsvOptions, Source, read_any, read_any_with_progress};

const SCENARIO: &str = r#"
name = "progress"
rate-hz = 100.0
[[segment]]
kind = "static"
orientation = { x = "north", z = "up" }
duration-s = 30.0
"#;

/// Every call as `(done, total)`.
fn calls(path: &Path, source: Source) -> Vec<(u64, u64)> {
    let mut calls = Vec::new();
    let series = read_any_with_progress(path, source, &CsvOptions::default(), &mut |d, t| {
        calls.push((d, t))
    })
    .unwrap();
    assert_eq!(
        series,
        read_any(path, source, &CsvOptions::default()).unwrap()
    );
    calls
}

fn check(calls: &[(u64, u64)], path: &Path) {
    let size = std::fs::metadata(path).unwrap().len();
    assert_eq!(calls.first(), Some(&(0, size)), "{calls:?}");
    assert_eq!(calls.last(), Some(&(size, size)), "{calls:?}");
    for w in calls.windows(2) {
        assert!(w[0].0 <= w[1].0, "not monotone: {w:?}");
        assert_eq!(w[1].1, size);
    }
}

#[test]
fn progress_is_monotone_and_reaches_the_file_size() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("scenario.toml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let sim = imu_sim::SimOptions::from_files(&scenario, None).unwrap();
    let mut config = imud::config::Config::default();
    config.log.dir = dir.path().join("log");
    config.name = "p".into();
    let out = imud::offline::record(sim, &config).unwrap();
    let mcap = &out.files[0];
    for source in [Source::Raw, Source::Corrected] {
        let c = calls(mcap, source);
        check(&c, mcap);
        // A 30 s recording spans several reads, so the bar moves.
        assert!(c.len() > 3, "{c:?}");
    }

    let csv = dir.path().join("series.csv");
    std::fs::write(
        &csv,
        "t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.01,0,0,9.8,0,0,0\n",
    )
    .unwrap();
    check(&calls(&csv, Source::Raw), &csv);
}
