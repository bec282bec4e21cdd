//! imud's rotated files of one session given to `imu-calibrate` one by one, in any order and
//! next to another recording: the files that chain (same recorder prefix and device,
//! consecutive file indices, in time order) are one recording, the other file stays a recording
//! of its own with its own reference. The fit equals the one from the session's directory, and
//! every fitted parameter lies within 3 standard errors of the hidden truth model. And
//! `--reference-free`, which takes one recording, takes the rotated files of one session.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Records shipped scenario `scenario` with seed `seed` into `dir/name`, rotating files at
/// `rotate_mib`: (the recording files in index order, the truth file).
fn record(
    dir: &Path,
    name: &str,
    scenario: &str,
    seed: u64,
    rotate_mib: u64,
) -> (Vec<PathBuf>, PathBuf) {
    let scenario = repo().join("config/scenarios").join(scenario);
    let truth_model = repo().join("config/models/example-3dm-gx1.toml");
    let mut sim = imu_sim::SimOptions::from_files(&scenario, Some(&truth_model)).unwrap();
    sim.seed = seed;
    let truth = dir.join(format!("{name}-truth.mcap"));
    sim.truth_out = Some(truth.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.join(name);
    c.log.rotate_size_mib = rotate_mib;
    c.name = name.into();
    let mut files = imud::offline::record(sim, &c).unwrap().files;
    files.sort();
    (files, truth)
}

/// Runs the binary with `--json`, asserting success; the parsed output.
fn run_json(args: &[OsString]) -> serde_json::Value {
    let o = Command::new(env!("CARGO_BIN_EXE_imu-calibrate"))
        .args(args)
        .arg("--json")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    serde_json::from_slice(&o.stdout).unwrap()
}

fn os(items: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<OsString> {
    items.iter().map(|s| s.as_ref().to_os_string()).collect()
}

#[test]
fn rotated_files_in_any_order_are_one_recording_beside_another() {
    let dir = tempfile::tempdir().unwrap();
    let (index, index_truth) = record(dir.path(), "index", "index-table-12pos.toml", 11, 8);
    assert!(index.len() >= 3, "rotation made {index:?}");
    let (rate, rate_truth) = record(dir.path(), "rate", "rate-table.toml", 4, 512);
    assert_eq!(rate.len(), 1);
    let model = repo().join("config/models/fit-3dm-gx1.toml");
    let truth = repo().join("config/models/example-3dm-gx1.toml");
    let tail = os(&[
        &"--reference",
        &index_truth,
        &"--reference",
        &rate_truth,
        &"--model",
        &model,
        &"--truth",
        &truth,
    ]);
    // The session's last file first, the other recording among its files.
    let mut given: Vec<OsString> = vec![
        index[index.len() - 1].clone().into(),
        rate[0].clone().into(),
    ];
    given.extend(
        index[..index.len() - 1]
            .iter()
            .rev()
            .map(|p| p.clone().into()),
    );
    let by_files = run_json(&[given, tail.clone()].concat());
    let by_dir = run_json(&[os(&[&dir.path().join("index"), &rate[0]]), tail].concat());

    let recs = by_files["recordings"].as_array().unwrap();
    assert_eq!(recs.len(), 2, "{by_files}");
    let files: Vec<PathBuf> = recs[0]["input"]["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| PathBuf::from(f.as_str().unwrap()))
        .collect();
    assert_eq!(files, index, "the session's files in time order");
    assert!(recs[0]["input"]["gaps"].as_array().unwrap().is_empty());
    assert_eq!(recs[0]["static_segments"], 24);
    assert_eq!(recs[1]["input"]["files"].as_array().unwrap().len(), 1);
    assert_eq!(recs[1]["rate_plateaus"], 42);
    // The same samples as the directory: the same fit, number for number.
    assert_eq!(by_files["fit"]["accel"], by_dir["fit"]["accel"]);
    assert_eq!(by_files["fit"]["gyro"], by_dir["fit"]["gyro"]);
    let rows = by_files["truth_comparison"].as_array().unwrap();
    let mut fitted = 0;
    for r in rows {
        if let Some(z) = r["error_in_se"].as_f64() {
            fitted += 1;
            assert!(z.abs() < 3.0, "{r}");
        }
    }
    assert!(fitted >= 15 + 21, "{fitted} fitted");
}

/// `--reference-free` takes one recording: the rotated files of one session, in any order, are
/// one, and give the poses and moves the single file gives.
#[test]
fn reference_free_takes_a_session_of_rotated_files() {
    let dir = tempfile::tempdir().unwrap();
    let (files, _) = record(dir.path(), "hand", "hand-held-raw.toml", 23, 1);
    assert!(files.len() >= 3, "rotation made {files:?}");
    let (whole, _) = record(dir.path(), "whole", "hand-held-raw.toml", 23, 512);
    assert_eq!(whole.len(), 1);
    let common = os(&[&"--reference-free", &"--latitude-deg", &"40"]);
    let mut shuffled: Vec<OsString> = files.iter().rev().map(|p| p.clone().into()).collect();
    shuffled.extend(common.clone());
    let by_files = run_json(&shuffled);
    let by_one = run_json(&[os(&[&whole[0]]), common].concat());
    let listed: Vec<PathBuf> = by_files["input"]["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| PathBuf::from(f.as_str().unwrap()))
        .collect();
    assert_eq!(listed, files);
    for key in ["poses", "moves"] {
        assert_eq!(
            by_files["fit"][key].as_array().unwrap().len(),
            by_one["fit"][key].as_array().unwrap().len(),
            "{key}"
        );
    }
    assert_eq!(by_files["fit"]["poses"].as_array().unwrap().len(), 41);
    // The same samples: the same fit.
    assert_eq!(by_files["fit"]["accel"], by_one["fit"]["accel"]);
}
