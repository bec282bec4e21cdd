//! End-to-end runs of the `imu-noise` binary on a small synthetic CSV: table, JSON, Kalibr file
//! and plots, and the error path.

use std::process::Command;

fn write_csv(path: &std::path::Path) {
    write_csv_n(path, 20_000);
}

fn write_csv_n(path: &std::path::Path, n: usize) {
    // 100 Hz, n samples, deterministic uniform noise (sd 0.01 per sample -> N = 1e-3).
    let mut state: u64 = 3;
    let mut noise = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.01 * 12f64.sqrt()
    };
    let mut s = String::from("t,ax,ay,az,gx,gy,gz\n");
    for i in 0..n {
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
    let svg = std::fs::read_to_string(plots.join("allan-gyro.svg")).unwrap();
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

fn run_json(csv: &std::path::Path, args: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-noise"))
        .arg(csv)
        .arg("--json")
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The white-noise truth of `write_csv` (N = 1e-3 U/sqrt(Hz)) for each kind at `tau_s` (m >> 1):
/// ADEV, OADEV, HDEV, OHDEV, TOTDEV N/sqrt(tau); MDEV N/sqrt(2 tau); TDEV tau MDEV/sqrt(3).
fn white_fm_truth(kind: &str, tau_s: f64) -> f64 {
    let adev = 1e-3 / tau_s.sqrt();
    match kind {
        "mdev" => adev / 2f64.sqrt(),
        "tdev" => tau_s * adev / 2f64.sqrt() / 3f64.sqrt(),
        _ => adev,
    }
}

/// Every kind at once, at an explicit tau list: the bounds cover the white-noise truth as
/// often as their confidence level says (210 points per run; the seven kinds of one axis and
/// tau are correlated, so the band is wide), every point says its noise type (white FM here at
/// most taus), and every kind is plotted.
#[test]
fn every_kind_with_bounds_at_explicit_taus() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("static.csv");
    write_csv(&csv);
    let plots = dir.path().join("plots");
    for (confidence, min_cover, max_cover) in [(0.683, 0.55, 0.82), (0.95, 0.9, 0.99)] {
        let (inside, total) = kinds_at_taus(&csv, confidence, &plots);
        let cover = inside as f64 / total as f64;
        assert!(
            (min_cover..=max_cover).contains(&cover),
            "{confidence} bounds cover the truth at {inside} of {total} points"
        );
    }
    for kind in ["adev", "mdev", "hdev", "ohdev", "tdev", "totdev"] {
        let svg = std::fs::read_to_string(plots.join(format!("dev-{kind}-gyro.svg"))).unwrap();
        assert!(svg.contains(&format!("data-name=\"{}\"", kind.to_uppercase())));
    }
}

/// One run of every kind at taus 0.5..10 s: checks the shape of the JSON, returns how many
/// points' bounds hold the truth, of how many.
fn kinds_at_taus(
    csv: &std::path::Path,
    confidence: f64,
    plots: &std::path::Path,
) -> (usize, usize) {
    let kinds = ["adev", "oadev", "mdev", "hdev", "ohdev", "tdev", "totdev"];
    let v = run_json(
        csv,
        &[
            "--kind",
            &kinds.join(","),
            "--taus",
            "0.5,1,2,5,10",
            "--confidence",
            &confidence.to_string(),
            "--plot",
            plots.to_str().unwrap(),
        ],
    );
    let axes = v.as_array().unwrap();
    assert_eq!(axes.len(), 6);
    let (mut white, mut inside, mut total) = (0, 0, 0);
    for a in axes {
        let devs = a["deviations"].as_array().unwrap();
        let names: Vec<&str> = devs.iter().map(|d| d["kind"].as_str().unwrap()).collect();
        assert_eq!(names, kinds);
        for d in devs {
            let kind = d["kind"].as_str().unwrap();
            assert_eq!(d["confidence"], confidence);
            assert_eq!(d["edf_method"], "greenhall");
            let taus: Vec<f64> = d["points"]
                .as_array()
                .unwrap()
                .iter()
                .map(|p| p["tau_s"].as_f64().unwrap())
                .collect();
            assert_eq!(taus.len(), 5, "{kind}: {taus:?}");
            for (p, want) in d["points"]
                .as_array()
                .unwrap()
                .iter()
                .zip([0.5, 1.0, 2.0, 5.0, 10.0])
            {
                let tau = p["tau_s"].as_f64().unwrap();
                assert!((tau - want).abs() < 1e-9, "{kind}: tau {tau}");
                let (lo, hi) = (p["dev_lo"].as_f64().unwrap(), p["dev_hi"].as_f64().unwrap());
                let truth = white_fm_truth(kind, tau);
                assert!(lo < hi, "{kind} tau {tau}: [{lo:e}, {hi:e}]");
                if lo < truth && truth < hi {
                    inside += 1;
                }
                total += 1;
                if p["noise"] == "white-fm" && p["alpha"] == 0 {
                    white += 1;
                }
            }
        }
        let unit = devs[5]["unit"].as_str().unwrap();
        assert!(unit.ends_with("*s"), "TDEV unit {unit}");
    }
    assert!(
        white * 10 >= total * 9,
        "white FM identified at {white} of {total} points"
    );
    (inside, total)
}

/// Stable32's decade set, and the text table's block per kind.
#[test]
fn decade_taus_and_the_table() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("static.csv");
    write_csv(&csv);
    let v = run_json(&csv, &["--kind", "mdev", "--taus", "decade"]);
    let taus: Vec<f64> = v[0]["deviations"][0]["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["tau_s"].as_f64().unwrap())
        .collect();
    let want = [
        0.01, 0.02, 0.04, 0.1, 0.2, 0.4, 1.0, 2.0, 4.0, 10.0, 20.0, 40.0,
    ];
    assert_eq!(taus.len(), want.len(), "{taus:?}");
    for (t, w) in taus.iter().zip(want) {
        assert!((t / w - 1.0).abs() < 1e-9, "{taus:?}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_imu-noise"))
        .arg(&csv)
        .args(["--kind", "hdev,totdev", "--taus", "octave"])
        .output()
        .unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    for block in [
        "HDEV of accel [m/s^2]",
        "HDEV of gyro [rad/s]",
        "TOTDEV of gyro [rad/s]",
    ] {
        assert!(text.contains(block), "{block} missing in\n{text}");
    }
}

/// Unknown kinds, bad tau lists and confidence levels outside (0, 1) are usage errors (64)
/// that name the bad value.
#[test]
fn bad_kind_taus_and_confidence_are_usage_errors() {
    for (flag, value) in [
        ("--kind", "oadev,allan"),
        ("--taus", "1,two"),
        ("--taus", "0.001"),
        ("--confidence", "1.5"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("static.csv");
        write_csv(&csv);
        let out = Command::new(env!("CARGO_BIN_EXE_imu-noise"))
            .arg(&csv)
            .args([flag, value])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let bad = value.rsplit(',').next().unwrap();
        assert!(stderr.contains(bad), "{flag} {value}: {stderr}");
        if value != "0.001" {
            assert_eq!(out.status.code(), Some(64), "{flag} {value}: {stderr}");
        } else {
            assert!(
                stderr.contains("shorter than the sample period"),
                "{stderr}"
            );
        }
    }
}

/// `--kind theo1,theoh`: both in the JSON and the figures; Theo1's taus are 0.75 m tau0 with m
/// even and reach past a third of the record, TheoH switches from OADEV (tau = m tau0) to
/// TheoBR at 10 % of it, and TheoH's 99 % bounds hold the white-noise truth (at least 95 % of
/// the points).
#[test]
fn theo1_and_theoh_in_json_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("short.csv");
    // 30 s at 100 Hz: TheoH's bias ratio is O(N^3).
    write_csv_n(&csv, 3000);
    let plots = dir.path().join("plots");
    let v = run_json(
        &csv,
        &[
            "--kind",
            "theo1,theoh",
            "--taus",
            "octave",
            "--confidence",
            "0.99",
            "--plot",
            plots.to_str().unwrap(),
        ],
    );
    let record_s = 2999.0 * 0.01;
    let (mut inside, mut total) = (0, 0);
    for a in v.as_array().unwrap() {
        let devs = a["deviations"].as_array().unwrap();
        assert_eq!(devs[0]["kind"], "theo1");
        assert_eq!(devs[1]["kind"], "theoh");
        let theo1 = devs[0]["points"].as_array().unwrap();
        for p in theo1 {
            let m = p["m"].as_u64().unwrap();
            assert!(m >= 10 && m.is_multiple_of(2), "m {m}");
            assert!((p["tau_s"].as_f64().unwrap() - 0.75 * m as f64 * 0.01).abs() < 1e-12);
        }
        let last = theo1.last().unwrap()["tau_s"].as_f64().unwrap();
        assert!(last > record_s / 3.0, "longest Theo1 tau {last}");
        let mut seen_theo = false;
        for p in devs[1]["points"].as_array().unwrap() {
            let (m, tau) = (
                p["m"].as_u64().unwrap() as f64,
                p["tau_s"].as_f64().unwrap(),
            );
            let oadev_point = (tau - m * 0.01).abs() < 1e-12;
            // OADEV below the largest octave under 10 % of the record, TheoBR from there on.
            assert!(
                !oadev_point || (tau < 0.1 * record_s && !seen_theo),
                "tau {tau}"
            );
            seen_theo |= !oadev_point;
            let (lo, dev, hi) = (
                p["dev_lo"].as_f64().unwrap(),
                p["dev"].as_f64().unwrap(),
                p["dev_hi"].as_f64().unwrap(),
            );
            let truth = white_fm_truth("oadev", tau);
            assert!(lo < dev && dev < hi, "tau {tau}");
            total += 1;
            if lo < truth && truth < hi {
                inside += 1;
            } else {
                eprintln!("outside: tau {tau}: {lo:e} .. {hi:e}, truth {truth:e}");
            }
        }
        assert!(seen_theo);
    }
    // 99 % bounds: at most 5 % of the points may miss the truth.
    assert!(
        inside * 20 >= total * 19,
        "{inside} of {total} bounds hold the truth"
    );
    // The noise-term fit takes the Theo1 point beyond the OADEV's last octave (1024 samples:
    // Theo1 at 2048, up to 75 % of the record) when a Theo kind is asked for, and says so.
    let plain = run_json(&csv, &["--taus", "octave"]);
    for (a, b) in v.as_array().unwrap().iter().zip(plain.as_array().unwrap()) {
        assert_eq!(a["fit"]["n_theo1_points"], 1, "{}", a["fit"]);
        assert_eq!(b["fit"]["n_theo1_points"], 0, "{}", b["fit"]);
        assert_eq!(
            a["fit"]["n_points"].as_u64().unwrap(),
            b["fit"]["n_points"].as_u64().unwrap() + 1
        );
    }
    let text = Command::new(env!("CARGO_BIN_EXE_imu-noise"))
        .args([csv.to_str().unwrap(), "--kind", "theo1", "--taus", "octave"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains("Fit extended by Theo1 points") && text.contains("gyro z 1"),
        "{text}"
    );
    for kind in ["theo1", "theoh"] {
        let svg = std::fs::read_to_string(plots.join(format!("dev-{kind}-gyro.svg"))).unwrap();
        assert!(svg.contains(&format!("data-name=\"{}\"", kind.to_uppercase())));
    }
}
