//! The workbench benchmark's recording where effects are claimed
//! (`config/scenarios/hand-held-effects-long.toml`: 38 hand-held poses over 511 s, raw counts,
//! no reference, an accel scale nonlinearity, a gyro asymmetric scale and a gyro g-sensitivity
//! hidden in the truth) held against the simulator's truth: the reference-free ladder from the
//! base model adds exactly the three hidden effects, each claim confirmed on held-out poses or
//! moves, the final model is consistent with the moves, and every fitted parameter of the three
//! effects is the truth's (in the accel frame, the procedure's gauge) within 3 standard errors.
//! The same recording (seed 7) is what `cargo bench --bench workbench_hand_held` times.

use std::collections::BTreeSet;

use imu_analysis::calibrate::reference_free::in_accel_frame;
use imu_analysis::input::{Source, read_mcap};
use imu_analysis::workbench::{DiagnoseOptions, Workbench};
use imu_model::{Calibration, EffectKind, Triad, TriadModel};

const SCENARIO: &str = include_str!("../../../config/scenarios/hand-held-effects-long.toml");
const TRUTH: &str = include_str!("../../../config/models/raw-uncompensated-effects.toml");

/// The effects the truth hides beyond bias, scale and misalignment.
const HIDDEN: [(Triad, EffectKind); 3] = [
    (Triad::Accel, EffectKind::ScaleNonlinearity),
    (Triad::Gyro, EffectKind::AsymmetricScale),
    (Triad::Gyro, EffectKind::GSensitivity),
];

#[test]
fn the_ladder_claims_the_three_hidden_effects_with_the_truths_values() {
    let dir = tempfile::tempdir().unwrap();
    // The truth model is passed as text: the scenario's relative `truth` path is dropped.
    let scenario: String = SCENARIO
        .lines()
        .filter(|l| !l.starts_with("truth"))
        .collect::<Vec<_>>()
        .join("\n");
    let session =
        imud::offline::record_session_text(dir.path(), "hh", &scenario, Some(TRUTH), 7, None)
            .unwrap();
    let series = read_mcap(&session.recording, Source::Raw, None).unwrap();
    let wb =
        Workbench::reference_free(&series, None, Some(40.0), DiagnoseOptions::default()).unwrap();
    let mut base = Calibration::identity();
    base.accel = TriadModel::with_effects(&TriadModel::PAPER_BASE);
    base.gyro = TriadModel::with_effects(&TriadModel::PAPER_BASE);
    let ladder = wb.ladder(&base).unwrap();
    for d in &ladder.final_diagnoses {
        eprintln!("{}", d.verdict);
    }

    // Exactly the hidden effects are added, each through the held-out check.
    let added: BTreeSet<(Triad, EffectKind)> =
        ladder.steps.iter().filter_map(|s| s.added).collect();
    assert_eq!(added, BTreeSet::from(HIDDEN), "{:?}", ladder.steps);
    assert_eq!(ladder.steps.len(), 1 + HIDDEN.len());
    for s in &ladder.steps[1..] {
        let h = s
            .held_out
            .as_ref()
            .expect("a claim carries its held-out check");
        assert!(h.confirmed, "{:?}: {h:?}", s.added);
    }
    // The final gyro gains are consistent with the rotations over the moves.
    let moves = ladder.steps.last().unwrap().gyro.moves.clone().unwrap();
    assert!(moves.consistent, "{moves:?}");

    // Every parameter of the three effects against the truth, in the procedure's gauge.
    let truth = in_accel_frame(&Calibration::from_toml_str(TRUTH, "truth.toml").unwrap());
    let cal = &ladder.calibration;
    let mut checked = 0;
    for (triad, effect) in HIDDEN {
        let (fit, want) = (cal.triad(triad), truth.triad(triad));
        let (want_ids, want_values) = (want.param_ids(), want.params());
        let (values, se) = (fit.params(), fit.std_errors());
        for (i, id) in fit.param_ids().iter().enumerate() {
            if id.effect != effect {
                continue;
            }
            // A parameter the truth does not set (the nonlinearity's cubic term) is 0.
            let t = want_ids
                .iter()
                .position(|w| w == id)
                .map_or(0.0, |j| want_values[j]);
            let s = se[i].unwrap_or_else(|| panic!("{triad} {}: no standard error", id.name));
            eprintln!(
                "{triad} {}: {:.4e} +/- {s:.1e} (truth {t:.4e})",
                id.name, values[i]
            );
            assert!(
                (values[i] - t).abs() < 3.0 * s,
                "{triad} {}: {:.4e} +/- {s:.1e} vs truth {t:.4e}",
                id.name,
                values[i]
            );
            checked += 1;
        }
    }
    // Quadratic and cubic per accel axis, three asymmetries, nine g-sensitivities.
    assert_eq!(checked, 6 + 3 + 9);
}
