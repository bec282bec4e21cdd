//! End-to-end runs of the `imu-noise` binary on a small synthetic CSV: table, JSON, Kalibr file
//! and plots, and the error path.

use std::process::Command;

fn write_csv(path: &std::path::Path) {
    // 100 Hz, 20000 samples, deterministic uniform noise (sd 0.01 per sample -> N = 1e-3).
    let mut state: u64 = 3;
    let mut noise = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.01 * 12f64.sqrt()
    };
    let mut s = String::from("t,ax,ay,az,gx,gy,gz\n");
    for i in 0..20_000 {
        s += &format!(
            "{},{},{},{},{},{},{}\n",
            i as f64 / 100.0,
            noise(),
            noise(),
            9.81 + noise(),
            noise(),
            noise(),
            noise()
        );
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn json_kalibr_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("static.csv");
    write_csv(&csv);
    let yaml = dir.path().join("imu.yaml");
    let plots = dir.path().join("plots");
    let out = Command::new(env!("CARGO_BIN_EXE_imu-noise"))
        .arg(&csv)
        .arg("--json")
        .arg("--kalibr")
        .arg(&yaml)
        .arg("--plot")
        .arg(&plots)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let axes = v.as_array().unwrap();
    assert_eq!(axes.len(), 6);
    for a in axes {
        let n = a["fit"]["n_u_per_sqrt_hz"]["value"].as_f64().unwrap();
        assert!((n / 1e-3 - 1.0).abs() < 0.1, "{a}");
        assert!((a["sample_rate_hz"].as_f64().unwrap() - 100.0).abs() < 1e-6);
    }
    assert_eq!(axes[3]["display"]["n_unit"], "deg/sqrt(h)");
    assert_eq!(axes[0]["display"]["b_unit"], "micro-g");
    let y = std::fs::read_to_string(&yaml).unwrap();
    for key in [
        "accelerometer_noise_density:",
        "accelerometer_random_walk:",
        "gyroscope_noise_density:",
        "gyroscope_random_walk:",
        "update_rate: 100.000",
        "rostopic: /imu/data",
    ] {
        assert!(y.contains(key), "{key} missing in\n{y}");
    }
    let svg = std::fs::read_to_string(plots.join("adev-gyro-z.svg")).unwrap();
    assert!(svg.contains("data-name=\"OADEV\"") && svg.contains("data-name=\"N term\""));

    let table = Command::new(env!("CARGO_BIN_EXE_imu-noise"))
        .arg(&csv)
        .output()
        .unwrap();
    let text = String::from_utf8(table.stdout).unwrap();
    assert!(
        text.contains("N [U/sqrt(Hz)]") && text.contains("deg/sqrt(h)"),
        "{text}"
    );
}

#[test]
fn missing_file_is_an_error_with_the_path() {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-noise"))
        .arg("/nonexistent/rec.mcap")
        .output()
        .unwrap();
    // EX_NOINPUT, as in every imud tool (it was 1 before the tools shared one exit-code map).
    assert_eq!(out.status.code(), Some(66));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/rec.mcap"));
}
