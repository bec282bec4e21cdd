//! Truth-based tests of the thermal analysis: short simulated warm-ups through the daemon's
//! offline pipeline, with and without a hidden temperature coefficient.

use std::path::{Path, PathBuf};

use imu_analysis::characterize::thermal::{ThermalOptions, ThermalReport, ThermalVerdict, analyze};
use imu_analysis::input::{Source, read_mcap};

/// 40 minutes static while warming 22 -> 38 deg C with a 10-minute time constant.
const SCENARIO: &str = r#"
name = "thermal-short"
description = "short warm-up for tests"
rate-hz = 100.0
latitude-deg = 40.0

[temperature]
kind = "warmup"
ambient-c = 22.0
operating-c = 38.0
tau-s = 600.0

[[segment]]
kind = "static"
orientation = { roll-deg = 0.0, pitch-deg = 0.0, yaw-deg = 0.0 }
duration-s = 2400.0
"#;

/// The hidden accel temperature coefficients, m/s^2 per K.
const HIDDEN: [f64; 3] = [1e-3, -2e-3, 5e-4];

fn model_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/example-3dm-gx1.toml")
}

fn run(seed: u64, extra_model: &str) -> ThermalReport {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("scenario.toml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let model = dir.path().join("truth.toml");
    let base = std::fs::read_to_string(model_path()).unwrap();
    std::fs::write(&model, format!("{base}\n{extra_model}")).unwrap();
    let mut sim = imu_sim::SimOptions::from_files(&scenario, Some(&model)).unwrap();
    sim.seed = seed;
    let mut c = imud::config::Config::default();
    c.log.dir = dir.path().join("log");
    c.log.rotate_size_mib = 1 << 20;
    c.name = "t".into();
    let out = imud::offline::record(sim, &c).unwrap();
    assert_eq!(out.files.len(), 1, "{:?}", out.files);
    let series = read_mcap(&out.files[0], Source::Raw, None).unwrap();
    assert!(series.temp.len() > 2000, "temperature logged at 1 Hz");
    analyze(&series, &ThermalOptions::default()).unwrap()
}

#[test]
fn no_model_recommended_without_a_hidden_effect() {
    // The example model has bias instability and random walk on every axis, no thermal effect.
    for seed in [1, 2, 3] {
        let r = run(seed, "");
        let w = r.warmup.as_ref().unwrap();
        assert!((w.tau_s - 600.0).abs() < 30.0, "seed {seed}: {w:?}");
        for a in &r.axes {
            assert!(
                !a.model_warranted,
                "seed {seed}: {} {}: coeff {:.3e} +/- {:.3e}, p {:.2e}, change {:.2e} vs scatter {:.2e}",
                a.sensor,
                a.axis,
                a.bias_coeff_per_k,
                a.bias_coeff_std_per_k,
                a.linear.p_values[1],
                a.predicted_change,
                a.bin_noise
            );
        }
        assert!(!r.model_recommended, "seed {seed}: {}", r.recommendation);
        assert_eq!(
            r.recommendation.codes()[0],
            "no_model_warranted",
            "{}",
            r.recommendation
        );
        assert!(r.confounding.temp_vs_warmup_corr.abs() > 0.95);
    }
}

#[test]
fn hidden_temperature_bias_is_detected_and_recovered() {
    let extra = format!(
        "[accel.temp-bias]\nt0-c = 25.0\ncoefficients = [[{:e}, {:e}, {:e}]]\n",
        HIDDEN[0], HIDDEN[1], HIDDEN[2]
    );
    for seed in [7, 8] {
        let r = run(seed, &extra);
        assert!(r.model_recommended, "seed {seed}: {}", r.recommendation);
        for (i, truth) in HIDDEN.iter().enumerate() {
            let a = &r.axes[i];
            assert!(a.model_warranted, "seed {seed}: accel {}", a.axis);
            let z = (a.bias_coeff_per_k - truth) / a.bias_coeff_std_per_k;
            assert!(
                z.abs() < 3.0,
                "seed {seed}: accel {}: {:.4e} +/- {:.1e} vs truth {truth:e}",
                a.axis,
                a.bias_coeff_per_k,
                a.bias_coeff_std_per_k
            );
        }
        // z carries 1 g: the coefficient is also offered as a scale coefficient.
        assert!(r.axes[2].scale_coeff_per_k.is_some());
        assert!(r.axes[0].scale_coeff_per_k.is_none());
        for a in &r.axes[3..] {
            assert!(!a.model_warranted, "seed {seed}: gyro {}", a.axis);
        }
    }
}

/// A hidden gyro temperature coefficient, rad/s per K, on x only.
fn gyro_tempco(c: f64) -> String {
    format!("[gyro.temp-bias]\nt0-c = 25.0\ncoefficients = [[{c:e}, 0.0, 0.0]]\n")
}

#[test]
fn a_resolvable_gyro_coefficient_is_warranted() {
    // 1e-3 rad/s/K over 16 K is 1.6e-2 rad/s, far above the drift of a 40-minute run.
    let truth = 1e-3;
    let r = run(11, &gyro_tempco(truth));
    let a = &r.axes[3];
    assert_eq!(a.verdict, ThermalVerdict::Warranted, "{}", r.recommendation);
    assert!(a.model_warranted && a.significant && a.linear.p_values[1] < 0.01);
    let z = (a.bias_coeff_per_k - truth) / a.bias_coeff_std_per_k;
    assert!(
        z.abs() < 3.0,
        "{:e} +/- {:e}",
        a.bias_coeff_per_k,
        a.bias_coeff_std_per_k
    );
    assert_eq!(
        r.recommendation.codes()[0],
        "model_warranted",
        "{}",
        r.recommendation
    );
}

#[test]
fn an_unresolvable_gyro_coefficient_is_bounded_not_warranted() {
    // 5e-5 rad/s/K (8e-4 rad/s over 16 K) is within the bias drift of this gyro (50 deg/h bias
    // instability, 1e-5 rad/s/sqrt(s) random walk) over a 40-minute run. The verdict must not
    // be "warranted", and its upper bound must contain the truth.
    let truth = 5e-5;
    for seed in [12, 13] {
        let r = run(seed, &gyro_tempco(truth));
        let a = &r.axes[3];
        let ThermalVerdict::NotResolvable {
            bound_per_k,
            detectable_per_k,
            change_bound,
        } = a.verdict
        else {
            panic!("seed {seed}: gyro x {:?}: {}", a.verdict, r.recommendation);
        };
        assert!(!a.model_warranted && !a.significant);
        assert!(
            a.linear.p_values[1] >= 0.005,
            "the test does not resolve it"
        );
        assert!(
            bound_per_k >= truth,
            "seed {seed}: bound {bound_per_k:e} < truth {truth:e}"
        );
        // The bound is the estimate plus the detection threshold, and scales to the range.
        assert!(
            detectable_per_k > truth,
            "seed {seed}: {detectable_per_k:e}"
        );
        let range = r
            .bins
            .iter()
            .map(|b| b.temp_c)
            .fold(f64::NEG_INFINITY, f64::max)
            - r.bins
                .iter()
                .map(|b| b.temp_c)
                .fold(f64::INFINITY, f64::min);
        assert!((change_bound - bound_per_k * range).abs() < 1e-12);
        // The recommendation lists it as not resolvable (and so not among the warranted).
        let codes = r.recommendation.codes();
        assert!(
            codes.contains(&"not_resolvable"),
            "seed {seed}: {codes:?}: {}",
            r.recommendation
        );
    }
}
