//! Every deviation kind and its confidence bounds through the `imu-noise` command line match
//! Stable32's published tables on PHASE.DAT (the phase differenced into a 1 Hz rate series in
//! a CSV, which imu-noise integrates back).

use std::process::Command;

use imu_stats::allan::Kind;

// `stable32_tables()`: Stable32's published PHASE.DAT tables (shared with imu-stats' test).
include!("../../../crates/imu-stats/tests/data/stable32_phase_dat.rs");

fn phase_dat() -> Vec<f64> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../crates/imu-stats/tests/data/phase_dat.txt"
    );
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| l.trim().parse().unwrap())
        .collect()
}

#[test]
fn every_kind_and_its_bounds_equal_stable32_through_the_cli() {
    let x = phase_dat();
    let mut csv = String::from("t,ax,ay,az,gx,gy,gz\n");
    for (i, w) in x.windows(2).enumerate() {
        let y = w[1] - w[0];
        csv += &format!("{i},{y:e},{y:e},{y:e},{y:e},{y:e},{y:e}\n");
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("phase_dat_rate.csv");
    std::fs::write(&path, csv).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_imu-noise"))
        .arg(&path)
        .args(["--json", "--taus", "octave", "--confidence", "0.683"])
        .args(["--kind", "adev,oadev,mdev,hdev,ohdev,tdev,totdev"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let gyro_x = &v[3];
    assert_eq!(gyro_x["sensor"], "gyro");
    for (kind, rows) in stable32_tables() {
        let curve = gyro_x["deviations"]
            .as_array()
            .unwrap()
            .iter()
            .find(|d| d["kind"] == kind.name())
            .unwrap();
        for (m, lo, dev, hi) in rows {
            let p = curve["points"]
                .as_array()
                .unwrap()
                .iter()
                .find(|p| p["m"] == m)
                .unwrap_or_else(|| panic!("{kind:?}: no m = {m}"));
            assert_eq!(p["alpha"], 0, "{kind:?} m {m}");
            for (field, want, tol) in [
                ("dev", dev, 1e-4),
                ("dev_lo", lo, 1e-2),
                ("dev_hi", hi, 1e-2),
            ] {
                let got = p[field].as_f64().unwrap();
                assert!(
                    (got / want - 1.0).abs() < tol,
                    "{kind:?} m {m} {field}: {got:e} vs Stable32 {want:e}"
                );
            }
        }
    }
}
