//! imu-diagnose and imu-calibrate agree on a Ferraris plan's segments (issue 30): on a session
//! shaped like imucal's public example (`imu-sim --export-parts`: labelled parts joined with no
//! motion between them, no time column, a flipped gyro read with negated counts), with and
//! without its labels, the workbench fits exactly the segments of the procedure's segmentation
//! (the one imu-calibrate fits): the six rests for the accelerometer (a hand's turn is no
//! steady input for it), the rests and the three turns for the gyro; and the accelerometer's
//! base model, which is the truth's, is consistent with the noise floor.

use std::path::{Path, PathBuf};
use std::process::Command;

use imu_analysis::input::{AccelUnit, ColumnRef, Columns, CsvOptions, GyroUnit, read_text};
use imu_analysis::reference::Reference;
use imu_analysis::segment::{SegmentKind, SegmentOptions};

const TRUTH: &str = r#"
format = "imud-calibration/1"
[accel.scale]
value = [1.2e-3, -0.8e-3, 2.8e-2]
[accel.bias]
value = [0.25, -0.18, 0.32]
[accel.noise]
white-density = [1.5e-3, 1.5e-3, 1.8e-3]
[gyro.misalignment]
xz = -1.3e-2
yz = 3.8e-2
zy = -3.6e-2
[gyro.scale]
value = [1.8e-2, -1.3e-2, -9.0e-3]
[gyro.bias]
value = [8.7e-3, -6.1e-3, 1.05e-2]
[gyro.noise]
white-density = [1.0e-3, 1.0e-3, 1.0e-3]
"#;

const COLUMNS: [&str; 6] = ["acc_x", "acc_y", "acc_z", "gyr_x", "gyr_y", "gyr_z"];

fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

#[test]
fn diagnose_fits_the_segments_calibrate_fits() {
    let dir = tempfile::tempdir().unwrap();
    let truth = dir.path().join("truth.toml");
    std::fs::write(&truth, TRUTH).unwrap();
    let mut sim = imu_sim::SimOptions::from_files(
        &repo_path("config/scenarios/ferraris-parts.toml"),
        Some(&truth),
    )
    .unwrap();
    sim.seed = 31;
    let labelled = dir.path().join("session.csv");
    let out = imu_sim::export::export_parts(&sim, &labelled, -1).unwrap();
    let text = std::fs::read_to_string(&labelled).unwrap();
    let unlabelled = dir.path().join("unlabelled.csv");
    let without: String = text
        .lines()
        .map(|l| format!("{}\n", l.split_once(',').unwrap().1))
        .collect();
    std::fs::write(&unlabelled, without).unwrap();
    let plan = dir.path().join("ferraris.toml");
    let shipped = std::fs::read_to_string(repo_path("config/plans/ferraris.toml")).unwrap();
    std::fs::write(
        &plan,
        format!("{shipped}gravity-m-s2 = 9.80665\ntemp-c = 25.0\n"),
    )
    .unwrap();
    let gyro_scale = -out.gyro_count_rad_s;
    for file in [&labelled, &unlabelled] {
        // The procedure's segmentation, as imu-calibrate takes it.
        let options = CsvOptions {
            rate_hz: Some(out.rate_hz),
            accel: AccelUnit::Counts(out.accel_count_m_s2),
            gyro: GyroUnit::Counts(gyro_scale),
            ..CsvOptions::default()
        };
        let columns = Columns {
            main: Some(COLUMNS.map(|c| ColumnRef::Name(c.into())).to_vec()),
            ..Columns::default()
        };
        let series = read_text(file, &options, &columns).unwrap();
        let reference = Reference::open(Some(&plan), None, None, &series)
            .unwrap()
            .unwrap();
        let seg = reference
            .segmentation(&series, &SegmentOptions::default())
            .unwrap();
        let spans = |kind: Option<SegmentKind>| -> Vec<(f64, f64)> {
            seg.segments
                .iter()
                .filter(|s| kind.is_none_or(|k| s.kind == k))
                .map(|s| (s.start_s, s.end_s))
                .collect()
        };
        assert_eq!(spans(Some(SegmentKind::Static)).len(), 6);
        assert_eq!(spans(Some(SegmentKind::Plateau)).len(), 3);

        let o = Command::new(env!("CARGO_BIN_EXE_imu-diagnose"))
            .arg(file)
            .arg("--plan")
            .arg(&plan)
            .args(["--rate-hz", &out.rate_hz.to_string()])
            .args(["--columns", &COLUMNS.join(",")])
            .arg(format!("--csv-accel=counts:{}", out.accel_count_m_s2))
            .arg(format!("--csv-gyro=counts:{gyro_scale}"))
            .arg("--json")
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let fitted = |triad: &str| -> (Vec<(f64, f64)>, &serde_json::Value) {
            let d = j["diagnoses"]
                .as_array()
                .unwrap()
                .iter()
                .find(|d| d["triad"] == triad)
                .unwrap();
            let spans = d["segments"]
                .as_array()
                .unwrap()
                .iter()
                .map(|s| (s["start_s"].as_f64().unwrap(), s["end_s"].as_f64().unwrap()))
                .collect();
            (spans, d)
        };
        let (accel, a) = fitted("accel");
        assert_eq!(
            accel,
            spans(Some(SegmentKind::Static)),
            "{}",
            file.display()
        );
        assert_eq!(fitted("gyro").0, spans(None), "{}", file.display());
        assert_eq!(a["consistent"], true, "{a}");
    }
}
