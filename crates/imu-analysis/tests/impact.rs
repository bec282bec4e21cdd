//! Truth-based tests of the impact analysis: a simulated shock train through the daemon's
//! offline pipeline; the event count and the misalignment-induced cross-axis coupling.

use std::path::{Path, PathBuf};

use imu_analysis::characterize::impact::{ImpactOptions, analyze};
use imu_analysis::input::{Source, read_mcap};

const COUNT: usize = 30;

const SCENARIO: &str = r#"
name = "impacts-short"
description = "shock train for tests"
rate-hz = 100.0
latitude-deg = 40.0

[[segment]]
kind = "static"
orientation = { roll-deg = 0.0, pitch-deg = 0.0, yaw-deg = 0.0 }
duration-s = 5.0

[[segment]]
kind = "impacts"
axis = "z"
count = 30
period-s = 1.0
peak-g = 4.0
width-ms = 40.0

[[segment]]
kind = "static"
duration-s = 5.0
"#;

fn model_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/example-3dm-gx1.toml")
}

#[test]
fn events_are_counted_and_coupling_matches_the_misalignment() {
    // From config/models/example-3dm-gx1.toml.
    let (xz, yz) = (-0.8e-3, 1.5e-3);
    let scale = [1.2e-3, -0.8e-3, 1.5e-3];
    for seed in [11, 12] {
        let dir = tempfile::tempdir().unwrap();
        let scenario = dir.path().join("scenario.toml");
        std::fs::write(&scenario, SCENARIO).unwrap();
        let mut sim = imu_sim::SimOptions::from_files(&scenario, Some(&model_path())).unwrap();
        sim.seed = seed;
        let mut c = imud::config::Config::default();
        c.log.dir = dir.path().join("log");
        c.name = "t".into();
        let out = imud::offline::record(sim, &c).unwrap();
        let series = read_mcap(&out.files[0], Source::Raw, None).unwrap();
        let r = analyze(&series, &ImpactOptions::default()).unwrap();
        assert_eq!(r.events.len(), COUNT, "seed {seed}");
        assert_eq!(r.struck_axis, Some(2));
        assert!(r.events.iter().all(|e| e.struck_axis == 2));
        // A z shock dz is seen on x as (1 + s_x) xz dz and on z as (1 + s_z) dz (to first order;
        // the z nonlinearity adds ~0.2 %).
        for (i, m) in [(0, xz), (1, yz)] {
            let predicted = m * (1.0 + scale[i]) / (1.0 + scale[2]);
            let p = r.pooled_accel_coupling[i];
            assert!(
                (p.value - predicted).abs() < 4.0 * p.std_error + 0.01 * predicted.abs(),
                "seed {seed} axis {i}: {:.4e} +/- {:.1e} vs {predicted:.4e}",
                p.value,
                p.std_error
            );
            // The per-event slopes agree on average.
            let s = r.summary.accel_coupling[i];
            assert!((s.mean - predicted).abs() < 4.0 * s.std / (s.n as f64).sqrt() + 1e-5);
        }
        assert!((r.pooled_accel_coupling[2].value - 1.0).abs() < 1e-9);
        // Peaks near 4 g on z; settling within the window.
        let z = r.summary.accel_peak_m_s2[2];
        assert!(z.mean > 3.0 * 9.8 && z.max < 4.2 * 9.81, "{z:?}");
        assert!(r.summary.accel_settling_s[2].mean < 0.2);
    }
}
