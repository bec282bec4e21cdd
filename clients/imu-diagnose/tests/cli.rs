//! End-to-end test of `imu-diagnose`: a short simulated index-table session whose truth hides a
//! gyro g-sensitivity is recorded through the daemon's offline pipeline; the ladder must add
//! gyro g-sensitivity, write a calibration imud loads and an HTML report with the ladder and
//! charts, and `--add gyro:g-sensitivity` must bring the gyro residual down.

use std::path::{Path, PathBuf};
use std::process::Command;

use imu_model::{Calibration, EffectKind};

fn config(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../config")
        .join(rel)
}

/// Records the workbench demo (2 x 12 index-table positions; its truth hides a gyro
/// g-sensitivity under bias, scale and misalignment); returns (recording, truth, base model:
/// bias + scale + misalignment on both triads).
fn record(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let s = imud::offline::record_session(
        dir,
        "t",
        &config("scenarios/workbench-demo.toml"),
        Some(&config("models/workbench-demo.toml")),
        11,
        None,
    )
    .unwrap();
    (
        s.recording,
        s.truth,
        config("models/bias-scale-misalignment.toml"),
    )
}

fn run(args: &[&std::ffi::OsStr]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-diagnose"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "imu-diagnose failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn gyro_rms(j: &serde_json::Value) -> f64 {
    let axes = j["diagnoses"][1]["axes"].as_array().unwrap();
    let sq: f64 = axes
        .iter()
        .map(|a| a["residual_rms"].as_f64().unwrap().powi(2))
        .sum();
    sq.sqrt()
}

#[test]
fn ladder_finds_the_hidden_gyro_g_sensitivity() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, truth, model) = record(dir.path());
    let cal_path = dir.path().join("cal.toml");
    let report = dir.path().join("r.html");

    let j = run(&[
        "ladder".as_ref(),
        rec.as_os_str(),
        "--reference".as_ref(),
        truth.as_os_str(),
        "-o".as_ref(),
        cal_path.as_os_str(),
        "--report".as_ref(),
        report.as_os_str(),
        "--json".as_ref(),
    ]);
    let steps = j["steps"].as_array().unwrap();
    let added: Vec<&serde_json::Value> = steps
        .iter()
        .map(|s| &s["added"])
        .filter(|a| !a.is_null())
        .collect();
    assert!(
        added.contains(&&serde_json::json!(["gyro", "g-sensitivity"])),
        "ladder added {added:?}"
    );
    for s in steps {
        for t in ["accel", "gyro"] {
            assert_eq!(s[t]["residual_rms"].as_array().unwrap().len(), 3);
            assert_eq!(s[t]["noise_floor_rms"].as_array().unwrap().len(), 3);
        }
    }
    let cal = Calibration::load(&cal_path).unwrap();
    assert!(cal.gyro.has(EffectKind::GSensitivity), "{cal:?}");
    assert_eq!(
        cal.provenance.procedure.as_deref(),
        Some("imu-diagnose ladder")
    );
    let html = std::fs::read_to_string(&report).unwrap();
    assert!(html.contains("The ladder"), "no ladder in the report");
    assert!(html.contains("g-sensitivity"));
    assert!(html.contains("<svg"));

    // Diagnose the base model, then with the hidden effect added.
    let base = run(&[
        rec.as_os_str(),
        "--reference".as_ref(),
        truth.as_os_str(),
        "--model".as_ref(),
        model.as_os_str(),
        "--json".as_ref(),
    ]);
    assert_eq!(
        base["diagnoses"][1]["consistent"], false,
        "{}",
        base["verdict"]
    );
    assert_eq!(
        base["candidates"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["triad"] == "gyro")
            .unwrap()["effect"],
        "g-sensitivity"
    );
    // Programs read the verdict and the explanation by their codes, beside the words.
    assert_eq!(base["verdict_codes"]["gyro"][0], "missing_effect");
    assert_eq!(
        base["verdict_codes"]["gyro"],
        base["diagnoses"][1]["verdict_codes"]
    );
    assert_eq!(
        base["candidates"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["triad"] == "gyro")
            .unwrap()["explanation_code"],
        "fitted"
    );
    let with = run(&[
        rec.as_os_str(),
        "--reference".as_ref(),
        truth.as_os_str(),
        "--model".as_ref(),
        model.as_os_str(),
        "--add".as_ref(),
        "gyro:g-sensitivity".as_ref(),
        "--json".as_ref(),
    ]);
    let (before, after) = (gyro_rms(&base), gyro_rms(&with));
    assert!(
        with["diagnoses"][1]["consistent_with_drift"] == true || after < 0.5 * before,
        "gyro residual {before:.3e} -> {after:.3e}: {}",
        with["verdict"]
    );
}

#[test]
fn bad_add_is_a_clear_error() {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-diagnose"))
        .args([
            "rec.mcap",
            "--reference",
            "t.mcap",
            "--add",
            "gyro:no-such-effect",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("unknown effect"), "{err}");
}

/// A model file with noise tables (a characterisation of the sensor's noise): they become the
/// noise floor, and the missing effect is still found.
#[test]
fn noise_tables_of_the_model_file_are_the_floor() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, truth, base) = record(dir.path());
    let truth_model = Calibration::load(&config("models/workbench-demo.toml")).unwrap();
    let mut model = Calibration::load(&base).unwrap();
    model.accel.noise = truth_model.accel.noise.clone();
    model.gyro.noise = truth_model.gyro.noise.clone();
    let model_path = dir.path().join("model-with-noise.toml");
    model.save(&model_path).unwrap();

    let j = run(&[
        rec.as_os_str(),
        "--reference".as_ref(),
        truth.as_os_str(),
        "--model".as_ref(),
        model_path.as_os_str(),
        "--json".as_ref(),
    ]);
    let gyro = &j["diagnoses"][1];
    assert_eq!(
        gyro["noise_floor"]["source"], "the given noise characterisation",
        "{gyro}"
    );
    let white = gyro["noise_floor"]["white_per_sqrt_hz"][0]
        .as_f64()
        .unwrap();
    assert_eq!(
        white,
        truth_model.gyro.noise.as_ref().unwrap().white_density[0]
    );
    assert_eq!(gyro["candidates"][0]["effect"], "g-sensitivity", "{gyro}");
    assert_eq!(gyro["candidates"][0]["claimed"], true, "{gyro}");
}

/// Without a reference: 36 hand-held still poses (config/scenarios/workbench-poses.toml) of the
/// workbench demo's truth (a gyro g-sensitivity hidden under bias, scale and misalignment). The
/// ladder must find the g-sensitivity from the still poses alone and write a calibration with
/// it and with the gyro gains fitted from the moves.
#[test]
fn reference_free_ladder_finds_the_hidden_gyro_g_sensitivity() {
    let dir = tempfile::tempdir().unwrap();
    let s = imud::offline::record_session(
        dir.path(),
        "t",
        &config("scenarios/workbench-poses.toml"),
        None,
        41,
        None,
    )
    .unwrap();
    let cal_path = dir.path().join("cal.toml");
    let j = run(&[
        "ladder".as_ref(),
        s.recording.as_os_str(),
        "--reference-free".as_ref(),
        "--latitude-deg".as_ref(),
        "40".as_ref(),
        "-o".as_ref(),
        cal_path.as_os_str(),
        "--json".as_ref(),
    ]);
    let added: Vec<&serde_json::Value> = j["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| &s["added"])
        .filter(|a| !a.is_null())
        .collect();
    assert_eq!(
        added,
        vec![&serde_json::json!(["gyro", "g-sensitivity"])],
        "{}",
        j["verdict"]
    );
    assert!(j["reference"].as_str().unwrap().contains("reference-free"));
    assert!(
        j["notes"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n.as_str().unwrap().contains("gravity magnitude")),
        "{}",
        j["notes"]
    );
    let cal = Calibration::load(&cal_path).unwrap();
    assert!(cal.gyro.has(EffectKind::GSensitivity), "{cal:?}");
    assert!(
        cal.gyro.has(EffectKind::Scale),
        "gyro gains from the moves: {cal:?}"
    );
    assert_eq!(
        cal.provenance.procedure.as_deref(),
        Some("imu-diagnose ladder --reference-free")
    );
    // The fitted g-sensitivity agrees with the hidden one on its largest entry.
    let truth = Calibration::load(&config("models/workbench-demo.toml")).unwrap();
    let names = cal.gyro.param_names(imu_model::Triad::Gyro);
    let zz = names.iter().position(|n| n == "g-sensitivity.zz").unwrap();
    let tz = truth
        .gyro
        .param_names(imu_model::Triad::Gyro)
        .iter()
        .position(|n| n == "g-sensitivity.zz")
        .unwrap();
    let (fit, want) = (cal.gyro.params()[zz], truth.gyro.params()[tz]);
    let se = cal.gyro.std_errors()[zz].expect("fitted with a standard error");
    assert!(
        (fit - want).abs() < 4.0 * se,
        "g-sensitivity.zz {fit:.3e} +/- {se:.1e}, truth {want:.3e}"
    );
}

/// Exactly one truth source; the reference-free options only with --reference-free; a
/// reference log's clock offset is not a second source.
#[test]
fn truth_source_arguments_are_checked() {
    let args = |a: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_imu-diagnose"))
            .args(a)
            .output()
            .unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let e = args(&["rec.mcap", "--plan", "p.toml", "--reference-free"]);
    assert!(e.contains("cannot be used with"), "{e}");
    let e = args(&["rec.mcap", "--reference", "l.csv", "--latitude-deg", "40"]);
    assert!(e.contains("cannot be used with"), "{e}");
    let e = args(&["rec.mcap"]);
    assert!(e.contains("--reference-free"), "{e}");
    let e = args(&[
        "rec.mcap",
        "--reference",
        "l.csv",
        "--reference-offset-s",
        "0.5",
    ]);
    assert!(!e.contains("cannot be used with"), "{e}");
    assert!(e.contains("rec.mcap"), "{e}");
}

/// The claim's held-out check reaches the user: in `--json` (the candidate's `held_out`, with
/// the held-out RMS lower with the effect than without) and in the text under the candidate.
#[test]
fn the_claim_shows_its_held_out_check_in_json_and_text() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, truth, model) = record(dir.path());
    let args = [
        rec.as_os_str(),
        "--reference".as_ref(),
        truth.as_os_str(),
        "--model".as_ref(),
        model.as_os_str(),
    ];
    let mut json_args = args.to_vec();
    json_args.push("--json".as_ref());
    let j = run(&json_args);
    let c = j["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["claimed"] == true)
        .unwrap();
    assert_eq!(c["effect"], "g-sensitivity");
    let h = &c["held_out"];
    assert_eq!(h["confirmed"], true, "{h}");
    assert_eq!(h["scheme"], "k-fold", "{h}");
    let sq = |k: &str| -> f64 {
        h[k].as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap().powi(2))
            .sum()
    };
    assert!(sq("held_out_rms_after") < sq("held_out_rms_before"), "{h}");
    // Candidates that were not put to the test carry no held_out.
    assert!(
        j["candidates"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|c| c["claimed"] == false)
            .all(|c| c.get("held_out").is_none())
    );

    let out = Command::new(env!("CARGO_BIN_EXE_imu-diagnose"))
        .args(args)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("held-out (5-fold over segments): weighted RMS")
            && text.contains("confirmed on held-out data"),
        "{text}"
    );
}
