//! Theo1 and TheoH at octave averaging times (issue 24): Theo1 on a 100,000-sample rate series
//! (white noise plus a random walk, 1 Hz, generated here), and TheoH, whose bias ratio costs
//! O(N^3 / 900), on 20,000 samples. Wall-clock seconds of `deviation` with the SP 1065 EDF.
//!
//! `cargo bench -p imu-stats --bench theo`

use std::time::Instant;

use imu_stats::allan::{Kind, Options, deviation};

/// White noise plus a random walk from a fixed-seed LCG (uniform steps).
fn series(n: usize) -> Vec<f64> {
    let mut state: u64 = 24;
    let mut uniform = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut walk = 0.0;
    (0..n)
        .map(|_| {
            walk += 1e-2 * uniform();
            uniform() + walk
        })
        .collect()
}

fn main() {
    for (kind, n) in [(Kind::Theo1, 100_000), (Kind::Theoh, 20_000)] {
        let y = series(n);
        let start = Instant::now();
        let curve = deviation(kind, &y, 1.0, &Options::default()).expect("deviation");
        let s = start.elapsed().as_secs_f64();
        let last = curve.points.last().expect("points");
        println!(
            "{:<6} N = {n:>7}: {:>2} octave taus to {:.0} s (m = {}) in {s:.2} s",
            kind.name(),
            curve.points.len(),
            last.tau_s,
            last.m
        );
    }
}
