//! Faults end to end: hot reload, garbage on the line, an unplug and kill -9 on every protocol;
//! bad configuration and calibration files as clear errors.

use super::*;

#[test]
fn hot_reload_garbage_unplug_and_kill_9() {
    hot_reload_garbage_unplug_and_kill(DeviceProtocol::Gx1);
}

#[test]
fn mip_hot_reload_garbage_unplug_and_kill_9() {
    hot_reload_garbage_unplug_and_kill(DeviceProtocol::Mip);
}

#[test]
fn xsens_hot_reload_garbage_unplug_and_kill_9() {
    hot_reload_garbage_unplug_and_kill(DeviceProtocol::Xsens);
}

#[test]
fn vectornav_hot_reload_garbage_unplug_and_kill_9() {
    hot_reload_garbage_unplug_and_kill(DeviceProtocol::Vectornav);
}

fn hot_reload_garbage_unplug_and_kill(protocol: DeviceProtocol) {
    let dir = tempfile::tempdir().unwrap();
    let cal_path = dir.path().join("calibration.toml");
    std::fs::write(&cal_path, TRUTH).unwrap();
    let name = unique(&format!("faults-{protocol}"));
    let imud = Imud::start(dir.path(), &name, &dir.path().join("imu0"), &cal_path);
    let mut sub = Subscription::<CorrectedSample>::open(&name, Duration::from_secs(10))
        .unwrap_or_else(|e| panic!("{e}: {}", imud.stderr()));
    let sim = imu_sim::spawn(sim_options(dir.path(), true, protocol)).unwrap();
    let mut got = Vec::new();
    // Wait until the scenario reached its final, endless still segment (6.5 s in).
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(30),
        |g| g.len() >= 800,
    );
    assert!(got.len() >= 800, "{}", imud.stderr());

    // Hot reload: a calibration whose accel bias is 0.5 m/s^2 smaller on x moves corrected x by
    // +0.5 m/s^2 (bias is subtracted after the gain stages, scaled by 1/(1+s) and the inverse
    // misalignment), starting at one sample.
    let reloaded = TRUTH.replace("value = [0.15, -0.2, 0.1]", "value = [-0.35, -0.2, 0.1]");
    std::fs::write(&cal_path, &reloaded).unwrap();
    imud.signal("-HUP");
    let new_id = u64::from_str_radix(
        &Calibration::from_toml_str(&reloaded, "b")
            .unwrap()
            .content_id(),
        16,
    )
    .unwrap();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(20),
        |g| g.iter().filter(|s| s.calibration_id == new_id).count() >= 100,
    );
    let switch = got
        .iter()
        .position(|s| s.calibration_id == new_id)
        .expect("reload took effect");
    assert!(
        got[switch..].iter().all(|s| s.calibration_id == new_id),
        "one switch, never back"
    );
    let mean_x =
        |s: &[CorrectedSample]| s.iter().map(|v| v.accel_m_s2[0]).sum::<f64>() / s.len() as f64;
    // Both windows lie in the final still segment, so only the calibration differs.
    let before = &got[..switch];
    let after = &got[switch..];
    let last_before = &before[before.len().saturating_sub(50)..];
    let first_after = &after[..50.min(after.len())];
    let shift = mean_x(first_after) - mean_x(last_before);
    assert!(
        (shift - 0.5 / 1.002).abs() < 0.05,
        "reload shifted x by {shift}"
    );

    // Garbage on the line is skipped and counted; no frame is lost around it.
    let garbage: Vec<u8> = (0..64u8).map(|i| i.wrapping_mul(37) | 0x80).collect();
    sim.inject(&garbage);
    let n_before = got.len();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(20),
        |g| g.len() >= n_before + 100,
    );
    assert!(
        got.windows(2).all(|w| w[1].seq == w[0].seq + 1),
        "no sample lost around the garbage"
    );

    // Unplug for a second: the daemon reconnects by itself and samples resume.
    sim.unplug(Duration::from_secs(1));
    let n_before = got.len();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(30),
        |g| g.len() >= n_before + 300,
    );
    assert!(
        got.len() >= n_before + 300,
        "streaming did not resume after replug: {}",
        imud.stderr()
    );

    // kill -9 after 150 more samples (1.5 s at 100 Hz): the file is readable up to at most
    // about a second before the kill.
    let n_before = got.len();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(30),
        |g| g.len() >= n_before + 150,
    );
    assert!(got.len() >= n_before + 150, "{}", imud.stderr());
    let killed_at_ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64;
    imud.signal("-KILL");
    let log = imud.stderr();
    drop(imud);
    drop(sim);
    let files = recordings(dir.path());
    let rec = read_recording(files.last().unwrap()).unwrap();
    assert!(
        rec.stopped_early.is_some(),
        "a killed daemon leaves no summary"
    );
    let last = rec
        .raw
        .last()
        .expect("samples before the kill are readable");
    let lag_s = (killed_at_ns - last.t_host_wall_ns) as f64 * 1e-9;
    assert!(lag_s < 1.5, "file ends {lag_s:.2} s before the kill");

    // The log shows the garbage counted, the reconnect, and the new calibration.
    let (_, last_status) = rec.statuses.last().expect("status records");
    assert!(
        last_status.garbage_bytes + last_status.checksum_failures > 0,
        "{last_status:?}"
    );
    assert_eq!(last_status.reconnects, 1, "{last_status:?}: {log}");
    // Every injected byte is in the log, flagged as rejected, in order (nothing lost, nothing
    // passed off as a frame).
    let rejected: Vec<u8> = rec
        .frames
        .iter()
        .filter(|f| !f.accepted)
        .flat_map(|f| f.bytes.iter().copied())
        .collect();
    assert!(
        rejected
            .windows(garbage.len())
            .any(|w| w == garbage.as_slice()),
        "the injected bytes must appear, flagged, in /imu/raw_frame"
    );
    assert!(
        rec.calibrations
            .iter()
            .any(|c| c.id == format!("{new_id:016x}"))
    );
    // Across the unplug the sequence numbering continues without reuse.
    assert!(rec.raw.windows(2).all(|w| w[1].seq == w[0].seq + 1));
}

#[test]
fn bad_config_and_calibration_files_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("imud.toml");
    std::fs::write(
        &cfg,
        "name = \"x\"\n[device]\nbaud = 38400\nparity = \"none\"\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_imud"))
        .arg("--config")
        .arg(&cfg)
        .arg("--print-config")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("imud.toml:4:") && err.contains("parity"),
        "{err}"
    );

    let cal = dir.path().join("cal.toml");
    std::fs::write(
        &cal,
        "format = \"imud-calibration/1\"\n[accel.bias]\nvalue = [1.0, 2.0]\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_imud"))
        .args(["--device", "/nonexistent", "--name"])
        .arg(unique("badcal"))
        .arg("--calibration")
        .arg(&cal)
        .arg("--log-dir")
        .arg(dir.path().join("logs"))
        .output()
        .unwrap();
    assert!(
        !out.status.success(),
        "an invalid calibration at start-up is fatal"
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cal.toml:3") && err.contains("accel.bias"),
        "{err}"
    );

    // --print-config shows the effective configuration with flags applied.
    let out = Command::new(env!("CARGO_BIN_EXE_imud"))
        .args(["--print-config", "--baud", "115200", "--name", "printed"])
        .args(["--readers-socket", "/run/printed/r.sock"])
        .env_remove("IMUD_CONFIG")
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("baud = 115200")
            && text.contains("name = \"printed\"")
            && text.contains("readers-socket = \"/run/printed/r.sock\""),
        "{text}"
    );
}
