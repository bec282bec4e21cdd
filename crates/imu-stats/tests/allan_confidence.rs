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

/// Runs the allantools peer on phase `x` at factors `ms` and asserts our deviation, noise type,
/// EDF and bounds equal its own at every factor both compute (at least `min_common` per kind);
/// returns the noise exponents seen.
fn assert_equal_to_allantools(
    name: &str,
    x: &[f64],
    ms: &[usize],
    confidence: f64,
    min_common: usize,
) -> std::collections::BTreeSet<i32> {
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
        .arg(confidence.to_string())
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
        let opts = greenhall(TauSet::Factors(ms.to_vec()), confidence);
        let (curve, noise) = deviation_from_phase_with_noise(kind, x, 1.0, &opts).unwrap();
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
            for (field, ours, tol) in [
                ("dev", p.dev, 1e-9),
                ("edf", p.edf, 1e-9),
                ("lo", p.dev_lo, 1e-6),
                ("hi", p.dev_hi, 1e-6),
            ] {
                let theirs = r[field].as_f64().unwrap();
                assert_within(&format!("{what} {field}"), ours, theirs, tol);
            }
        }
        assert!(
            compared >= min_common,
            "{name} {kind:?}: only {compared} taus in common"
        );
    }
    alphas
}

/// Our EDF, noise type and bounds equal allantools' (Greenhall EDF, Stable32's noise
/// identification from allantools' `ci` functions, chi-square bounds) at 95 % confidence on
/// PHASE.DAT and on a short mixed-noise series.
#[test]
fn bounds_equal_allantools_in_the_same_run() {
    if !peers_available() {
        return;
    }
    let ms = [1usize, 2, 3, 5, 8, 13, 30, 64, 100, 128, 250, 400, 700];
    for (name, x) in [("PHASE.DAT", phase_dat()), ("mixed", mixed_phase(6000))] {
        let alphas = assert_equal_to_allantools(name, &x, &ms, 0.95, 9);
        if name == "mixed" {
            assert!(
                alphas.len() >= 2,
                "the mixed series should change noise type: {alphas:?}"
            );
        }
    }
}

/// 500,000 phase points of white PM, white FM, flicker FM (a sum of first-order Markov
/// processes one per decade of correlation time, flat per decade: 1/f within 1 .. 1e6 s) and
/// random-walk FM, at octave factors and N/5 = 100,000: the regime where the decimated phase
/// has fewer than 30 points (m >= 16,384), where the noise type comes from the B1 ratio (ADEV,
/// HDEV) or the previous tau, and where the bounds used to collapse (issue 24). Every kind
/// against allantools' `ci` module in the same run, at 68.3 %.
#[test]
fn bounds_equal_allantools_on_a_long_record_to_n_over_5() {
    if !peers_available() {
        return;
    }
    let n = 500_000;
    let mut state: u64 = 24;
    let mut normal = || {
        // Sum of 4 uniforms: close enough to Gaussian for a noise model, and portable.
        (0..4)
            .map(|_| {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .sum::<f64>()
            * 3f64.sqrt()
    };
    let mut markov = [0.0f64; 7];
    let (mut walk, mut phase) = (0.0, 0.0);
    let x: Vec<f64> = (0..=n)
        .map(|_| {
            let mut flicker = 0.0;
            for (k, s) in markov.iter_mut().enumerate() {
                let rho = (-1.0 / 10f64.powi(k as i32)).exp();
                *s = rho * *s + (1.0 - rho * rho).sqrt() * normal();
                flicker += *s;
            }
            walk += 2e-4 * normal();
            let y = 1.0 * normal() + 0.02 * flicker + walk;
            phase += y;
            phase + 30.0 * normal()
        })
        .collect();
    let mut ms: Vec<usize> = (0..17).map(|k| 1 << k).collect();
    ms.push(n / 5);
    let alphas = assert_equal_to_allantools("long", &x, &ms, 0.683, 17);
    assert!(
        alphas.len() >= 3,
        "the long series should pass through several noise types: {alphas:?}"
    );
}
