//! The imud binary against MIP units it has never seen: `tests/python/faulty_mip.py`, a MIP
//! device on a real pseudo-terminal written independently of imu-sim and of imud's codec, in
//! the shapes today's units come in (a 3DM-GX5 with the reference time, a 3DM-GX3 with only
//! the internal timestamp and no magnetometer, a 7-series unit that takes only the generic
//! commands) and with faults (a late and corrupted start-up reply, dropped frames, a stalled
//! link, a unit that streams before it is configured). Every sample is checked against the
//! pattern the device sent, every lost frame is counted exactly.

mod python_device;

use imu_bus::recording::Recording;
use python_device::Session;

/// The device with `device_args`, imud (`imud_args`, config `config`) on it until `stream_s`
/// after the unit is configured.
fn session(
    name: &str,
    device_args: &[&str],
    imud_args: &[&str],
    config: &str,
    stream_s: f64,
) -> Session {
    python_device::run(&python_device::Setup {
        script: "faulty_mip.py",
        name: &format!("mip-{name}"),
        device_args,
        imud_args,
        config,
        ready: ", clock ",
        stream_s,
    })
}

/// The test device's frame `k` (faulty_mip.py `values`), as the f32 it sent.
fn values(k: u64) -> ([f32; 3], [f32; 3], [f32; 3]) {
    let accel = [
        0.001 * (k % 7) as f64,
        -0.002 * (k % 5) as f64,
        -1.0 + 1e-4 * (k % 3) as f64,
    ];
    let gyro = [1e-3 * ((k % 11) as f64 - 5.0), 2e-3, -5e-4 * (k % 4) as f64];
    let mag = [0.21, -0.05 + 0.001 * (k % 2) as f64, 0.43];
    (
        accel.map(|v| v as f32),
        gyro.map(|v| v as f32),
        mag.map(|v| v as f32),
    )
}

/// Every sample is the frame the device time says, with the values the device sent; samples
/// are exactly the frames sent in the configured session; losses are counted exactly; stamps
/// strictly increase. `period_s` is the data period, `tick_s` the device clock's tick.
fn check_every_sample(s: &Session, period_s: f64, tick_s: f64, mag: bool) {
    let (rec, report) = (&s.rec, &s.report);
    let sent = report["frames_sent"].as_u64().unwrap();
    let first = report["first"].as_u64().unwrap();
    let dropped = report["dropped_between"].as_u64().unwrap();
    // The device may have sent a last frame imud never read before it stopped.
    assert!(
        sent - rec.raw.len() as u64 <= 1,
        "{sent} sent, {} recorded: {}",
        rec.raw.len(),
        s.log
    );
    let (_, status) = rec.statuses.last().expect("a status");
    assert_eq!(status.samples_lost, dropped, "{}", s.log);
    assert_eq!(status.protocol, imu_bus::sample::device_protocol::MIP);
    // Every data packet of the configured session was a sample, with no field skipped.
    assert_eq!((status.packets_unusable, status.fields_skipped), (0, 0));
    let g0 = imu_model::units::STANDARD_GRAVITY_M_S2;
    let t0 = rec.raw[0].ticks_unwrapped as f64 * tick_s;
    for (i, r) in rec.raw.iter().enumerate() {
        let k = first + ((r.ticks_unwrapped as f64 * tick_s - t0) / period_s).round() as u64;
        let (a, w, m) = values(k);
        for j in 0..3 {
            assert_eq!(
                r.accel_device_m_s2[j],
                f64::from(a[j]) * g0,
                "sample {i} (frame {k})"
            );
            assert_eq!(
                r.gyro_device_rad_s[j],
                f64::from(w[j]),
                "sample {i} (frame {k})"
            );
            if mag {
                assert_eq!(r.mag_device_gauss[j], f64::from(m[j]), "sample {i}");
            } else {
                assert!(
                    r.mag_device_gauss[j].is_nan(),
                    "no magnetometer: NaN, never 0"
                );
            }
        }
        assert_eq!(r.flags & imu_bus::sample::raw_flags::NO_COUNTS, 16);
    }
    assert!(
        rec.raw
            .windows(2)
            .all(|w| w[1].t_sample_ns > w[0].t_sample_ns && w[1].seq == w[0].seq + 1),
        "stamps repeat or go back, or a seq is skipped"
    );
    // Uncalibrated: the corrected stream is the device's reading.
    assert_eq!(rec.imu.len(), rec.raw.len());
}

fn device_meta<'a>(rec: &'a Recording, key: &str) -> &'a str {
    rec.metadata["imud.device"]
        .get(key)
        .unwrap_or_else(|| panic!("no {key} in {:?}", rec.metadata["imud.device"]))
}

/// A 3DM-GX5-style unit that streams at power-on, probed (no protocol configured), at 200 Hz
/// on an oscillator 80 ppm fast, with a single lost frame and a burst.
#[test]
fn a_streaming_gx5_is_probed_configured_and_every_frame_is_checked() {
    let s = session(
        "gx5",
        &[
            "--streaming",
            "--rate-hz",
            "200",
            "--drift-ppm",
            "80",
            "--drop",
            "150,400,401,402",
        ],
        &[],
        "",
        4.0,
    );
    assert!(
        s.log.contains("protocol mip (probed: it streams)"),
        "{}",
        s.log
    );
    assert_eq!(device_meta(&s.rec, "protocol"), "mip");
    assert_eq!(device_meta(&s.rec, "model"), "3DM-GX5-25");
    assert_eq!(device_meta(&s.rec, "serial-number"), "6251.99");
    assert_eq!(device_meta(&s.rec, "firmware"), "1.1.41");
    assert_eq!(device_meta(&s.rec, "rate-hz"), "200");
    assert!(device_meta(&s.rec, "clock").starts_with("reference time"));
    assert_eq!(s.report["dropped_between"], 4);
    check_every_sample(&s, 5e-3 * (1.0 + 80e-6), 1e-9, true);
    // The temperature field, recorded about once a second with the value sent.
    assert!(
        s.rec.temperatures.len() >= 3,
        "{}",
        s.rec.temperatures.len()
    );
    for (_, t) in &s.rec.temperatures {
        assert!((24.5..=24.6).contains(t), "{t}");
    }
    // The probe's bytes and the pre-configuration stream are logged, not samples.
    assert!(s.rec.frames.len() > s.rec.raw.len());
}

/// A 3DM-GX3-style unit: no reference time, no temperature, no magnetometer. imud falls back
/// to the 62.5 kHz internal timestamp and says so.
#[test]
fn a_gx3_style_unit_runs_on_its_internal_timestamp() {
    let s = session(
        "gx3",
        &[
            "--no-reference-time",
            "--no-temperature",
            "--no-mag",
            "--drop",
            "120",
        ],
        &["--protocol", "mip"],
        "",
        3.0,
    );
    assert!(device_meta(&s.rec, "clock").starts_with("internal timestamp"));
    assert_eq!(device_meta(&s.rec, "magnetometer"), "false");
    assert_eq!(device_meta(&s.rec, "temperature"), "false");
    assert!(
        s.log.contains("refuses"),
        "the refused formats are said: {}",
        s.log
    );
    check_every_sample(&s, 1e-2, 1.0 / 62_500.0, false);
    assert!(s.rec.temperatures.is_empty());
}

/// A 7-series-style unit (only the generic 3DM commands), idle at power-on and probed,
/// configured to 50 Hz from its 100.
#[test]
fn a_7_series_unit_is_probed_and_configured_with_the_generic_commands() {
    let s = session(
        "cv7",
        &["--generic-only"],
        &[],
        "[device]\nrate-hz = 50.0\n",
        3.0,
    );
    assert!(
        s.log.contains("protocol mip (probed: it acknowledges"),
        "{}",
        s.log
    );
    assert_eq!(device_meta(&s.rec, "rate-hz"), "50");
    assert_eq!(device_meta(&s.rec, "message-format-command"), "0x0C 0x0F");
    let format = s.report["format"].as_array().unwrap();
    assert!(
        format.iter().all(|f| f[1] == 20),
        "decimation 20: {format:?}"
    );
    check_every_sample(&s, 2e-2, 1e-9, true);
}

/// A start-up reply 1.5 s late (past the 1 s reply time-out) and corrupted replies only delay
/// the session; a one-second stall while streaming loses nothing and bends no stamp.
#[test]
fn a_late_and_corrupted_start_up_reply_and_a_stall_lose_nothing() {
    let s = session(
        "faults",
        &[
            "--delay-reply",
            "3:1.5",
            "--corrupt-replies",
            "0.004",
            "--stall",
            "1:1",
            "--seed",
            "7",
        ],
        &["--protocol", "mip"],
        "",
        4.0,
    );
    let (_, status) = s.rec.statuses.last().expect("a status");
    assert!(
        status.checksum_failures + status.garbage_bytes > 0 || s.log.contains("no reply"),
        "the faults were seen: {}",
        s.log
    );
    check_every_sample(&s, 1e-2, 1e-9, true);
}
