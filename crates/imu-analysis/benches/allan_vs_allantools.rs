//! Speed and agreement of our octave-tau OADEV against Python allantools on one 10-million-sample
//! rate series (white + flicker + random walk), in the same run:
//! `cargo bench -p imu-analysis --bench allan_vs_allantools`.

use std::process::Command;
use std::time::Instant;

use imu_model::{NoiseGenerator, NoiseModel};
use imu_stats::allan::{Kind, Options, StreamingOadev, TauSet, deviation};

const N_SAMPLES: usize = 10_000_000;

fn main() {
    let model = NoiseModel {
        white_density: [1e-3; 3],
        bias_instability: [2.4e-4; 3],
        random_walk: [1e-5; 3],
        ..NoiseModel::default()
    };
    let mut g = NoiseGenerator::new(&model, 1.0, 1);
    let y: Vec<f64> = (0..N_SAMPLES).map(|_| g.next()[0]).collect();
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("y.f64");
    std::fs::write(
        &path,
        y.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>(),
    )
    .expect("write series");

    let opts = Options {
        taus: TauSet::Octave,
        ..Options::default()
    };
    // Best of 3 (the first run also faults the pages in).
    let mut ours_s = f64::INFINITY;
    let mut curve = None;
    for _ in 0..3 {
        let t = Instant::now();
        let c = deviation(Kind::Oadev, &y, 1.0, &opts).expect("oadev");
        ours_s = ours_s.min(t.elapsed().as_secs_f64());
        curve = Some(c);
    }
    let curve = curve.expect("ran");
    let t = Instant::now();
    let mut s = StreamingOadev::new(1.0, N_SAMPLES / 2);
    s.extend(&y);
    let stream = s.curve(0.683, None);
    let stream_s = t.elapsed().as_secs_f64();

    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/python/allantools_peer.py"
    );
    let out = Command::new("python3")
        .args([
            script,
            path.to_str().expect("utf-8 path"),
            "1.0",
            "oadev",
            "octave",
        ])
        .output()
        .expect("run python3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let peer: serde_json::Value = serde_json::from_slice(&out.stdout).expect("peer json");
    let peer_s = peer["compute_s"].as_f64().expect("compute_s");
    let ptaus = peer["oadev"]["taus"].as_array().expect("taus");
    let pdevs = peer["oadev"]["devs"].as_array().expect("devs");
    let mut max_rel: f64 = 0.0;
    let mut compared = 0;
    for (t, d) in ptaus.iter().zip(pdevs) {
        let m = t.as_f64().expect("tau").round() as usize;
        if let Some(p) = curve.points.iter().find(|p| p.m == m) {
            max_rel = max_rel.max((p.dev / d.as_f64().expect("dev") - 1.0).abs());
            compared += 1;
        }
    }
    let mut stream_rel: f64 = 0.0;
    for (a, b) in stream.points.iter().zip(&curve.points) {
        stream_rel = stream_rel.max((a.dev / b.dev - 1.0).abs());
    }
    println!(
        "series: {N_SAMPLES} samples, octave taus: ours {} , allantools {}",
        curve.points.len(),
        ptaus.len()
    );
    println!("ours (batch OADEV, best of 3): {:.3} s", ours_s);
    println!("ours (streaming OADEV):        {:.3} s", stream_s);
    println!(
        "allantools {} oadev:      {:.3} s",
        peer["allantools_version"].as_str().unwrap_or("?"),
        peer_s
    );
    println!("speed ratio allantools/ours:   {:.1}x", peer_s / ours_s);
    println!("max relative difference ({compared} taus): {max_rel:.2e}");
    println!("streaming vs batch max relative difference: {stream_rel:.2e}");
}
