//! Calibration file tests: round trips, content ids, the shipped example files, and error
//! messages that name the file, the line and the key.

mod common;

use common::*;
use imu_model::{Calibration, EffectKind, InputFile, ModelError, NoiseModel, Provenance, Triad};

fn full_calibration(seed: u64) -> Calibration {
    let mut rng = rng(seed);
    let mut cal = Calibration::identity();
    cal.id = Some("unit-7 2025-03-01".into());
    cal.description = Some("every effect, with std errors".into());
    cal.provenance = Provenance {
        created: Some("2025-03-01T12:00:00Z".into()),
        tool: Some("imu-calibrate 0.1.0".into()),
        procedure: Some("12-position static".into()),
        inputs: vec![
            InputFile {
                path: "logs/a.mcap".into(),
                sha256: Some("ab".repeat(32)),
            },
            InputFile {
                path: "logs/b.mcap".into(),
                sha256: None,
            },
        ],
        notes: Some("multi\nline \"quoted\" notes".into()),
        temperature_range_c: Some([21.5, 38.25]),
    };
    for t in Triad::ALL {
        let mut m = random_model(&applicable(t), t, &mut rng);
        let se: Vec<f64> = m.params().iter().map(|p| p.abs() * 0.01 + 1e-9).collect();
        m.set_std_errors(Some(&se));
        m.noise = Some(NoiseModel {
            white_density: [1e-3, 2e-3, 3e-3],
            bias_instability: [1e-4, 0.0, 3e-4],
            bias_instability_tau_max_s: 500.0,
            random_walk: [1e-5, 1e-5, 1e-5],
            quantization_lsb: [0.0, 1e-3, 1e-3],
        });
        m.residual_rms = Some([1e-3, 2e-3, 3e-3]);
        *cal.triad_mut(t) = m;
    }
    cal.validate().expect("valid");
    cal
}

fn parse_err(text: &str) -> String {
    match Calibration::from_toml_str(text, "calib.toml") {
        Ok(c) => panic!("expected an error, parsed {c:?}"),
        Err(e) => e.to_string(),
    }
}

fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "message lacks {p:?}: {msg}");
    }
}

#[test]
fn round_trip_preserves_every_field() {
    for seed in 0..5 {
        let cal = full_calibration(seed);
        let text = cal.to_toml_string();
        let back = Calibration::from_toml_str(&text, "round-trip.toml")
            .unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(back, cal, "\n{text}");
        assert_eq!(back.to_toml_string(), text);
        assert_eq!(back.content_id(), cal.content_id());
    }
}

#[test]
fn written_files_state_units() {
    let text = full_calibration(1).to_toml_string();
    assert_mentions(
        &text,
        &[
            "[accel.bias]\n# constant bias",
            "# units: value [m/s^2]",
            "# units: value [rad/s]",
            "# units: value [gauss]",
            "offset-m [m]",
            "quadratic [1/(rad/s)]; cubic [1/(rad/s)^2]",
            "coefficients [row k in (m/s^2)/K^k]",
            "white-density rad/s/sqrt(Hz)",
            "amplitude [gauss]; tau-s [s]",
        ],
    );
}

#[test]
fn content_id_is_stable_and_tracks_parameters_only() {
    let cal = full_calibration(2);
    let id = cal.content_id();
    assert_eq!(id.len(), 16);
    assert!(id.chars().all(|c| c.is_ascii_hexdigit()));
    assert_eq!(full_calibration(2).content_id(), id, "deterministic");

    let mut changed = cal.clone();
    let mut p = changed.gyro.params();
    p[0] += 1e-12;
    changed.gyro.set_params(&p);
    assert_ne!(
        changed.content_id(),
        id,
        "a parameter change must change the id"
    );

    let mut relabeled = cal.clone();
    relabeled.provenance.notes = Some("other notes".into());
    relabeled.description = None;
    relabeled.id = Some("another name".into());
    assert_eq!(
        relabeled.content_id(),
        id,
        "provenance and labels are not content"
    );

    assert_ne!(Calibration::identity().content_id(), id);
}

#[test]
fn the_documented_hand_written_example_parses() {
    let text = r#"
format = "imud-calibration/1"
description = "3DM-GX1-like unit with a hidden g-sensitivity"

[accel.bias]
value = [0.012, -0.020, 0.031]       # m/s^2
std-error = [0.0004, 0.0004, 0.0005] # optional everywhere

[accel.misalignment]
xy = 0.002
xz = -0.001
# omitted entries are 0

[gyro.g-sensitivity]
matrix = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0e-4, 0.0, 0.0]]  # rad/s per m/s^2

[gyro.noise]
white-density = [8.7e-4, 8.7e-4, 8.7e-4]    # rad/s/sqrt(Hz)
bias-instability = [1e-4, 1e-4, 1e-4]       # rad/s
"#;
    let cal = Calibration::from_toml_str(text, "example.toml").expect("parses");
    assert_eq!(
        cal.accel.bias.as_ref().map(|b| b.value),
        Some([0.012, -0.020, 0.031])
    );
    assert_eq!(
        cal.accel.bias.as_ref().and_then(|b| b.std_error),
        Some([0.0004, 0.0004, 0.0005])
    );
    let m = cal.accel.misalignment.as_ref().expect("present");
    assert_eq!((m.xy, m.xz, m.yx, m.zy), (0.002, -0.001, 0.0, 0.0));
    assert_eq!(
        cal.gyro.g_sensitivity.as_ref().map(|g| g.matrix[2][0]),
        Some(1.0e-4)
    );
    let n = cal.gyro.noise.as_ref().expect("present");
    assert_eq!(n.white_density, [8.7e-4; 3]);
    assert_eq!(n.random_walk, [0.0; 3]);
    assert_eq!(n.bias_instability_tau_max_s, 1000.0);
    assert!(cal.mag.is_empty());
    assert_eq!(
        cal.accel.kinds(),
        vec![EffectKind::Misalignment, EffectKind::Bias]
    );
}

#[test]
fn empty_and_absent_triads_are_identity() {
    let cal = Calibration::from_toml_str(
        "format = \"imud-calibration/1\"\n[accel]\n[gyro]\n",
        "empty.toml",
    )
    .expect("parses");
    assert_eq!(cal, Calibration::identity());
    // Integers are accepted where numbers are expected.
    let cal = Calibration::from_toml_str(
        "format = \"imud-calibration/1\"\n[mag.bias]\nvalue = [1, 0, -2]\n",
        "ints.toml",
    )
    .expect("parses");
    assert_eq!(cal.mag.bias.map(|b| b.value), Some([1.0, 0.0, -2.0]));
}

#[test]
fn every_shipped_model_file_parses() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).expect("config/models exists") {
        let path = entry.expect("readable").path();
        if path.extension().is_some_and(|e| e == "toml") {
            let cal = Calibration::load(&path).unwrap_or_else(|e| panic!("{e}"));
            // Saving and re-reading keeps it identical.
            let back =
                Calibration::from_toml_str(&cal.to_toml_string(), "re-read").expect("re-reads");
            assert_eq!(back, cal, "{}", path.display());
            n += 1;
        }
    }
    assert!(n >= 2, "expected the shipped examples in {}", dir.display());

    let identity = Calibration::load(&dir.join("identity.toml")).expect("loads");
    assert_eq!(identity.content_id(), Calibration::identity().content_id());
    let gx1 = Calibration::load(&dir.join("example-3dm-gx1.toml")).expect("loads");
    assert!(gx1.gyro.has(EffectKind::GSensitivity));
    assert!(gx1.accel.has(EffectKind::LeverArm));
    assert!(!gx1.gyro.has(EffectKind::TempBias) && !gx1.gyro.has(EffectKind::Warmup));
    let bi = gx1
        .accel
        .noise
        .as_ref()
        .expect("accel noise")
        .bias_instability;
    assert!((bi[1] - 100e-6 * imu_model::units::STANDARD_GRAVITY_M_S2).abs() < 1e-5);
}

#[test]
fn save_then_load_round_trips_and_io_errors_name_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("calibration.toml");
    let cal = full_calibration(3);
    cal.save(&path).expect("saves");
    assert_eq!(Calibration::load(&path).expect("loads"), cal);
    assert!(
        !dir.path().join("calibration.toml.tmp").exists(),
        "temporary file renamed away"
    );

    let missing = dir.path().join("nope.toml");
    let err = Calibration::load(&missing).unwrap_err();
    assert!(matches!(err, ModelError::Io { .. }));
    assert_mentions(&err.to_string(), &["nope.toml"]);
}

#[test]
fn typo_in_a_key_names_file_line_key_and_suggestion() {
    let msg =
        parse_err("format = \"imud-calibration/1\"\n\n[accel.bias]\nvlaue = [0.1, 0.2, 0.3]\n");
    assert_mentions(
        &msg,
        &[
            "calib.toml:4:1:",
            "unknown key `vlaue`",
            "[accel.bias]",
            "valid keys: value, std-error",
            "did you mean `value`",
        ],
    );
}

#[test]
fn unknown_effect_lists_the_valid_effects() {
    let msg = parse_err(
        "format = \"imud-calibration/1\"\ndescription = \"x\"\n\n[accel.biass]\nvalue = [0.1, 0.2, 0.3]\n",
    );
    assert_mentions(
        &msg,
        &[
            "calib.toml:4:8:",
            "unknown effect `biass` in [accel]",
            "valid effects: lever-arm, misalignment, scale,",
            "g-sensitivity",
            "did you mean `bias`",
        ],
    );
    // The same through a dotted key inside the triad table.
    let msg = parse_err("format = \"imud-calibration/1\"\n[gyro]\nscal.value = [0.1, 0.2, 0.3]\n");
    assert_mentions(
        &msg,
        &[
            "calib.toml:3:1:",
            "unknown effect `scal` in [gyro]",
            "did you mean `scale`",
        ],
    );
}

#[test]
fn wrong_array_length_names_the_key() {
    let msg = parse_err("format = \"imud-calibration/1\"\n[gyro.scale]\nvalue = [1e-3, 2e-3]\n");
    assert_mentions(
        &msg,
        &[
            "calib.toml:3:9:",
            "gyro.scale.value",
            "length 2",
            "[x, y, z]",
        ],
    );
}

#[test]
fn non_number_names_the_element() {
    let msg =
        parse_err("format = \"imud-calibration/1\"\n[gyro.bias]\nvalue = [0.1, \"fast\", 0.3]\n");
    assert_mentions(
        &msg,
        &[
            "calib.toml:3:15:",
            "gyro.bias.value[1]",
            "expected f64",
            "write a number",
        ],
    );
}

#[test]
fn unknown_top_level_key_and_noise_key() {
    let msg = parse_err("format = \"imud-calibration/1\"\ndescripton = \"x\"\n");
    assert_mentions(
        &msg,
        &[
            "calib.toml:2:1:",
            "unknown key `descripton` at the top level",
            "did you mean `description`",
        ],
    );
    let msg = parse_err(
        "format = \"imud-calibration/1\"\n[accel.noise]\nwhite-density = [1e-3, 1e-3, 1e-3]\nbias-instabilty = [1e-4, 1e-4, 1e-4]\n",
    );
    assert_mentions(
        &msg,
        &[
            "calib.toml:4:1:",
            "`bias-instabilty`",
            "[accel.noise]",
            "did you mean `bias-instability`",
        ],
    );
}

#[test]
fn missing_fields_and_syntax_errors_have_locations() {
    let msg =
        parse_err("format = \"imud-calibration/1\"\n\n[accel.bias]\nstd-error = [0.1, 0.2, 0.3]\n");
    assert_mentions(
        &msg,
        &["calib.toml:3:", "missing field `value`", "[accel.bias]"],
    );
    let msg = parse_err("[accel.bias]\nvalue = [0.1, 0.2, 0.3]\n");
    assert_mentions(
        &msg,
        &[
            "calib.toml:1:1:",
            "missing field `format`",
            "imud-calibration/1",
        ],
    );
    let msg = parse_err("format = \"imud-calibration/1\"\n[accel.bias]\nvalue = [0.1, 0.2, 0.3\n");
    assert_mentions(&msg, &["calib.toml:3:"]);
}

#[test]
fn out_of_domain_values_are_invalid_with_key_and_line() {
    let cases: &[(&str, &str, usize)] = &[
        (
            "[gyro.scale-nonlinearity]\nquadratic = [0.0, 0.0, 0.0]\ncubic = [0.0, -1e-3, 0.0]\n",
            "gyro.scale-nonlinearity.cubic[1]",
            4,
        ),
        (
            "[accel.asymmetric-scale]\nvalue = [0.0, 1.2, 0.0]\n",
            "accel.asymmetric-scale.value[1]",
            3,
        ),
        (
            "[mag.warmup]\namplitude = [0.1, 0.0, 0.0]\ntau-s = 0.0\n",
            "mag.warmup.tau-s",
            4,
        ),
        (
            "[gyro.lever-arm]\noffset-m = [0.01, 0.0, 0.0]\n",
            "gyro.lever-arm",
            2,
        ),
        (
            "[accel.g-sensitivity]\nmatrix = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]\n",
            "accel.g-sensitivity",
            2,
        ),
        (
            "[accel.misalignment]\nzy = 0.3\n",
            "accel.misalignment.zy",
            3,
        ),
        (
            "[accel.lever-arm]\noffset-m = [12.0, 0.0, 0.0]\n",
            "accel.lever-arm.offset-m[0]",
            3,
        ),
        (
            "[gyro.noise]\nwhite-density = [1e-3, -1e-3, 1e-3]\n",
            "gyro.noise.white-density[1]",
            3,
        ),
        (
            "[accel.temp-scale]\ncoefficients = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]\nstd-error = [[0.0, 0.0, 0.0]]\n",
            "accel.temp-scale.std-error",
            4,
        ),
        (
            "[gyro.scale]\nvalue = [0.0, nan, 0.0]\n",
            "gyro.scale.value[1]",
            3,
        ),
    ];
    for (body, key, line) in cases {
        let text = format!("format = \"imud-calibration/1\"\n{body}");
        let err = Calibration::from_toml_str(&text, "calib.toml").unwrap_err();
        match &err {
            ModelError::Invalid {
                key: k, line: l, ..
            } => {
                assert_eq!(k, key, "{err}");
                assert_eq!(*l, Some(*line), "{err}");
            }
            other => panic!("expected Invalid for {key}, got {other}"),
        }
        assert_mentions(&err.to_string(), &[&format!("calib.toml:{line}: {key}: ")]);
    }
    let err =
        Calibration::from_toml_str("format = \"imud-calibration/2\"\n", "calib.toml").unwrap_err();
    assert_mentions(
        &err.to_string(),
        &["calib.toml:1: format: ", "imud-calibration/1"],
    );
}

#[test]
fn validate_reports_models_built_in_code() {
    let mut cal = Calibration::identity();
    cal.gyro.add(EffectKind::Warmup);
    cal.gyro.warmup.as_mut().expect("added").tau_s = -1.0;
    let err = cal.validate().unwrap_err();
    assert_mentions(&err.to_string(), &["<memory>: gyro.warmup.tau-s: "]);
}
