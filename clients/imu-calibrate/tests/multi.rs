//! Several recordings in one `imu-calibrate` fit: an index-table session and a rate-table
//! session of the same simulated unit (the shipped scenarios, different seeds, each its own
//! power-on) are fitted jointly, each against its own reference. Every fitted parameter must lie
//! within 3 standard errors of the hidden truth model, and the joint fit must give what neither
//! file gives alone: the accel misalignment and nonlinearity (index table) and the gyro scale
//! (rate table). References must be one per recording, and a missing one is named.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn truth_model() -> PathBuf {
    repo().join("config/models/example-3dm-gx1.toml")
}

/// Runs the binary; (success, stdout, stderr).
fn run_cli(args: &[OsString]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_imu-calibrate"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8(o.stdout).unwrap(),
        String::from_utf8(o.stderr).unwrap(),
    )
}

fn args(items: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<OsString> {
    items.iter().map(|s| s.as_ref().to_os_string()).collect()
}

/// Runs with `--json`, asserting success; the parsed output.
fn run_json(items: &[&dyn AsRef<std::ffi::OsStr>]) -> serde_json::Value {
    let mut a = args(items);
    a.push("--json".into());
    let (ok, out, err) = run_cli(&a);
    assert!(ok, "{err}");
    serde_json::from_str(&out).unwrap()
}

/// Error in standard errors of `triad name` (None when not fitted or absent).
fn z(j: &serde_json::Value, triad: &str, name: &str) -> Option<f64> {
    j["truth_comparison"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["triad"] == triad && r["name"] == name)
        .and_then(|r| r["error_in_se"].as_f64())
}

fn std_error(j: &serde_json::Value, triad: &str, name: &str) -> f64 {
    j["truth_comparison"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["triad"] == triad && r["name"] == name)
        .and_then(|r| r["std_error"].as_f64())
        .unwrap_or_else(|| panic!("{triad} {name} not fitted"))
}

/// Every fitted parameter within 3 standard errors; returns how many were fitted.
fn fitted_within_3_se(label: &str, j: &serde_json::Value) -> usize {
    let mut fitted = 0;
    for r in j["truth_comparison"].as_array().unwrap() {
        if let Some(z) = r["error_in_se"].as_f64() {
            fitted += 1;
            eprintln!(
                "{label}: {} {:<32} fitted {:>12.4e} truth {:>12.4e} z {z:>6.2}",
                r["triad"].as_str().unwrap(),
                r["name"].as_str().unwrap(),
                r["fitted"].as_f64().unwrap(),
                r["truth"].as_f64().unwrap()
            );
            assert!(z.abs() < 3.0, "{label}: {} {}: {r}", r["triad"], r["name"]);
        }
    }
    fitted
}

const AXES: [&str; 3] = ["x", "y", "z"];
const MISALIGNMENT: [&str; 6] = ["xy", "xz", "yx", "yz", "zx", "zy"];

#[test]
fn an_index_table_and_a_rate_table_session_fit_jointly_within_their_standard_errors() {
    let dir = tempfile::tempdir().unwrap();
    let scenarios = repo().join("config/scenarios");
    let index = imud::offline::record_session(
        dir.path(),
        "index",
        &scenarios.join("index-table-12pos.toml"),
        Some(&truth_model()),
        11,
        None,
    )
    .unwrap();
    let rate = imud::offline::record_session(
        dir.path(),
        "rate",
        &scenarios.join("rate-table.toml"),
        Some(&truth_model()),
        4,
        None,
    )
    .unwrap();
    // What to fit: the shipped fit model (accel bias, scale, misalignment and the nonlinearity
    // the truth hides; gyro bias, scale, misalignment, g-sensitivity; the 3DM-GX1's noise).
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/fit-3dm-gx1.toml");
    let cal_path = dir.path().join("cal.toml");
    let truth = truth_model();

    // Jointly, each against its simulator truth.
    let joint = run_json(&[
        &index.recording,
        &rate.recording,
        &"--reference",
        &index.truth,
        &"--reference",
        &rate.truth,
        &"--model",
        &model,
        &"--truth",
        &truth,
        &"-o",
        &cal_path,
    ]);
    let n = fitted_within_3_se("joint", &joint);
    // The accel misalignment and quadratic nonlinearity need the index table's many gravity
    // directions; the gyro scale and misalignment need the rate table's plateaus.
    for m in MISALIGNMENT {
        let name = format!("misalignment.{m}");
        assert!(z(&joint, "accel", &name).is_some(), "accel {name}");
        assert!(z(&joint, "gyro", &name).is_some(), "gyro {name}");
    }
    for a in AXES {
        let q = format!("scale-nonlinearity.quadratic.{a}");
        assert!(z(&joint, "accel", &q).is_some(), "accel {q}");
        let s = format!("scale.{a}");
        assert!(z(&joint, "gyro", &s).is_some(), "gyro {s}");
    }
    // accel 3 + 3 + 6 + 3 quadratic (+ cubic where observable), gyro 3 + 3 + 6 + 9.
    assert!(n >= 15 + 21, "{n} fitted");
    // Which recordings contributed, and how.
    let recs = joint["recordings"].as_array().unwrap();
    assert_eq!(recs.len(), 2);
    assert_eq!(
        recs[0]["recording"].as_str().unwrap(),
        index.recording.display().to_string()
    );
    assert_eq!(recs[0]["static_segments"], 24);
    assert_eq!(recs[0]["rate_plateaus"], 0);
    assert_eq!(recs[1]["static_segments"], 9);
    assert_eq!(recs[1]["rate_plateaus"], 42);
    assert_eq!(recs[0]["accel_points"], 24);
    assert_eq!(recs[1]["gyro_points"], 9 + 42);
    assert!(joint.get("recording").is_none(), "{joint}");
    // `--json` has each note's code beside its sentence, in the same order.
    let codes = joint["fit"]["note_codes"].as_array().expect("note_codes");
    assert_eq!(
        codes.len(),
        joint["fit"]["notes"].as_array().expect("notes").len()
    );
    assert!(codes.iter().any(|c| c == "joint_biases"), "{codes:?}");
    let notes = joint["fit"]["notes"].to_string();
    assert!(
        notes.contains("2 recordings fitted together")
            && notes.contains("the gyro bias is taken as the same in all 2 recordings"),
        "{notes}"
    );
    // The calibration file names every input with its hash, recording before its reference.
    let cal = imu_model::Calibration::load(&cal_path).unwrap();
    let inputs: Vec<&str> = cal
        .provenance
        .inputs
        .iter()
        .map(|i| i.path.as_str())
        .collect();
    let want: Vec<String> = [&index.recording, &index.truth, &rate.recording, &rate.truth]
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    assert_eq!(inputs, want);
    for input in &cal.provenance.inputs {
        let out = Command::new("sha256sum").arg(&input.path).output().unwrap();
        let want = String::from_utf8_lossy(&out.stdout);
        let want = want.split_whitespace().next().unwrap();
        assert_eq!(input.sha256.as_deref(), Some(want), "{}", input.path);
    }
    assert!(
        cal.description
            .as_deref()
            .unwrap()
            .ends_with("of 2 recordings"),
        "{:?}",
        cal.description
    );

    // The table output names each recording, its reference and what it gave.
    let (ok, table, err) = run_cli(&args(&[
        &index.recording,
        &rate.recording,
        &"--reference",
        &index.truth,
        &"--reference",
        &rate.truth,
        &"--model",
        &model,
    ]));
    assert!(ok, "{err}");
    eprintln!("{table}");
    for (k, rec, plateaus, points) in [
        (1, &index.recording, 0, "24 accel, 24 gyro"),
        (2, &rate.recording, 42, "9 accel, 51 gyro"),
    ] {
        let head = format!("recording {k}: {}", rec.display());
        let at = table
            .find(&head)
            .unwrap_or_else(|| panic!("{head}\n{table}"));
        let block: String = table[at..].lines().take(4).collect::<Vec<_>>().join("\n");
        assert!(block.contains("  reference: simulator truth"), "{block}");
        assert!(
            block.contains(&format!("static, {plateaus} rate plateaus")),
            "{block}"
        );
        assert!(block.contains(&format!("  points: {points}")), "{block}");
    }

    // Neither file alone gives all of it: the index table no gyro gains ...
    let alone = |rec: &Path, reference: &Path| {
        run_json(&[
            &rec,
            &"--reference",
            &reference,
            &"--model",
            &model,
            &"--truth",
            &truth,
        ])
    };
    let index_only = alone(&index.recording, &index.truth);
    fitted_within_3_se("index table alone", &index_only);
    for a in AXES {
        assert!(z(&index_only, "gyro", &format!("scale.{a}")).is_none());
    }
    // ... and the rate table (gravity along +x, +y and +z only) not the accel misalignment
    // and nonlinearity.
    let rate_only = alone(&rate.recording, &rate.truth);
    let accel_shape: Vec<String> = MISALIGNMENT
        .iter()
        .map(|m| format!("misalignment.{m}"))
        .chain(
            AXES.iter()
                .map(|a| format!("scale-nonlinearity.quadratic.{a}")),
        )
        .collect();
    let fitted_alone = accel_shape
        .iter()
        .filter(|n| z(&rate_only, "accel", n).is_some())
        .count();
    assert!(
        fitted_alone < accel_shape.len(),
        "the rate table alone fitted all accel misalignment and nonlinearity"
    );
    // The joint gyro gains are as good as the rate table's own (the index table adds bias and
    // g-sensitivity information, not gain information).
    for a in AXES {
        let s = format!("scale.{a}");
        let ratio = std_error(&joint, "gyro", &s) / std_error(&rate_only, "gyro", &s);
        assert!(
            ratio < 1.2,
            "gyro {s}: joint SE {ratio:.2} x the rate table's"
        );
    }

    // Mixed references: the index table by its test plan, the rate table by its truth; a
    // turn-on bias repeatability widens the biases (the mean over power-ons) and says so.
    let plan = repo().join("config/plans/index-table-12pos.toml");
    let mixed = run_json(&[
        &index.recording,
        &"--plan",
        &plan,
        &rate.recording,
        &"--reference",
        &rate.truth,
        &"--model",
        &model,
        &"--truth",
        &truth,
        &"--gyro-turn-on-bias-rad-s",
        &"1e-3",
    ]);
    let recs = mixed["recordings"].as_array().unwrap();
    assert!(
        recs[0]["reference_description"]
            .as_str()
            .unwrap()
            .starts_with("test plan"),
        "{}",
        recs[0]
    );
    assert!(
        recs[1]["reference_description"]
            .as_str()
            .unwrap()
            .starts_with("simulator truth"),
        "{}",
        recs[1]
    );
    let notes = mixed["fit"]["notes"].to_string();
    assert!(
        notes.contains("recording 1 (") && notes.contains("plan "),
        "{notes}"
    );
    assert!(
        notes.contains("the gyro bias is the mean over the 2 power-ons"),
        "{notes}"
    );
    for a in AXES {
        let b = format!("bias.{a}");
        let se = std_error(&mixed, "gyro", &b);
        // Two power-ons with 1e-3 rad/s each: at least 1e-3 / sqrt(2).
        assert!(se > 0.7e-3, "gyro {b}: SE {se:e}");
        let zb = z(&mixed, "gyro", &b).unwrap();
        assert!(zb.abs() < 3.0, "gyro {b}: {zb}");
    }
}

#[test]
fn each_recording_needs_its_own_reference() {
    // The references are matched before any file is read: the paths need not exist.
    let (ok, _, err) = run_cli(&args(&[
        &"index.mcap",
        &"rate.mcap",
        &"--plan",
        &"index-table-12pos.toml",
    ]));
    assert!(!ok);
    assert!(
        err.contains(
            "recording 2 (rate.mcap) has no reference: 2 recordings but 1 reference (--plan \
             index-table-12pos.toml); give one --plan or --reference per recording"
        ),
        "{err}"
    );
    let (ok, _, err) = run_cli(&args(&[
        &"a.mcap",
        &"--reference",
        &"a.csv",
        &"b.mcap",
        &"--plan",
        &"b.toml",
        &"--reference-offset-s",
        &"2.5",
    ]));
    assert!(!ok);
    assert!(
        err.contains("--reference-offset-s 2.5 follows --plan b.toml"),
        "{err}"
    );
    let (ok, _, err) = run_cli(&args(&[&"a.mcap", &"b.mcap", &"--reference-free"]));
    assert!(!ok);
    assert!(
        err.contains("--reference-free takes one recording, got 2"),
        "{err}"
    );
}
