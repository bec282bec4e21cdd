//! Theo1 and TheoH at octave averaging times (issue 24): Theo1 on a 100,000-sample rate series
//! (white noise plus a random walk, 1 Hz, generated here), and TheoH, whose bias ratio needs
//! Theo1 at N/30 factors up to 0.13 N, at the record lengths given as arguments (20,000,
//! 100,000 by default; 1,000,000 takes about ten minutes: `-- 1000000`). Wall-clock seconds of
//! `deviation` with the SP 1065 EDF.
//!
//! `cargo bench -p imu-stats --bench theo [-- N...]`

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
    let theoh_lengths: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let theoh_lengths = if theoh_lengths.is_empty() {
        vec![20_000, 100_000]
    } else {
        theoh_lengths
    };
    let runs = std::iter::once((Kind::Theo1, 100_000))
        .chain(theoh_lengths.into_iter().map(|n| (Kind::Theoh, n)));
    for (kind, n) in runs {
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
