//! Every file under config/ parses, and every scenario compiles to a sensible timeline: a typo in
//! a shipped example is caught here, not by a user.

use imu_model::Calibration;
use imu_sim::Scenario;
use imud_e2e::{config_files, repo_root};

#[test]
fn every_model_file_parses_and_round_trips() {
    let files = config_files("models", "toml");
    assert!(
        files.len() >= 2,
        "config/models must hold the documented examples"
    );
    for f in files {
        let cal = Calibration::load(&f).unwrap_or_else(|e| panic!("{e}"));
        let again = Calibration::from_toml_str(&cal.to_toml_string(), "round-trip").unwrap();
        assert_eq!(cal, again, "{}", f.display());
    }
}

#[test]
fn every_scenario_parses_compiles_and_names_a_loadable_truth_model() {
    let files = config_files("scenarios", "toml");
    let names: Vec<String> = files
        .iter()
        .map(|f| f.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    // One scenario per test of the paper, plus the demo.
    for wanted in [
        "static-6h",
        "index-table-12pos",
        "earth-rate-8pos",
        "rate-table",
        "dynamic-30deg",
        "impacts",
        "thermal-warmup",
        "multi-pose",
        "demo",
    ] {
        assert!(
            names.iter().any(|n| n == wanted),
            "config/scenarios/{wanted}.toml is missing"
        );
    }
    for f in files {
        let opts = imu_sim::SimOptions::from_files(&f, None).unwrap_or_else(|e| panic!("{e}"));
        let s: &Scenario = &opts.scenario;
        assert!(
            !s.description.is_empty(),
            "{}: describe the scenario",
            f.display()
        );
        let timeline = s.compile(opts.seed);
        let d = timeline.duration_s();
        assert!(d > 0.0, "{}", f.display());
        assert!(!timeline.segments().is_empty());
        // The truth model named by the scenario is a real, non-trivial model.
        assert!(
            s.truth.is_some(),
            "{}: shipped scenarios name their truth model",
            f.display()
        );
        assert_ne!(opts.truth, Calibration::identity(), "{}", f.display());
        // Static segments really are static: gravity along the same sensor direction throughout.
        for seg in timeline.segments().iter().filter(|s| s.kind == "static") {
            let end = seg.end_s.unwrap_or(seg.start_s + 10.0);
            let a = timeline.state(seg.start_s + 1e-6).specific_force_m_s2;
            let b = timeline.state(end - 1e-6).specific_force_m_s2;
            assert!((a - b).norm() < 1e-9, "{}: {}", f.display(), seg.label);
        }
    }
}

#[test]
fn earth_rate_scenario_matches_table_1() {
    let f = repo_root().join("config/scenarios/earth-rate-8pos.toml");
    let opts = imu_sim::SimOptions::from_files(&f, None).unwrap();
    let s = &opts.scenario;
    let timeline = s.compile(0);
    let w = imu_model::units::EARTH_RATE_RAD_S;
    let lat = s.latitude_deg.to_radians();
    let (c, sn) = (w * lat.cos(), w * lat.sin());
    // Table 1: accelerations (in g) and Earth-rate components on (spin=z, input1=x, input2=y).
    let table: [([f64; 3], [f64; 2]); 8] = [
        ([1.0, 0.0, 0.0], [c, 0.0]),
        ([1.0, 0.0, 0.0], [0.0, -c]),
        ([1.0, 0.0, 0.0], [-c, 0.0]),
        ([1.0, 0.0, 0.0], [0.0, c]),
        ([0.0, 0.0, -1.0], [0.0, -sn]),
        ([0.0, 1.0, 0.0], [sn, 0.0]),
        ([0.0, 0.0, 1.0], [0.0, sn]),
        ([0.0, -1.0, 0.0], [-sn, 0.0]),
    ];
    let statics: Vec<_> = timeline
        .segments()
        .iter()
        .filter(|s| s.kind == "static")
        .collect();
    assert_eq!(statics.len(), 8);
    for (k, (seg, (acc, rate))) in statics.iter().zip(table).enumerate() {
        let st = timeline.state(seg.start_s + 1.0);
        let f = st.specific_force_m_s2 / s.gravity_m_s2;
        // (spin, input1, input2) = (z, x, y)
        let got_acc = [f.z, f.x, f.y];
        for i in 0..3 {
            assert!(
                (got_acc[i] - acc[i]).abs() < 1e-12,
                "position {}: accel {got_acc:?}",
                k + 1
            );
        }
        let got_rate = [st.angular_rate_rad_s.x, st.angular_rate_rad_s.y];
        for i in 0..2 {
            assert!(
                (got_rate[i] - rate[i]).abs() < 1e-15,
                "position {}: rate {got_rate:?}",
                k + 1
            );
        }
    }
}
