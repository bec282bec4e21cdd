//! `imu-sim --export-text`: a hand-held scenario written as two text files of raw counts, each
//! line the truth file's pre-quantisation measurement in counts (to the rounding), at the
//! truth's times; the units to read them back are printed; an endless scenario is refused.

use std::process::Command;

const SCENARIO: &str = r#"
name = "export"
rate-hz = 50.0
[hand]
tremor-deg = 0.2
tilt-noise-deg = 3.0
[[segment]]
kind = "static"
orientation = { x = "north", z = "up" }
duration-s = 2.0
[[segment]]
kind = "random-poses"
count = 3
dwell-s = 2.0
move-s = 1.0
"#;

const TRUTH: &str = r#"
format = "imud-calibration/1"
[accel.bias]
value = [4.9, -3.1, 2.2]
[accel.noise]
white-density = [1.5e-3, 1.5e-3, 1.8e-3]
[gyro.bias]
value = [0.0873, -0.1571, 0.1134]
[gyro.noise]
white-density = [1.0e-3, 1.0e-3, 1.0e-3]
"#;

fn rows(path: &std::path::Path) -> Vec<[f64; 4]> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect()
}

#[test]
fn export_is_the_truths_measurement_in_raw_counts() {
    let dir = tempfile::tempdir().unwrap();
    let (scenario, model) = (dir.path().join("s.toml"), dir.path().join("m.toml"));
    std::fs::write(&scenario, SCENARIO).unwrap();
    std::fs::write(&model, TRUTH).unwrap();
    let truth_out = dir.path().join("truth.mcap");
    let out = Command::new(env!("CARGO_BIN_EXE_imu-sim"))
        .arg("--scenario")
        .arg(&scenario)
        .arg("--truth")
        .arg(&model)
        .arg("--truth-out")
        .arg(&truth_out)
        .args(["--seed", "4", "--export-text"])
        .arg(dir.path().join("txt"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8(out.stdout).unwrap();
    // GainScales 7000 (accel) and 10000 (gyro): one count is gain / 32 768 000 g or rad/s.
    let g0 = 9.80665;
    let (accel_count, gyro_count) = (7000.0 / 32_768_000.0 * g0, 10000.0 / 32_768_000.0);
    assert!(
        stdout.contains(&format!(
            "--csv-accel counts:{accel_count}@32768 --csv-gyro counts:{gyro_count}@32768"
        )),
        "{stdout}"
    );
    let truth = imu_rec::truth::read_truth(&truth_out).unwrap().samples;
    let (acc, gyro) = (
        rows(&dir.path().join("txt/acc.txt")),
        rows(&dir.path().join("txt/gyro.txt")),
    );
    // 2 s + 3 x (1 s + 2 s) at 50 Hz, both ends.
    assert_eq!(acc.len(), 551);
    assert_eq!((gyro.len(), truth.len()), (acc.len(), acc.len()));
    let mut tremor_rad_s: f64 = 0.0;
    for ((a, w), t) in acc.iter().zip(&gyro).zip(&truth) {
        assert!((a[0] - t.t_s).abs() < 1e-6 && a[0] == w[0]);
        for i in 0..3 {
            let want_a = t.measured_accel_m_s2[i] / accel_count + 32768.0;
            let want_w = t.measured_gyro_rad_s[i] / gyro_count + 32768.0;
            assert!(
                (a[i + 1] - want_a).abs() <= 0.5 + 1e-9,
                "t {} accel {i}",
                a[0]
            );
            assert!(
                (w[i + 1] - want_w).abs() <= 0.5 + 1e-9,
                "t {} gyro {i}",
                w[0]
            );
        }
        if t.segment == 0 {
            let r = t.angular_rate_rad_s;
            tremor_rad_s = tremor_rad_s.max((r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt());
        }
    }
    // The hand trembles during the first rest (the truth holds the motion it made).
    assert!(tremor_rad_s > 0.01, "{tremor_rad_s}");

    // An endless scenario cannot be exported.
    let endless = dir.path().join("endless.toml");
    std::fs::write(&endless, "name = \"e\"\n[[segment]]\nkind = \"static\"\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_imu-sim"))
        .arg("--scenario")
        .arg(&endless)
        .arg("--export-text")
        .arg(dir.path().join("e"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("never ends"), "{err}");
}
