//! End-to-end test of `imu-calibrate`: a simulated index-table + rate-table recording through
//! the daemon's offline pipeline, calibrated against the simulator's truth; the written file
//! loads, and every fitted parameter is within 3 standard errors of the truth model.

use std::ffi::{OsStr, OsString};
use std::path::{Path, PathBuf};
use std::process::Command;

fn model_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/example-3dm-gx1.toml")
}

#[test]
fn calibrates_a_simulated_recording_within_its_standard_errors() {
    let dir = tempfile::tempdir().unwrap();
    // The shipped session: index-table sweeps, then a rate table on each axis.
    let scenario = repo().join("config/scenarios/calibration-session.toml");
    let mut sim = imu_sim::SimOptions::from_files(&scenario, Some(&model_path())).unwrap();
    sim.seed = 17;
    let truth_path = dir.path().join("truth.mcap");
    sim.truth_out = Some(truth_path.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.path().join("log");
    c.name = "t".into();
    let out = imud::offline::record(sim, &c).unwrap();
    // What to fit: the shipped fit model (accel bias, scale, misalignment and the nonlinearity
    // the truth hides; gyro bias, scale, misalignment, g-sensitivity; the 3DM-GX1's noise).
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/fit-3dm-gx1.toml");
    let cal_path = dir.path().join("cal.toml");

    let run = |json: bool| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_imu-calibrate"));
        cmd.arg(&out.files[0])
            .arg("--reference")
            .arg(&truth_path)
            .arg("--model")
            .arg(&model)
            .arg("--truth")
            .arg(model_path())
            .arg("-o")
            .arg(&cal_path);
        if json {
            cmd.arg("--json");
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8(o.stdout).unwrap()
    };
    let table = run(false);
    eprintln!("{table}");
    assert!(table.contains("fitted vs truth"));
    assert!(table.contains("rate plateaus"));

    let j: serde_json::Value = serde_json::from_str(&run(true)).unwrap();
    let rows = j["truth_comparison"].as_array().unwrap();
    let mut fitted = 0;
    for r in rows {
        let name = format!("{} {}", r["triad"], r["name"]);
        if let Some(z) = r["error_in_se"].as_f64() {
            fitted += 1;
            assert!(z.abs() < 3.0, "{name}: {r}");
        } else {
            // Only the cubic nonlinearity may be unobservable with 60-degree steps.
            assert!(name.contains("cubic"), "{name} not fitted: {r}");
        }
    }
    // accel 3+3+6+6 (minus <= 2 cubic), gyro 3+3+6+9.
    assert!(fitted >= 16 + 21, "{fitted} of {}", rows.len());
    // Results as data: one entry per parameter with its typed id beside the parallel columns,
    // a stable code beside every held parameter's and every warning's sentence.
    for triad in ["accel", "gyro"] {
        let f = &j["fit"][triad];
        let params = f["parameters"].as_array().unwrap();
        assert_eq!(params.len(), f["names"].as_array().unwrap().len());
        for (i, p) in params.iter().enumerate() {
            assert_eq!(p["name"], f["names"][i], "{triad}");
            assert_eq!(p["value"], f["params"][i], "{triad}");
            assert!(
                p["id"]["effect"].is_string() && p["id"]["role"].is_string(),
                "{p}"
            );
        }
        for u in f["unobservable"].as_array().unwrap() {
            assert!(u["code"].is_string() && u["reason"].is_string(), "{u}");
        }
        assert_eq!(
            f["warning_codes"].as_array().unwrap().len(),
            f["warnings"].as_array().unwrap().len(),
            "{triad}"
        );
    }
    assert!(
        j["fit"]["recordings"][0]["segmentation"]["segments"]
            .as_array()
            .unwrap()
            .len()
            >= 12 + 12
    );
    // The one-recording field scripts read is still there.
    assert_eq!(
        j["fit"]["segmentation"],
        j["fit"]["recordings"][0]["segmentation"]
    );

    let cal = imu_model::Calibration::load(&cal_path).unwrap();
    assert!(cal.gyro.has(imu_model::EffectKind::GSensitivity));
    assert!(cal.accel.residual_rms.is_some());
    let inputs = &cal.provenance.inputs;
    assert_eq!(inputs.len(), 2);
    // Each input's hash equals what coreutils' sha256sum says of the file.
    for input in inputs {
        let out = Command::new("sha256sum").arg(&input.path).output().unwrap();
        let want = String::from_utf8_lossy(&out.stdout);
        let want = want.split_whitespace().next().unwrap();
        assert_eq!(input.sha256.as_deref(), Some(want), "{}", input.path);
    }
    assert!(cal.provenance.created.as_ref().unwrap().ends_with('Z'));
    // The temperatures the data covered (the simulator's constant 25 C, read back through the
    // device's temperature word).
    let [lo, hi] = cal
        .provenance
        .temperature_range_c
        .expect("temperature range");
    assert!(
        lo <= hi && (lo - 25.0).abs() < 0.5 && (hi - 25.0).abs() < 0.5,
        "{lo} {hi}"
    );
}

/// What to fit from an index table alone: the accel model with its nonlinearity, and only the
/// gyro bias (g-sensitivity from statics needs north known, as in the Table 1 plan; the gains
/// need rate plateaus).
const INDEX_MODEL: &str = r#"
format = "imud-calibration/1"
[accel.bias]
value = [0.0, 0.0, 0.0]
[accel.scale]
value = [0.0, 0.0, 0.0]
[accel.misalignment]
[accel.scale-nonlinearity]
quadratic = [0.0, 0.0, 0.0]
cubic = [0.0, 0.0, 0.0]
[gyro.bias]
value = [0.0, 0.0, 0.0]
[accel.noise]
white-density = [1.5e-3, 1.5e-3, 1.8e-3]
bias-instability = [1.27e-3, 9.8e-4, 4.2e-4]
bias-instability-tau-max-s = 1000.0
random-walk = [2.0e-5, 2.0e-5, 2.0e-5]
quantization-lsb = [2.1e-3, 2.1e-3, 2.1e-3]
[gyro.noise]
white-density = [1.0e-3, 1.0e-3, 1.0e-3]
bias-instability = [2.4e-4, 2.4e-4, 2.4e-4]
bias-instability-tau-max-s = 1000.0
random-walk = [1.0e-5, 1.0e-5, 1.0e-5]
quantization-lsb = [2.6e-4, 2.6e-4, 2.6e-4]
"#;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Records a shipped scenario through the offline pipeline: (dir, recording, truth file).
fn record_shipped(scenario: &str, seed: u64) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = repo().join("config/scenarios").join(scenario);
    let mut sim = imu_sim::SimOptions::from_files(&path, None).unwrap();
    sim.seed = seed;
    let truth_path = dir.path().join("truth.mcap");
    sim.truth_out = Some(truth_path.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.path().join("log");
    c.name = "t".into();
    let out = imud::offline::record(sim, &c).unwrap();
    assert_eq!(out.files.len(), 1);
    let rec = out.files[0].clone();
    (dir, rec, truth_path)
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

/// Every fitted parameter of a `--json --truth` run within 3 standard errors; returns how
/// many were fitted.
fn fitted_within_3_se(json: &serde_json::Value) -> usize {
    let mut fitted = 0;
    for r in json["truth_comparison"].as_array().unwrap() {
        if let Some(z) = r["error_in_se"].as_f64() {
            fitted += 1;
            assert!(z.abs() < 3.0, "{} {}: {r}", r["triad"], r["name"]);
        }
    }
    fitted
}

#[test]
fn calibrates_real_hardware_style_with_a_plan_or_a_reference_log() {
    // The shipped index-table scenario and its shipped plan: no truth file involved.
    let (dir, rec, truth_path) = record_shipped("index-table-12pos.toml", 11);
    let plan = repo().join("config/plans/index-table-12pos.toml");
    let model = dir.path().join("model.toml");
    std::fs::write(&model, INDEX_MODEL).unwrap();
    let cal_path = dir.path().join("cal.toml");
    let truth_model = model_path();
    let base: Vec<OsString> = vec![
        rec.clone().into(),
        "--model".into(),
        model.clone().into(),
        "--truth".into(),
        truth_model.into(),
    ];
    let with = |extra: &[&OsStr]| -> Vec<OsString> {
        base.iter()
            .cloned()
            .chain(extra.iter().map(|s| s.to_os_string()))
            .collect()
    };

    let (ok, table, err) = run_cli(&with(&["--plan".as_ref(), plan.as_os_str()]));
    assert!(ok, "{err}");
    eprintln!("{table}");
    assert!(table.contains("reference: test plan"), "{table}");
    assert!(
        table.contains("segments: 24 static, 0 rate plateaus"),
        "{table}"
    );
    assert!(
        table.contains("note: Earth's rate is not fully known"),
        "{table}"
    );

    let (ok, out, err) = run_cli(&with(&[
        "--plan".as_ref(),
        plan.as_os_str(),
        "--json".as_ref(),
        "-o".as_ref(),
        cal_path.as_os_str(),
    ]));
    assert!(ok, "{err}");
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    // accel 18 (cubic nonlinearity is observable with 30-degree steps), gyro bias.
    assert_eq!(fitted_within_3_se(&j), 18 + 3);
    // The same as against the simulator's truth (the accel exactly; the gyro bias within the
    // Earth rate the plan cannot know without north).
    let (ok, out, err) = run_cli(&with(&[
        "--reference".as_ref(),
        truth_path.as_os_str(),
        "--json".as_ref(),
    ]));
    assert!(ok, "{err}");
    let by_truth: serde_json::Value = serde_json::from_str(&out).unwrap();
    let rows = |v: &serde_json::Value| v["truth_comparison"].as_array().unwrap().clone();
    for (a, b) in rows(&j).iter().zip(&rows(&by_truth)) {
        assert_eq!(a["name"], b["name"]);
        let d = (a["fitted"].as_f64().unwrap() - b["fitted"].as_f64().unwrap()).abs()
            / b["std_error"].as_f64().unwrap();
        let max = if a["triad"] == "accel" { 1e-3 } else { 1.0 };
        assert!(d < max, "{} {}: {d} SE apart", a["triad"], a["name"]);
    }
    assert!(
        j["reference_description"]
            .as_str()
            .unwrap()
            .starts_with("test plan"),
        "{}",
        j["reference_description"]
    );
    let cal = imu_model::Calibration::load(&cal_path).unwrap();
    let inputs = &cal.provenance.inputs;
    assert_eq!(inputs[1].path, plan.display().to_string());
    assert!(
        cal.provenance
            .procedure
            .as_deref()
            .unwrap()
            .contains("test plan")
    );

    // The same recording against a reference log on a clock 12.5 s ahead (written from the
    // truth in deg/s and g, as a rate table's or a motion capture's log could be).
    let truth = imu_rec::truth::read_truth(&truth_path).unwrap();
    let mut csv = String::from("t_s,wx_deg_s,wy_deg_s,wz_deg_s,fx_g,fy_g,fz_g\n");
    let first_t_s = truth
        .samples
        .iter()
        .find(|s| s.command == 0x01)
        .unwrap()
        .t_s;
    for s in truth.samples.iter().filter(|s| s.command == 0x01) {
        let w = s.angular_rate_rad_s.map(f64::to_degrees);
        let f = s
            .specific_force_m_s2
            .map(|x| x / imu_model::units::STANDARD_GRAVITY_M_S2);
        csv.push_str(&format!(
            "{:.4},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9}\n",
            s.t_s - first_t_s + 12.5,
            w[0],
            w[1],
            w[2],
            f[0],
            f[1],
            f[2]
        ));
    }
    let log = dir.path().join("log.csv");
    std::fs::write(&log, csv).unwrap();
    let (ok, out, err) = run_cli(&with(&[
        "--reference".as_ref(),
        log.as_os_str(),
        "--json".as_ref(),
    ]));
    assert!(ok, "{err}");
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(
        j["fit"]["note_codes"]
            .as_array()
            .is_some_and(|c| c.iter().any(|c| c == "log_clock")),
        "{}",
        j["fit"]["note_codes"]
    );
    let notes = j["fit"]["notes"].to_string();
    assert!(
        notes.contains("log clock = recording clock +12.5"),
        "{notes}"
    );
    assert_eq!(fitted_within_3_se(&j), 18 + 3);

    // A plan whose table turns the other way: refused, naming the step and the directions.
    let wrong = dir.path().join("wrong.toml");
    let text = std::fs::read_to_string(&plan).unwrap();
    std::fs::write(&wrong, text.replacen("axis = \"x\"", "axis = \"-x\"", 1)).unwrap();
    let (ok, _, err) = run_cli(&with(&["--plan".as_ref(), wrong.as_os_str()]));
    assert!(!ok);
    assert!(
        err.starts_with("imu-calibrate: error: calibrating"),
        "{err}"
    );
    assert!(
        err.contains("wrong.toml: the recording does not follow the plan"),
        "{err}"
    );
    assert!(err.contains("step 1 (line 17) position 2 of 12"), "{err}");
    assert!(err.contains("from the planned"), "{err}");

    // One reference per recording: a plan and a log for one recording are refused; one of
    // them is required.
    let (ok, _, err) = run_cli(&with(&[
        "--plan".as_ref(),
        plan.as_os_str(),
        "--reference".as_ref(),
        log.as_os_str(),
    ]));
    assert!(
        !ok && err.contains("2 references (--plan ") && err.contains("for 1 recording"),
        "{err}"
    );
    let (ok, _, err) = run_cli(&base);
    assert!(!ok && err.contains("required"), "{err}");
}

/// The same session as CSV: the accelerometer in raw counts in one file, the gyro in deg/s in
/// another (its own sample times, 3 ms later); the calibration against the plan equals the one
/// from the MCAP recording to well within its standard errors.
#[test]
fn calibrates_csv_counts_with_accel_and_gyro_in_two_files() {
    use imu_analysis::input::{Source, read_mcap};
    let (dir, rec, _truth) = record_shipped("index-table-12pos.toml", 12);
    let plan = repo().join("config/plans/index-table-12pos.toml");
    let series = read_mcap(&rec, Source::Raw, None).unwrap();
    let scale_m_s2 = 1e-3;
    let (acc, gyr) = (dir.path().join("acc.csv"), dir.path().join("gyr.csv"));
    let mut a = String::from("time_ns,ax_counts,ay_counts,az_counts\n");
    let mut g = String::from("time_ns,gx_deg_s,gy_deg_s,gz_deg_s\n");
    for (k, t) in series.t_s.iter().enumerate() {
        let ns = 5_000_000_000 + (t * 1e9).round() as i64;
        let c = series.accel_m_s2[k].map(|v| v / scale_m_s2);
        a += &format!("{ns},{:.4},{:.4},{:.4}\n", c[0], c[1], c[2]);
        // The gyro's own log, stamped 3 ms after each accel sample: read back at the accel's
        // times it is interpolated between neighbours, exact in still segments and plateaus.
        let w = series.gyro_rad_s[k].map(f64::to_degrees);
        g += &format!("{},{:.6},{:.6},{:.6}\n", ns + 3_000_000, w[0], w[1], w[2]);
    }
    std::fs::write(&acc, a).unwrap();
    std::fs::write(&gyr, g).unwrap();
    let fit = |args: &[&OsStr]| -> serde_json::Value {
        let (ok, out, err) = run_cli(&args.iter().map(|s| s.to_os_string()).collect::<Vec<_>>());
        assert!(ok, "{err}");
        serde_json::from_str(&out).unwrap()
    };
    let mcap = fit(&[
        rec.as_os_str(),
        "--plan".as_ref(),
        plan.as_os_str(),
        "--json".as_ref(),
    ]);
    let csv = fit(&[
        acc.as_os_str(),
        "--gyro-csv".as_ref(),
        gyr.as_os_str(),
        "--csv-time-scale-s".as_ref(),
        "1e-9".as_ref(),
        "--csv-accel".as_ref(),
        "counts:0.001".as_ref(),
        "--csv-gyro".as_ref(),
        "deg/s".as_ref(),
        "--plan".as_ref(),
        plan.as_os_str(),
        "--json".as_ref(),
    ]);
    for triad in ["accel", "gyro"] {
        let (m, c) = (&mcap["fit"][triad], &csv["fit"][triad]);
        let params = m["params"].as_array().unwrap();
        assert_eq!(params.len(), c["params"].as_array().unwrap().len());
        for (i, p) in params.iter().enumerate() {
            let (pm, pc) = (p.as_f64().unwrap(), c["params"][i].as_f64().unwrap());
            let Some(se) = m["std_errors"][i].as_f64() else {
                continue;
            };
            assert!(
                (pm - pc).abs() < 0.1 * se,
                "{triad} {}: MCAP {pm:e}, CSV {pc:e}, SE {se:e}",
                m["names"][i]
            );
        }
    }
    assert!(
        csv["recording"].as_str().unwrap().contains("acc.csv"),
        "{}",
        csv["recording"]
    );
}

/// Effects chosen by flags: `--add` extends the default model (bias + scale + misalignment);
/// an unknown effect or one that does not apply to the triad is a clear error.
#[test]
fn effects_can_be_added_by_flags() {
    let (_dir, rec, _truth) = record_shipped("index-table-12pos.toml", 13);
    let plan = repo().join("config/plans/index-table-12pos.toml");
    let args = |extra: &[&str]| -> Vec<OsString> {
        [rec.as_os_str(), "--plan".as_ref(), plan.as_os_str()]
            .iter()
            .map(|s| s.to_os_string())
            .chain(extra.iter().map(OsString::from))
            .collect()
    };
    let (ok, out, err) = run_cli(&args(&["--add", "accel:scale-nonlinearity", "--json"]));
    assert!(ok, "{err}");
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    let names: Vec<&str> = j["fit"]["accel"]["names"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    for want in [
        "bias.x",
        "scale.z",
        "misalignment.zy",
        "scale-nonlinearity.quadratic.x",
    ] {
        assert!(names.contains(&want), "{want} not in {names:?}");
    }
    assert!(
        !j["fit"]["gyro"]["names"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n.as_str().unwrap().starts_with("scale-nonlinearity")),
        "the accel-only --add reached the gyro"
    );
    let (ok, _, err) = run_cli(&args(&["--add", "accel:no-such-effect"]));
    assert!(!ok && err.contains("--add accel:no-such-effect"), "{err}");
    let (ok, _, err) = run_cli(&args(&["--add", "accel:g-sensitivity"]));
    assert!(!ok && err.contains("does not apply"), "{err}");
}
