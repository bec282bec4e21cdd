//! Compares our OADEV, MDEV, HDEV and TDEV with Python allantools (the independent peer) on a
//! small series at several taus, to 1e-9 relative. Skipped when python3/allantools is missing,
//! unless IMUD_REQUIRE_PEERS is set (then missing peers fail the test).

use std::path::PathBuf;
use std::process::Command;

use imu_stats::allan::{Kind, Options, TauSet, deviation};

fn peer_script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/python/allantools_peer.py")
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

#[test]
fn oadev_mdev_hdev_tdev_equal_allantools() {
    if !peers_available() {
        return;
    }
    // Deterministic white + random-walk series.
    let mut state: u64 = 7;
    let mut uniform = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut walk = 0.0;
    let y: Vec<f64> = (0..5000)
        .map(|_| {
            walk += 0.01 * uniform();
            1.0 + uniform() + walk
        })
        .collect();
    let rate_hz = 10.0;
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("y.f64");
    std::fs::write(
        &data,
        y.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>(),
    )
    .unwrap();
    let ms = [1usize, 2, 3, 5, 10, 37, 100, 400, 1000];
    let taus: Vec<String> = ms
        .iter()
        .map(|m| format!("{}", *m as f64 / rate_hz))
        .collect();
    let out = Command::new("python3")
        .arg(peer_script())
        .arg(&data)
        .arg(rate_hz.to_string())
        .arg("oadev,mdev,hdev,tdev")
        .arg(taus.join(","))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let peer: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let opts = Options {
        taus: TauSet::All,
        ..Options::default()
    };
    for (name, kind) in [
        ("oadev", Kind::Oadev),
        ("mdev", Kind::Mdev),
        ("hdev", Kind::Hdev),
        ("tdev", Kind::Tdev),
    ] {
        let ours = deviation(kind, &y, 1.0 / rate_hz, &opts).unwrap();
        let p = &peer[name];
        let ptaus = p["taus"].as_array().unwrap();
        let pdevs = p["devs"].as_array().unwrap();
        assert!(ptaus.len() >= 6, "{name}: allantools returned {ptaus:?}");
        for (t, d) in ptaus.iter().zip(pdevs) {
            let m = (t.as_f64().unwrap() * rate_hz).round() as usize;
            let want = d.as_f64().unwrap();
            let got = ours.points.iter().find(|q| q.m == m).unwrap().dev;
            let rel = (got / want - 1.0).abs();
            assert!(
                rel < 1e-9,
                "{name} m={m}: ours {got:e} allantools {want:e} rel {rel:e}"
            );
        }
    }
}
