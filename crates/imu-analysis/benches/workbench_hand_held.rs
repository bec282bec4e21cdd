//! Time of the model workbench on a real-sized hand-held recording (issue 25 item 3: the
//! reference-free `imu-diagnose` under 1 s and `imu-diagnose ladder` under 2 s):
//! `cargo bench -p imu-analysis --bench workbench_hand_held`.
//!
//! Two recordings, each made once through imud's offline path, seed 7 (`IMUD_BENCH_SEED` for
//! another): `config/scenarios/hand-held-raw-long.toml` (38 hand-held poses of an uncompensated
//! unit, about 511 s at 100 Hz; nothing beyond the base model hidden, so nothing is claimed) and
//! `config/scenarios/hand-held-effects-long.toml` (the same poses and hand, three effects hidden:
//! the ladder claims them, with cross-validation, over several steps). `IMUD_BENCH_SCENARIO`
//! (`hand-held-raw-long` or `hand-held-effects-long`) runs one. Timed, each `IMUD_BENCH_RUNS`
//! times (default 5), median
//! printed: opening the reference-free workbench (segmentation, noise floors, the moves), the
//! diagnosis of the base model on both triads (what `imu-diagnose --reference-free` computes),
//! and the ladder from the base model (what `imu-diagnose ladder --reference-free` computes
//! after the workbench is open). Also printed: the claims and a digest of every number of the
//! diagnosis's JSON, so that two builds can be shown to give the same results.

use std::time::{Duration, Instant};

use imu_analysis::input::{Source, read_mcap};
use imu_analysis::workbench::{DiagnoseOptions, Workbench};
use imu_model::{Calibration, Triad, TriadModel};

/// (name, scenario, truth model) of each recording.
const RECORDINGS: [(&str, &str, &str); 2] = [
    (
        "hand-held-raw-long",
        include_str!("../../../config/scenarios/hand-held-raw-long.toml"),
        include_str!("../../../config/models/raw-uncompensated.toml"),
    ),
    (
        "hand-held-effects-long",
        include_str!("../../../config/scenarios/hand-held-effects-long.toml"),
        include_str!("../../../config/models/raw-uncompensated-effects.toml"),
    ),
];

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// CPU time of this process so far (user + system, every thread), s: Linux's
/// `/proc/self/stat` in clock ticks of 1/100 s (USER_HZ); None elsewhere. On a shared machine
/// the wall time depends on the load, the CPU time much less.
fn cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn median_f(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// FNV-1a over the bytes of `text`: a short fingerprint of the whole JSON.
fn digest(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

fn main() {
    let seed: u64 = env_or("IMUD_BENCH_SEED", 7);
    let runs: usize = env_or("IMUD_BENCH_RUNS", 5).max(1);
    let only = std::env::var("IMUD_BENCH_SCENARIO").ok();
    for (name, scenario, truth) in RECORDINGS {
        if only.as_deref().is_none_or(|o| o == name) {
            println!("== {name}");
            bench(scenario, truth, seed, runs);
        }
    }
}

/// Records `scenario` with the truth model `truth` and times the workbench on it.
fn bench(scenario: &str, truth: &str, seed: u64, runs: usize) {
    let dir = tempfile::tempdir().expect("temporary directory");
    // The truth model is passed as text: the scenario's relative `truth` path is dropped.
    let scenario: String = scenario
        .lines()
        .filter(|l| !l.starts_with("truth"))
        .collect::<Vec<_>>()
        .join("\n");
    let t = Instant::now();
    let session =
        imud::offline::record_session_text(dir.path(), "hh", &scenario, Some(truth), seed, None)
            .expect("recording the scenario");
    let series = read_mcap(&session.recording, Source::Raw, None).expect("reading it back");
    println!(
        "recording: {} samples, {:.1} s (made in {:.1} s)",
        series.len(),
        series.t_s.last().copied().unwrap_or(0.0) - series.t_s.first().copied().unwrap_or(0.0),
        t.elapsed().as_secs_f64()
    );

    let mut base = Calibration::identity();
    base.accel = TriadModel::with_effects(&TriadModel::PAPER_BASE);
    base.gyro = TriadModel::with_effects(&TriadModel::PAPER_BASE);
    let open = || {
        Workbench::reference_free(&series, None, Some(40.0), DiagnoseOptions::default())
            .expect("workbench")
    };
    let (mut t_open, mut t_diag, mut t_ladder) = (Vec::new(), Vec::new(), Vec::new());
    let (mut cpu_diag, mut cpu_ladder) = (Vec::new(), Vec::new());
    let mut fingerprint = None;
    for _ in 0..runs {
        let t = Instant::now();
        let wb = open();
        t_open.push(t.elapsed());
        let (t, c) = (Instant::now(), cpu_s());
        let accel = wb.diagnose(Triad::Accel, &base.accel).expect("accel");
        let gyro = wb.diagnose(Triad::Gyro, &base.gyro).expect("gyro");
        t_diag.push(t.elapsed());
        cpu_diag.extend(c.zip(cpu_s()).map(|(a, b)| b - a));
        let (t, c) = (Instant::now(), cpu_s());
        let ladder = wb.ladder(&base).expect("ladder");
        t_ladder.push(t.elapsed());
        cpu_ladder.extend(c.zip(cpu_s()).map(|(a, b)| b - a));
        let json = serde_json::to_string(&(&accel, &gyro, &ladder)).expect("json");
        let claims: Vec<String> = [&accel, &gyro]
            .iter()
            .flat_map(|d| d.candidates.iter().filter(|c| c.claimed))
            .map(|c| format!("{} {}", c.triad, c.effect))
            .collect();
        let added: Vec<String> = ladder
            .steps
            .iter()
            .filter_map(|s| s.added)
            .map(|(t, k)| format!("{t} {k}"))
            .collect();
        let f = (
            digest(&json),
            format!("{:?} / {:?}", accel.state, gyro.state),
            claims,
            added,
        );
        assert!(
            fingerprint.as_ref().is_none_or(|g| *g == f),
            "the runs differ: {fingerprint:?} vs {f:?}"
        );
        fingerprint = Some(f);
    }
    let (open_s, diag_s, ladder_s) = (
        median(t_open).as_secs_f64(),
        median(t_diag).as_secs_f64(),
        median(t_ladder).as_secs_f64(),
    );
    println!("median of {runs} runs:");
    println!("  open the workbench                 {open_s:.3} s");
    println!(
        "  diagnose accel + gyro              {diag_s:.3} s (CPU {:.2} s)",
        median_f(cpu_diag)
    );
    println!(
        "  ladder                             {ladder_s:.3} s (CPU {:.2} s)",
        median_f(cpu_ladder)
    );
    println!(
        "  imu-diagnose (open + diagnose)     {:.3} s (target 1 s)",
        open_s + diag_s
    );
    println!(
        "  imu-diagnose ladder (open + ladder) {:.3} s (target 2 s)",
        open_s + ladder_s
    );
    if let Some((d, states, claims, added)) = fingerprint {
        println!(
            "results: states {states}, claims {claims:?}, ladder added {added:?}, JSON digest \
             {d:016x}"
        );
    }
}
