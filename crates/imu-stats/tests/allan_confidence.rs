//! Confidence intervals of every deviation kind (Greenhall's EDF with lag-1 autocorrelation
//! noise identification) against Stable32's published bounds on PHASE.DAT, and against Python
//! allantools computing the same algorithm in the same run (skipped when python3/allantools is
//! missing, unless IMUD_REQUIRE_PEERS is set).

use std::path::PathBuf;
use std::process::Command;

use imu_stats::allan::{
    DevCurve, EdfMethod, Kind, NoiseType, Options, TauSet, deviation_from_phase_with_noise,
};

/// PHASE.DAT (distributed with Stable32; the copy in allantools' test data), 1001 phase points.
fn phase_dat() -> Vec<f64> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/phase_dat.txt");
    std::fs::read_to_string(&path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| l.trim().parse().unwrap())
        .collect()
}

fn greenhall(taus: TauSet, confidence: f64) -> Options {
    Options {
        taus,
        edf: EdfMethod::Greenhall,
        confidence,
        noise: None,
    }
}

// `stable32_tables()`: Stable32's published PHASE.DAT tables (shared with imu-noise's CLI test).
include!("data/stable32_phase_dat.rs");

fn point(curve: &DevCurve, m: usize) -> &imu_stats::allan::DevPoint {
    curve
        .points
        .iter()
        .find(|p| p.m == m)
        .unwrap_or_else(|| panic!("{:?}: no m = {m}", curve.kind))
}

fn assert_within(what: &str, got: f64, want: f64, tol: f64) {
    let rel = (got / want - 1.0).abs();
    assert!(
        rel < tol,
        "{what}: got {got:.5e}, want {want:.5e} (rel {rel:.1e})"
    );
}

/// Every kind's deviation (to Stable32's 5-digit rounding) and both bounds (to 1 %, the
/// tolerance of the issue; they agree to about 5e-4) and the identified noise type.
#[test]
fn bounds_equal_stable32_on_phase_dat_for_every_kind() {
    let x = phase_dat();
    assert_eq!(x.len(), 1001);
    let mut worst: f64 = 0.0;
    for (kind, rows) in stable32_tables() {
        let (curve, noise) =
            deviation_from_phase_with_noise(kind, &x, 1.0, &greenhall(TauSet::Octave, 0.683))
                .unwrap();
        assert!(
            noise.iter().all(|&t| t == NoiseType::WhiteFm),
            "{kind:?} {noise:?}"
        );
        for (m, lo, dev, hi) in rows {
            let p = point(&curve, m);
            let what = format!("{kind:?} m {m}");
            assert_within(&format!("{what} dev"), p.dev, dev, 1e-4);
            assert_within(&format!("{what} min"), p.dev_lo, lo, 1e-2);
            assert_within(&format!("{what} max"), p.dev_hi, hi, 1e-2);
            worst = worst.max((p.dev_lo / lo - 1.0).abs().max((p.dev_hi / hi - 1.0).abs()));
        }
    }
    // The 1 % tolerance is loose: the bounds are Stable32's to its rounding.
    assert!(worst < 1e-3, "worst bound difference {worst:e}");
}

fn peer_script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/python/allantools_ci_peer.py")
}

fn peers_available() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import allantools"])
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        assert!(
            std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
            "IMUD_REQUIRE_PEERS is set but python3 with allantools is missing \
             (pip install -r requirements-dev.txt)"
        );
        eprintln!("skipping: python3 with allantools not found");
    }
    ok
}

/// A phase series with several power laws at once: white PM, white FM and random-walk FM,
/// so that the identified type changes along the taus.
fn mixed_phase(n: usize) -> Vec<f64> {
    let mut state: u64 = 99;
    let mut uniform = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let (mut freq_walk, mut phase) = (0.0, 0.0);
    (0..n)
        .map(|_| {
            freq_walk += 0.003 * uniform();
            phase += 0.2 * uniform() + freq_walk;
            phase + 3.0 * uniform()
        })
        .collect()
}

/// Our EDF, noise type and bounds equal allantools' (Greenhall EDF, lag-1 ACF noise id,
/// chi-square bounds) at 95 % confidence on PHASE.DAT and on a mixed-noise series.
#[test]
fn bounds_equal_allantools_in_the_same_run() {
    if !peers_available() {
        return;
    }
    let ms = [1usize, 2, 3, 5, 8, 13, 30, 64, 100, 128, 250, 400, 700];
    for (name, x) in [("PHASE.DAT", phase_dat()), ("mixed", mixed_phase(6000))] {
        let dir = tempfile::tempdir().unwrap();
        let data = dir.path().join("x.f64");
        let bytes: Vec<u8> = x.iter().flat_map(|v| v.to_le_bytes()).collect();
        std::fs::write(&data, bytes).unwrap();
        let list: Vec<String> = ms.iter().map(|m| m.to_string()).collect();
        let out = Command::new("python3")
            .arg(peer_script())
            .arg(&data)
            .arg("1")
            .arg("adev,oadev,mdev,hdev,ohdev,tdev,totdev")
            .arg(list.join(","))
            .arg("0.95")
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let peer: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let mut alphas = std::collections::BTreeSet::new();
        for kind in Kind::ALL {
            let rows = peer[kind.name()].as_array().unwrap();
            let opts = greenhall(TauSet::Factors(ms.to_vec()), 0.95);
            let (curve, noise) = deviation_from_phase_with_noise(kind, &x, 1.0, &opts).unwrap();
            // The two libraries stop at different longest taus for some kinds: compare where
            // both have a value.
            let mut compared = 0;
            for (p, t) in curve.points.iter().zip(&noise) {
                let Some(r) = rows.iter().find(|r| r["m"].as_u64() == Some(p.m as u64)) else {
                    continue;
                };
                compared += 1;
                let what = format!("{name} {kind:?} m {}", p.m);
                assert_eq!(i64::from(t.alpha()), r["alpha"].as_i64().unwrap(), "{what}");
                alphas.insert(t.alpha());
                assert_within(
                    &format!("{what} dev"),
                    p.dev,
                    r["dev"].as_f64().unwrap(),
                    1e-9,
                );
                assert_within(
                    &format!("{what} edf"),
                    p.edf,
                    r["edf"].as_f64().unwrap(),
                    1e-9,
                );
                assert_within(
                    &format!("{what} lo"),
                    p.dev_lo,
                    r["lo"].as_f64().unwrap(),
                    1e-6,
                );
                assert_within(
                    &format!("{what} hi"),
                    p.dev_hi,
                    r["hi"].as_f64().unwrap(),
                    1e-6,
                );
            }
            assert!(
                compared >= 9,
                "{name} {kind:?}: only {compared} taus in common"
            );
        }
        if name == "mixed" {
            assert!(
                alphas.len() >= 2,
                "the mixed series should change noise type: {alphas:?}"
            );
        }
    }
}
