//! Every file under config/ parses, every scenario compiles to a sensible timeline, and every
//! test plan describes the scenario of the same name: a typo in a shipped example is caught
//! here, not by a user.

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

#[test]
fn every_plan_parses_and_describes_its_scenario() {
    use imu_analysis::reference::plan::Plan;
    use imu_analysis::segment::SegmentKind;
    let files = config_files("plans", "toml");
    let names: Vec<String> = files
        .iter()
        .map(|f| f.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    for wanted in ["index-table-12pos", "earth-rate-8pos", "rate-table"] {
        assert!(
            names.iter().any(|n| n == wanted),
            "config/plans/{wanted}.toml is missing"
        );
    }
    for (f, name) in files.iter().zip(&names) {
        // A Ferraris plan has no steps to compare: its faces and turns are found in the data
        // (clients/imu-calibrate/tests/ferraris.rs runs it on its scenario). It must load and
        // have a scenario of its name.
        let text = std::fs::read_to_string(f).unwrap();
        let shown = f.display().to_string();
        if let Some(ferraris) =
            imu_analysis::reference::ferraris::Ferraris::from_toml_str(&text, &shown)
        {
            let ferraris = ferraris.unwrap_or_else(|e| panic!("{e}"));
            assert!(ferraris.description.is_some(), "{shown}: describe the plan");
            let scenario = repo_root()
                .join("config/scenarios")
                .join(format!("{name}.toml"));
            imu_sim::SimOptions::from_files(&scenario, None)
                .unwrap_or_else(|e| panic!("{shown}: no scenario of that name: {e}"));
            continue;
        }
        let plan = Plan::load(f).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            plan.description.is_some(),
            "{}: describe the plan",
            f.display()
        );
        // A plan is named after the scenario it calibrates. The scenario's still and rate
        // segments, with consecutive still ones merged where no move separates them (a
        // mounting static and the table's first position), are the plan's entries: same kind,
        // same gravity direction, same table axis and rate.
        let scenario = repo_root()
            .join("config/scenarios")
            .join(format!("{name}.toml"));
        let opts = imu_sim::SimOptions::from_files(&scenario, None)
            .unwrap_or_else(|e| panic!("{}: no scenario of that name: {e}", f.display()));
        let timeline = opts.scenario.compile(opts.seed);
        let mut expected: Vec<&imu_sim::motion::SegmentInfo> = Vec::new();
        for seg in timeline.segments() {
            let merges = expected.last().is_some_and(|last| {
                seg.kind == "static" && last.kind == "static" && last.end_s == Some(seg.start_s)
            });
            if (seg.kind == "static" || seg.kind == "rate") && !merges {
                expected.push(seg);
            }
        }
        assert_eq!(
            plan.entries.len(),
            expected.len(),
            "{}: the plan has {} entries, the scenario {} segments",
            f.display(),
            plan.entries.len(),
            expected.len()
        );
        for (e, seg) in plan.entries.iter().zip(&expected) {
            let what = format!("{}: {} vs {}", f.display(), e.name(), seg.label);
            let kind = if seg.kind == "rate" {
                SegmentKind::Plateau
            } else {
                SegmentKind::Static
            };
            assert_eq!(e.kind, kind, "{what}");
            let up = -seg.gravity_dir_sensor;
            let planned = imu_model::Vec3::from(e.up_sensor);
            assert!(
                (planned - up).norm() < 1e-9,
                "{what}: up {planned:?} vs {up:?}"
            );
            if let Some(rate) = seg.table_rate_rad_s.filter(|r| *r != 0.0) {
                let axis = imu_model::Vec3::from(e.axis_sensor.expect("a plateau has an axis"));
                assert!((axis - seg.axis_sensor.unwrap()).norm() < 1e-12, "{what}");
                assert!((e.rate_rad_s - rate).abs() < 1e-12, "{what}");
            }
        }
        // The plans for the simulated runs state the simulator's gravity.
        assert_eq!(
            plan.gravity_m_s2,
            opts.scenario.gravity_m_s2,
            "{}",
            f.display()
        );
        assert_eq!(
            plan.latitude_deg,
            Some(opts.scenario.latitude_deg),
            "{}",
            f.display()
        );
    }
}
