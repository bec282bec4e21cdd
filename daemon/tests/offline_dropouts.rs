//! Link dropouts in an offline recording (`imud --sim --offline` with `[[dropout]]`): for
//! every protocol, the recording holds exactly the truth's data samples outside the dropout
//! windows, and the daemon's loss counter (the status's `samples_lost`) counts exactly the
//! samples lost; and the recording names its unit (model, serial number). (What the reader says of the same gaps, `missing_samples`:
//! python/tests/test_recording_info.py.)

use imu_bus::recording::read_recording;
use imu_bus::truth::{is_data_command, read_truth};
use imu_sim::SimOptions;
use imud::config::Config;

/// Two dropouts: 0.5 s at 3 s, 1 s from 5.005 s.
const WINDOWS: [(f64, f64); 2] = [(3.0, 0.5), (5.005, 1.0)];

fn scenario(protocol: &str) -> String {
    let mut s = format!(
        "name = \"lossy\"\nrate-hz = 100.0\n[device]\nprotocol = \"{protocol}\"\n\
         [[segment]]\nkind = \"static\"\nduration-s = 8.0\n"
    );
    for (at_s, duration_s) in WINDOWS {
        s += &format!("[[dropout]]\nat-s = {at_s}\nduration-s = {duration_s}\n");
    }
    s
}

#[test]
fn dropouts_lose_exactly_their_samples_and_the_daemon_counts_them() {
    for protocol in ["3dm-gx1", "mip", "xsens", "vectornav"] {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lossy.toml");
        std::fs::write(&path, scenario(protocol)).unwrap();
        let mut sim = SimOptions::from_files(&path, None).unwrap();
        sim.seed = 4;
        sim.truth_out = Some(dir.path().join("truth.mcap"));
        let mut config = Config::default();
        config.log.dir = dir.path().join("logs");
        config.name = "lossy".into();
        let report = imud::offline::record(sim, &config).unwrap();
        let truth = read_truth(&dir.path().join("truth.mcap")).unwrap();
        let data: Vec<f64> = truth
            .samples
            .iter()
            .filter(|s| is_data_command(s.command))
            .map(|s| s.t_s)
            .collect();
        assert_eq!(data.len(), 800, "{protocol}: the truth keeps every sample");
        assert_eq!(truth.run["dropouts-s"], "3..3.5,5.005..6.005", "{protocol}");
        let lost = data
            .iter()
            .filter(|&&t| WINDOWS.iter().any(|&(a, d)| a <= t && t < a + d))
            .count() as u64;
        assert_eq!(lost, 150, "{protocol}");
        assert_eq!(report.dropped, lost, "{protocol}");
        assert_eq!(report.samples, data.len() as u64 - lost, "{protocol}");
        assert_eq!(
            report.samples_lost, lost,
            "{protocol}: the daemon's loss counter"
        );
        assert_eq!(report.files.len(), 1, "{protocol}");
        let rec = read_recording(&report.files[0]).unwrap();
        assert_eq!(rec.raw.len() as u64, report.samples, "{protocol}");
        assert_eq!(rec.imu.len() as u64, report.samples, "{protocol}");
        // The unit is named as the live daemon names it: model and serial number.
        let device = &rec.metadata["imud.device"];
        assert!(!device["model"].is_empty(), "{protocol}: {device:?}");
        assert_eq!(device["serial-number"], "1001", "{protocol}");
    }
}
