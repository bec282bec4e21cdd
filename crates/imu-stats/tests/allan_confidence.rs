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

/// (m, min sigma, sigma, max sigma) of one Stable32 row.
type Row = (usize, f64, f64, f64);

/// Stable32 1.60 on PHASE.DAT, octave taus, confidence factor 0.683: the rows per kind. Source: allantools (github.com/aewallin/allantools, commit 599dc9e),
/// tests/phasedat/phase_dat_{adev,oadev,mdev,hdev,ohdev,tdev,totdev}_octave.txt. Stable32
/// identified alpha = 0 (white FM) at every tau.
#[rustfmt::skip]
fn stable32_tables() -> Vec<(Kind, Vec<Row>)> {
    // A flat table of published values.
    vec![
        (Kind::Adev, vec![
            (1, 2.8515e-01, 2.9223e-01, 2.9987e-01), (2, 1.9787e-01, 2.0510e-01, 2.1319e-01),
            (4, 1.4201e-01, 1.4943e-01, 1.5815e-01), (8, 1.0254e-01, 1.1013e-01, 1.1971e-01),
            (16, 5.6510e-02, 6.2381e-02, 7.0567e-02), (32, 4.9153e-02, 5.6233e-02, 6.7635e-02),
            (64, 2.7109e-02, 3.2550e-02, 4.3537e-02), (128, 2.6481e-02, 3.3855e-02, 5.5744e-02)]),
        (Kind::Oadev, vec![
            (1, 2.8515e-01, 2.9223e-01, 2.9987e-01), (2, 1.9520e-01, 2.0102e-01, 2.0738e-01),
            (4, 1.3931e-01, 1.4479e-01, 1.5098e-01), (8, 1.0038e-01, 1.0570e-01, 1.1198e-01),
            (16, 5.7696e-02, 6.1915e-02, 6.7217e-02), (32, 4.3654e-02, 4.8082e-02, 5.4202e-02),
            (64, 3.1755e-02, 3.6237e-02, 4.3377e-02), (128, 2.3045e-02, 2.7674e-02, 3.7027e-02)]),
        (Kind::Mdev, vec![
            (1, 2.8515e-01, 2.9223e-01, 2.9987e-01), (2, 1.5336e-01, 1.5821e-01, 1.6355e-01),
            (4, 1.0322e-01, 1.0780e-01, 1.1304e-01), (8, 6.9840e-02, 7.4192e-02, 7.9481e-02),
            (16, 3.8022e-02, 4.1376e-02, 4.5809e-02), (32, 3.0466e-02, 3.4255e-02, 3.9933e-02),
            (64, 2.3687e-02, 2.7871e-02, 3.5511e-02), (128, 1.4874e-02, 1.8669e-02, 2.8584e-02)]),
        (Kind::Hdev, vec![
            (1, 2.8635e-01, 2.9439e-01, 3.0315e-01), (2, 1.9887e-01, 2.0716e-01, 2.1659e-01),
            (4, 1.4054e-01, 1.4890e-01, 1.5896e-01), (8, 1.0744e-01, 1.1649e-01, 1.2829e-01),
            (16, 5.3296e-02, 5.9589e-02, 6.8811e-02), (32, 4.6987e-02, 5.4697e-02, 6.8092e-02),
            (64, 2.4870e-02, 3.0569e-02, 4.3652e-02), (128, 2.8841e-02, 3.8060e-02, 7.3807e-02)]),
        (Kind::Ohdev, vec![
            (1, 2.8635e-01, 2.9439e-01, 3.0315e-01), (2, 1.9491e-01, 2.0125e-01, 2.0825e-01),
            (4, 1.3777e-01, 1.4368e-01, 1.5043e-01), (8, 1.0388e-01, 1.0987e-01, 1.1704e-01),
            (16, 5.6173e-02, 6.0638e-02, 6.6369e-02), (32, 4.0664e-02, 4.5095e-02, 5.1382e-02),
            (64, 2.9271e-02, 3.3824e-02, 4.1477e-02), (128, 2.3761e-02, 2.9147e-02, 4.1367e-02)]),
        (Kind::Tdev, vec![
            (1, 1.6463e-01, 1.6872e-01, 1.7313e-01), (2, 1.7709e-01, 1.8268e-01, 1.8885e-01),
            (4, 2.3838e-01, 2.4895e-01, 2.6106e-01), (8, 3.2258e-01, 3.4268e-01, 3.6710e-01),
            (16, 3.5123e-01, 3.8221e-01, 4.2317e-01), (32, 5.6287e-01, 6.3287e-01, 7.3777e-01),
            (64, 8.7525e-01, 1.0298e+00, 1.3122e+00), (128, 1.0992e+00, 1.3797e+00, 2.1124e+00)]),
        (Kind::Totdev, vec![
            (1, 2.8707e-01, 2.9223e-01, 2.9768e-01), (2, 1.9592e-01, 2.0089e-01, 2.0625e-01),
            (4, 1.3947e-01, 1.4444e-01, 1.4998e-01), (8, 1.0039e-01, 1.0540e-01, 1.1126e-01),
            (16, 5.7732e-02, 6.1788e-02, 6.6839e-02), (32, 4.4255e-02, 4.8580e-02, 5.4484e-02),
            (64, 3.1639e-02, 3.5905e-02, 4.2546e-02), (128, 2.6406e-02, 3.1259e-02, 4.0383e-02),
            (256, 1.0734e-02, 1.3369e-02, 1.9924e-02)]),
    ]
}

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
