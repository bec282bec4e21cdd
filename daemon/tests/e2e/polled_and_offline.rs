//! Polled mode (temperature logged, calibration reloaded on a file change) and the offline
//! simulated unit (`--sim --offline`) equal to the truth sample for sample.

use super::*;

#[test]
fn polled_mode_logs_temperature_and_reloads_on_file_change() {
    let dir = tempfile::tempdir().unwrap();
    let cal_path = dir.path().join("calibration.toml");
    std::fs::write(&cal_path, TRUTH).unwrap();
    let cfg = dir.path().join("imud.toml");
    std::fs::write(
        &cfg,
        "[device]\nmode = \"polled\"\npoll-rate-hz = 50.0\ntemperature-rate-hz = 2.0\n[calibration]\nwatch = true\n",
    )
    .unwrap();
    let name = unique("polled");
    let mut opts = sim_options(dir.path(), true, DeviceProtocol::Gx1);
    opts.scenario.temperature = imu_sim::scenario::TemperatureProfile::Warmup {
        ambient_c: 22.0,
        operating_c: 38.0,
        tau_s: 20.0,
    };
    let sim = imu_sim::spawn(opts).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_imud"))
        .args(["--name", &name, "--baud", "115200", "--config"])
        .arg(&cfg)
        .arg("--device")
        .arg(dir.path().join("imu0"))
        .arg("--calibration")
        .arg(&cal_path)
        .arg("--log-dir")
        .arg(dir.path().join("logs"))
        .env("IMUD_LOG", "info")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.path().join("imud.stderr")).unwrap())
        .spawn()
        .unwrap();
    let imud = Imud {
        child,
        log_path: dir.path().join("imud.stderr"),
    };
    let mut sub = Subscription::<CorrectedSample>::open(&name, Duration::from_secs(10)).unwrap();
    let mut got = Vec::new();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(30),
        |g| g.len() >= 150,
    );

    // An invalid file is rejected and the previous calibration stays in force.
    let old_id = got.last().unwrap().calibration_id;
    std::fs::write(
        &cal_path,
        "format = \"imud-calibration/1\"\n[gyro.scale]\nvalue = [0.1, 0.2]\n",
    )
    .unwrap();
    imud.signal("-HUP");
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(5),
        |g| g.len() >= 250,
    );
    assert!(
        got.iter().all(|s| s.calibration_id == old_id),
        "an invalid file must not replace the calibration"
    );
    let log = imud.stderr();
    assert!(
        log.contains("calibration.toml:3") && log.contains("gyro.scale"),
        "{log}"
    );

    // A valid edit is picked up by the file watch alone (no signal). Its modification time is
    // set 2 s on, so it differs from the invalid file's whatever the file system's resolution.
    let edited = TRUTH.replace(
        "value = [0.01, -0.005, 0.008]",
        "value = [0.02, -0.005, 0.008]",
    );
    let invalid_mtime = std::fs::metadata(&cal_path).unwrap().modified().unwrap();
    std::fs::write(&cal_path, &edited).unwrap();
    std::fs::File::options()
        .write(true)
        .open(&cal_path)
        .unwrap()
        .set_modified(invalid_mtime + Duration::from_secs(2))
        .unwrap();
    let new_id = u64::from_str_radix(
        &Calibration::from_toml_str(&edited, "e")
            .unwrap()
            .content_id(),
        16,
    )
    .unwrap();
    drain(
        &mut sub,
        &mut got,
        Instant::now() + Duration::from_secs(10),
        |g| g.last().is_some_and(|s| s.calibration_id == new_id),
    );
    assert_eq!(
        got.last().unwrap().calibration_id,
        new_id,
        "{}",
        imud.stderr()
    );
    let log = imud.terminate();
    drop(sim);

    // Every poll answered is logged: samples and temperatures (at 2 Hz) match the truth.
    let truth = read_truth(&dir.path().join("truth.mcap")).unwrap();
    let rec = read_recording(&recordings(dir.path())[0]).unwrap();
    let truth_samples = truth
        .samples
        .iter()
        .filter(|s| is_data_command(s.command))
        .count();
    let truth_temps: Vec<f64> = truth
        .samples
        .iter()
        .filter(|s| s.command == 0x07)
        .map(|s| s.temp_c)
        .collect();
    // The simulator may have answered a last poll the daemon never read before it stopped.
    assert!(
        truth_samples - rec.raw.len() <= 1,
        "{truth_samples} vs {}: {log}",
        rec.raw.len()
    );
    assert!(truth_temps.len() - rec.temperatures.len() <= 1);
    let span_s = (rec.raw.last().unwrap().t_host_wall_ns - rec.raw[0].t_host_wall_ns) as f64 * 1e-9;
    assert!(
        rec.temperatures.len() as f64 >= 2.0 * span_s - 2.0,
        "{} temperatures in {span_s:.1} s",
        rec.temperatures.len()
    );
    for ((_, logged), truth_c) in rec.temperatures.iter().zip(&truth_temps) {
        assert!((logged - truth_c).abs() < 0.01, "{logged} vs {truth_c}");
    }
    // The warm-up is visible in the log: temperature rises.
    assert!(rec.temperatures.last().unwrap().1 > rec.temperatures[0].1 + 1.0);
}

#[test]
fn offline_recording_equals_the_truth_sample_for_sample() {
    offline_recording_equals_the_truth(DeviceProtocol::Gx1);
}

#[test]
fn offline_mip_recording_equals_the_truth_sample_for_sample() {
    offline_recording_equals_the_truth(DeviceProtocol::Mip);
}

#[test]
fn offline_xsens_recording_equals_the_truth_sample_for_sample() {
    offline_recording_equals_the_truth(DeviceProtocol::Xsens);
}

#[test]
fn offline_vectornav_recording_equals_the_truth_sample_for_sample() {
    offline_recording_equals_the_truth(DeviceProtocol::Vectornav);
}

fn offline_recording_equals_the_truth(protocol: DeviceProtocol) {
    let dir = tempfile::tempdir().unwrap();
    let scenario_path = dir.path().join("scenario.toml");
    // The scenario names its truth model (a top-level key, so before any table).
    std::fs::write(
        &scenario_path,
        format!(
            "truth = \"truth-model.toml\"\n{}",
            scenario(false, protocol)
        ),
    )
    .unwrap();
    std::fs::write(dir.path().join("truth-model.toml"), TRUTH).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_imud"))
        .args(["--offline", "--seed", "9", "--name", "off", "--log-dir"])
        .arg(dir.path().join("logs"))
        .arg("--sim")
        .arg(&scenario_path)
        .env_remove("IMUD_CONFIG")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed = String::from_utf8_lossy(&out.stdout);
    let files: Vec<&str> = printed.lines().collect();
    assert_eq!(files.len(), 2, "recording and truth paths: {printed}");
    let rec = read_recording(Path::new(files[0])).unwrap();
    let truth = read_truth(Path::new(files[1])).unwrap();
    assert_eq!(truth.run.get("seed").map(String::as_str), Some("9"));
    let data: Vec<_> = truth
        .samples
        .iter()
        .filter(|s| is_data_command(s.command))
        .collect();
    assert_eq!(rec.raw.len(), data.len());
    assert_eq!(rec.raw.len(), 750, "7.5 s at 100 Hz");
    // Temperature at the default 1 Hz, as a thermal analysis needs (polled from a GX1, the
    // MIP packets' field recorded once a second).
    assert_eq!(rec.temperatures.len(), 8);
    for (i, (r, t)) in rec.raw.iter().zip(&data).enumerate() {
        assert_same_device_time(protocol, r, t, i);
        match protocol {
            DeviceProtocol::Gx1 => {
                // Raw counts decode to the truth's pre-quantization measurement within half
                // an LSB, and the device reading is that decoding.
                let a =
                    imu_proto::scale::raw_bits_to_units(r.accel_counts[2] as u16, 7000) * 9.80665;
                assert!(
                    (a - t.measured_accel_m_s2[2]).abs()
                        <= 0.5 * 7000.0 / 32_768_000.0 * 9.80665 + 1e-12
                );
                assert_eq!(r.accel_device_m_s2[2], a);
            }
            DeviceProtocol::Vectornav => {
                // No counts; the device reading is the uncompensated measurement in f32.
                assert_eq!(r.flags & imu_bus::sample::raw_flags::NO_COUNTS, 16);
                for k in 0..3 {
                    for (got, want) in [
                        (r.gyro_device_rad_s[k], t.measured_gyro_rad_s[k]),
                        (r.accel_device_m_s2[k], t.measured_accel_m_s2[k]),
                    ] {
                        assert!(
                            (got - want).abs() <= 1e-7 * want.abs() + 1e-30,
                            "{got} {want}"
                        );
                    }
                }
            }
            DeviceProtocol::Mip | DeviceProtocol::Xsens => {
                // No counts; the device reading is the measurement in f32.
                assert_eq!(r.flags & imu_bus::sample::raw_flags::NO_COUNTS, 16);
                for k in 0..3 {
                    let (got, want) = (r.gyro_device_rad_s[k], t.measured_gyro_rad_s[k]);
                    assert!(
                        (got - want).abs() <= 1e-7 * want.abs() + 1e-30,
                        "{got} {want}"
                    );
                    let (got, want) = (r.accel_device_m_s2[k], t.measured_accel_m_s2[k]);
                    assert!(
                        (got - want).abs() <= 1e-6 * want.abs() + 1e-12,
                        "{got} {want}"
                    );
                }
            }
        }
    }
}
