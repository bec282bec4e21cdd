//! Link dropouts on a real pty (`[[dropout]]` in the scenario): the simulated 3DM-GX1 makes
//! every sample and writes its truth, but the replies inside the windows never reach imud;
//! imud records and publishes every other sample and counts exactly the lost ones in its
//! status (`samples_lost`, from the device's tick gaps).

use super::*;

/// 0.3 s at 2 s and 0.5 s at 4 s of scenario time (the scenario runs 7.5 s).
const WINDOWS: [(f64, f64); 2] = [(2.0, 0.3), (4.0, 0.5)];

#[test]
fn dropouts_on_the_pty_lose_their_samples_and_imud_counts_them() {
    let protocol = DeviceProtocol::Gx1;
    let dir = tempfile::tempdir().unwrap();
    let cal_path = dir.path().join("calibration.toml");
    std::fs::write(&cal_path, TRUTH).unwrap();
    let name = unique("dropouts");
    let mut opts = sim_options(dir.path(), false, protocol);
    let mut text = scenario(false, protocol);
    for (at_s, duration_s) in WINDOWS {
        text += &format!("[[dropout]]\nat-s = {at_s}\nduration-s = {duration_s}\n");
    }
    opts.scenario = Scenario::from_toml_str(&text, "e2e dropouts").unwrap();
    opts.scenario_text = text;
    let imud = Imud::start(dir.path(), &name, &dir.path().join("imu0"), &cal_path);
    let mut sub = Subscription::<CorrectedSample>::open(&name, Duration::from_secs(10))
        .unwrap_or_else(|e| panic!("{e}: {}", imud.stderr()));
    let (got, report) = collect_run(&mut sub, opts);
    let log = imud.terminate();
    assert!(report.completed);

    let truth = read_truth(&dir.path().join("truth.mcap")).unwrap();
    let data: Vec<f64> = truth
        .samples
        .iter()
        .filter(|s| is_data_command(s.command))
        .map(|s| s.t_s)
        .collect();
    let lost = data
        .iter()
        .filter(|&&t| WINDOWS.iter().any(|&(a, d)| a <= t && t < a + d))
        .count() as u64;
    // 80 samples at 100 Hz, to a sample at each window's ends (the stream's phase).
    assert!((78..=82).contains(&lost), "{lost} lost");
    assert_eq!(report.data_replies_lost, lost);
    let files = recordings(dir.path());
    assert_eq!(files.len(), 1, "{files:?}");
    let rec = read_recording(&files[0]).unwrap();
    assert_eq!(rec.raw.len() as u64, data.len() as u64 - lost, "{log}");
    assert_eq!(got.len(), rec.raw.len(), "{log}");
    let (_, status) = rec.statuses.last().expect("a status");
    assert_eq!(status.samples_lost, lost, "{log}");
}
