//! The simulator's truth file, written through the real pty path, is read identically by our
//! reader and by the reference Python `mcap` reader (an independent peer).

use std::path::Path;
use std::time::Duration;

use imu_bus::truth::read_truth;
use imu_proto::command::Command;
use imu_proto::decoder::{DecodeEvent, ReplyDecoder};
use imu_sim::{Pacing, SimOptions};
use imud_e2e::repo_root;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_serial::SerialPortBuilderExt;

/// Runs the Python peer; a missing peer skips the comparison locally but fails under CI
/// (`IMUD_REQUIRE_PEERS=1`), so the check can never silently vanish from the pipeline.
fn python_summary(truth: &Path) -> Option<serde_json::Value> {
    let script = repo_root().join("tests/python/read_truth.py");
    let out = std::process::Command::new("python3")
        .arg(&script)
        .arg(truth)
        .output();
    match out {
        Ok(o) if o.status.success() => {
            Some(serde_json::from_slice(&o.stdout).expect("peer prints JSON"))
        }
        other => {
            let why = format!("{other:?}");
            assert!(
                std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
                "Python mcap peer unavailable: {why}"
            );
            eprintln!("skipping the Python peer comparison (install requirements-dev.txt): {why}");
            None
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn truth_file_reads_the_same_in_python_mcap() {
    let dir = tempfile::tempdir().unwrap();
    let truth_out = dir.path().join("truth.mcap");
    let mut opts =
        SimOptions::from_files(&repo_root().join("config/scenarios/impacts.toml"), None).unwrap();
    opts.truth_out = Some(truth_out.clone());
    opts.pacing = Pacing::Fast;
    opts.linger = Duration::from_secs(2);
    let sim = imu_sim::spawn(opts).unwrap();
    let mut port = tokio_serial::new(sim.device_path().to_string_lossy(), 38_400)
        .open_native_async()
        .unwrap();
    port.write_all(&Command::SetContinuous { command: 0x0C }.to_bytes())
        .await
        .unwrap();
    let mut dec = ReplyDecoder::new();
    let mut data_ticks = Vec::new();
    let mut buf = vec![0u8; 1 << 16];
    while let Ok(Ok(n)) = tokio::time::timeout(Duration::from_secs(2), port.read(&mut buf)).await {
        if n == 0 {
            break;
        }
        dec.push(&buf[..n]);
        while let Some(ev) = dec.next_event() {
            if let DecodeEvent::Frame { reply, .. } = ev
                && reply.code() == 0x0C
            {
                data_ticks.push(reply.ticks().unwrap());
            }
        }
    }
    let report = tokio::task::spawn_blocking(move || sim.join())
        .await
        .unwrap()
        .unwrap();
    assert!(report.completed);
    // 80 s of scenario at 100 Hz.
    assert_eq!(data_ticks.len() as u64, report.data_replies);
    assert!(
        (data_ticks.len() as i64 - 8000).abs() <= 1,
        "{}",
        data_ticks.len()
    );

    let ours = read_truth(&truth_out).unwrap();
    assert_eq!(ours.samples.len(), data_ticks.len());
    let ours_ticks: Vec<u16> = ours.samples.iter().map(|s| s.ticks).collect();
    assert_eq!(
        ours_ticks, data_ticks,
        "truth is keyed by the ticks actually sent"
    );

    if let Some(py) = python_summary(&truth_out) {
        assert_eq!(py["samples"].as_u64().unwrap() as usize, ours.samples.len());
        assert_eq!(
            py["segments"].as_u64().unwrap() as usize,
            ours.segments.len()
        );
        assert_eq!(py["seqs_in_order"], serde_json::Value::Bool(true));
        let py_ticks: Vec<u16> = py["ticks"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as u16)
            .collect();
        assert_eq!(py_ticks, data_ticks);
        let names: Vec<&str> = py["metadata"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        for m in ["imu-sim.run", "imu-sim.scenario", "imu-sim.truth-model"] {
            assert!(names.contains(&m), "{names:?}");
        }
        assert_eq!(
            py["statistics_message_count"].as_u64().unwrap() as usize,
            ours.samples.len() + ours.segments.len()
        );
    }
}
