//! Tests of scenario parsing, validation and compilation.

use super::*;

const MINIMAL: &str = r#"
name = "t"
[[segment]]
kind = "static"
duration-s = 1.0
"#;

#[test]
fn minimal_scenario_has_documented_defaults() {
    let s = Scenario::from_toml_str(MINIMAL, "t.toml").unwrap();
    assert_eq!(s.rate_hz, 100.0);
    assert_eq!(s.device.gain_scale.accel, 7000);
    assert_eq!(s.device.tick_period_s, 6.5536e-3);
}

#[test]
fn unknown_key_names_file_line_and_key() {
    let text = "name = \"t\"\nrate-hz = 100\nlatitude = 40\n[[segment]]\nkind = \"static\"\nduration-s = 1\n";
    let e = Scenario::from_toml_str(text, "bad.toml")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("bad.toml:3:"), "{e}");
    assert!(e.contains("latitude"), "{e}");
}

#[test]
fn bad_axis_is_explained() {
    let text = "name = \"t\"\n[[segment]]\nkind = \"rotate\"\naxis = \"w\"\nangle-deg = 90\nduration-s = 1\n";
    let e = Scenario::from_toml_str(text, "a.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("a.toml:2:") || e.contains("a.toml:4:"), "{e}");
    assert!(e.contains("not one of x, y, z"), "{e}");
}

#[test]
fn endless_segment_only_last() {
    let text = "name = \"t\"\n[[segment]]\nkind = \"static\"\n[[segment]]\nkind = \"static\"\nduration-s = 1\n";
    let e = Scenario::from_toml_str(text, "e.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("segment 1 (static)") && e.contains("only the last"),
        "{e}"
    );
}

#[test]
fn axis_directions_build_right_handed_frames() {
    // Table 1 position 1: spin (z) up, input1 (x) north, input2 (y) west.
    let o = OrientationSpec {
        x: Some(Direction::North),
        z: Some(Direction::Up),
        ..Default::default()
    };
    let q = o.enu_from_sensor().unwrap();
    assert!((q * Vector3::y() - Direction::West.enu()).norm() < 1e-12);
    let bad = OrientationSpec {
        x: Some(Direction::North),
        y: Some(Direction::South),
        ..Default::default()
    };
    assert!(bad.enu_from_sensor().is_err());
    let left = OrientationSpec {
        x: Some(Direction::North),
        y: Some(Direction::East),
        z: Some(Direction::Up),
        ..Default::default()
    };
    assert!(
        left.enu_from_sensor().is_err(),
        "left-handed frame must be refused"
    );
}

#[test]
fn level_euler_zero_is_x_north_z_down() {
    let q = OrientationSpec::default().enu_from_sensor().unwrap();
    assert!((q * Vector3::x() - Direction::North.enu()).norm() < 1e-12);
    assert!((q * Vector3::z() - Direction::Down.enu()).norm() < 1e-12);
}

#[test]
fn temperature_profiles() {
    let w = TemperatureProfile::Warmup {
        ambient_c: 22.0,
        operating_c: 38.0,
        tau_s: 1800.0,
    };
    assert_eq!(w.temp_c(0.0), 22.0);
    assert!((w.temp_c(1800.0) - (38.0 - 16.0 / std::f64::consts::E)).abs() < 1e-9);
    let p = TemperatureProfile::Points {
        points: vec![[0.0, 20.0], [10.0, 30.0]],
    };
    assert_eq!(p.temp_c(-1.0), 20.0);
    assert_eq!(p.temp_c(5.0), 25.0);
    assert_eq!(p.temp_c(11.0), 30.0);
}

#[test]
fn mip_rates_divide_the_base_rate_and_bad_protocols_name_the_line() {
    let with = |rate: &str, protocol: &str| {
        format!(
            "name = \"t\"\nrate-hz = {rate}\n[device]\nprotocol = \"{protocol}\"\n\
             [[segment]]\nkind = \"static\"\nduration-s = 1.0\n"
        )
    };
    let s = Scenario::from_toml_str(&with("250.0", "mip"), "m.toml").unwrap();
    assert_eq!(s.device.protocol, DeviceProtocol::Mip);
    let e = Scenario::from_toml_str(&with("300.0", "mip"), "m.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("m.toml: rate-hz:") && e.contains("1000 Hz"),
        "{e}"
    );
    // The command line's --protocol checks the scenario again.
    let mut gx1 = Scenario::from_toml_str(&with("300.0", "3dm-gx1"), "g.toml").unwrap();
    assert!(gx1.set_protocol(DeviceProtocol::Mip, "g.toml").is_err());
    let e = Scenario::from_toml_str(&with("100.0", "gx5"), "p.toml")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("p.toml:4:") && e.contains("\"gx5\""), "{e}");
}

/// Four faces held by hand, then a turn: each face's gravity direction off its nominal by at
/// most the tilt noise (and by some of it), the same tilts for the same seed, the tremor's
/// rate visible while the unit is "still", and bad `[hand]` values named.
#[test]
fn hand_tilts_poses_and_trembles() {
    let text = |hand: &str| {
        format!(
            "name = \"t\"\n{hand}\n[[segment]]\nkind = \"static\"\norientation = {{ x = \"north\", z = \"up\" }}\nduration-s = 2\n\
             [[segment]]\nkind = \"static\"\norientation = {{ x = \"up\", y = \"north\" }}\nduration-s = 2\n\
             [[segment]]\nkind = \"static\"\norientation = {{ y = \"up\", z = \"north\" }}\nduration-s = 2\n\
             [[segment]]\nkind = \"static\"\norientation = {{ x = \"north\", z = \"down\" }}\nduration-s = 2\n"
        )
    };
    let plain = Scenario::from_toml_str(&text(""), "t.toml").unwrap();
    let hand = Scenario::from_toml_str(
        &text("[hand]\ntilt-noise-deg = 3.0\ntremor-deg = 0.2\n"),
        "t.toml",
    )
    .unwrap();
    assert_eq!(hand.hand.tremor_band_hz, [4.0, 12.0]);
    let (p, h) = (plain.compile(7), hand.compile(7));
    assert_eq!(h.segments().len(), p.segments().len());
    let mut largest_deg: f64 = 0.0;
    for (a, b) in p.segments().iter().zip(h.segments()) {
        if a.kind != "static" {
            continue;
        }
        let off_deg = a
            .gravity_dir_sensor
            .angle(&b.gravity_dir_sensor)
            .to_degrees();
        assert!(off_deg <= 3.0 + 1e-9, "{}: {off_deg} deg", b.label);
        largest_deg = largest_deg.max(off_deg);
    }
    assert!(largest_deg > 0.3, "no tilt: {largest_deg}");
    // With tremor the rests are held, not static.
    assert!(h.segments().iter().all(|s| s.kind != "static"));
    assert!(h.segments().iter().any(|s| s.kind == "held"));
    let again = hand.compile(7);
    assert_eq!(again.state(3.0), h.state(3.0));
    // In the middle of the first face: plain is still, the hand trembles (deg/s of rate) and
    // its specific force keeps gravity's magnitude.
    let (sp, sh) = (p.state(1.0), h.state(1.0));
    assert!(sp.angular_rate_rad_s.norm() < 1e-4);
    let tremor_deg_s = (sh.angular_rate_rad_s - sp.angular_rate_rad_s)
        .norm()
        .to_degrees();
    assert!(tremor_deg_s > 0.1 && tremor_deg_s < 100.0, "{tremor_deg_s}");
    assert!((sh.specific_force_m_s2.norm() - sp.specific_force_m_s2.norm()).abs() < 1e-9);
    for (bad, key) in [
        ("[hand]\ntremor-deg = -1", "hand.tremor-deg"),
        (
            "[hand]\ntremor-deg = 0.2\ntremor-band-hz = [4, 80]",
            "hand.tremor-band-hz",
        ),
        ("[hand]\ntilt-noise-deg = 45", "hand.tilt-noise-deg"),
    ] {
        let e = Scenario::from_toml_str(&text(bad), "h.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("h.toml: ") && e.contains(key), "{e}");
    }
}

#[test]
fn gnss_time_and_its_outages_parse_and_a_backwards_outage_is_named() {
    let head = "name = \"t\"\nrate-hz = 100\n[device]\nprotocol = \"mip\"\ngnss-time = true\n";
    let tail = "[[segment]]\nkind = \"static\"\nduration-s = 1\n";
    let text = format!("{head}[[device.gnss-outage]]\nstart-s = 2.0\nend-s = 5.0\n{tail}");
    let s = Scenario::from_toml_str(&text, "g.toml").unwrap();
    assert!(s.device.gnss_valid_at(1.9) && s.device.gnss_valid_at(5.0));
    assert!(!s.device.gnss_valid_at(2.0) && !s.device.gnss_valid_at(4.9));
    assert_eq!(s.device.gnss_epoch_utc_s, 1_767_225_600.0);
    let text = format!("{head}[[device.gnss-outage]]\nstart-s = 5.0\nend-s = 2.0\n{tail}");
    let e = Scenario::from_toml_str(&text, "g.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("g.toml:") && e.contains("device.gnss-outage"),
        "{e}"
    );
    assert!(e.contains("start-s 5 must come before end-s 2"), "{e}");
}

/// A still `duration_s` with `extra` tables after the segment.
fn with_dropouts(duration_s: f64, extra: &str) -> String {
    format!("name = \"t\"\n[[segment]]\nkind = \"static\"\nduration-s = {duration_s}\n{extra}")
}

#[test]
fn written_dropouts_lose_their_windows_only() {
    let text = with_dropouts(
        60.0,
        "[[dropout]]\nat-s = 30.0\nduration-s = 0.5\n[[dropout]]\nat-s = 10.0\nduration-s = 2.0\n",
    );
    let s = Scenario::from_toml_str(&text, "d.toml").unwrap();
    let t = s.compile(1);
    let windows: Vec<(f64, f64)> = t.dropouts().iter().map(|d| (d.start_s, d.end_s)).collect();
    assert_eq!(windows, [(10.0, 12.0), (30.0, 30.5)]);
    let lost: Vec<bool> = [9.99, 10.0, 11.99, 12.0, 30.2, 30.5, 59.0]
        .iter()
        .map(|&t_s| t.link_lost_at(t_s))
        .collect();
    assert_eq!(lost, [false, true, true, false, true, false, false]);
    // No dropouts: the same timeline as before they existed.
    assert!(
        Scenario::from_toml_str(MINIMAL, "t.toml")
            .unwrap()
            .compile(1)
            .dropouts()
            .is_empty()
    );
}

#[test]
fn bad_dropouts_name_file_line_and_problem() {
    let err = |extra: &str, duration_s: f64| {
        Scenario::from_toml_str(&with_dropouts(duration_s, extra), "d.toml")
            .unwrap_err()
            .to_string()
    };
    // The second table starts on line 8 (the segment takes lines 2 to 4).
    let e = err(
        "[[dropout]]\nat-s = 10.0\nduration-s = 5.0\n[[dropout]]\nat-s = 12.0\nduration-s = 1.0\n",
        60.0,
    );
    assert!(
        e.starts_with("d.toml:8: dropout 2:") && e.contains("overlaps dropout 1"),
        "{e}"
    );
    let e = err("[[dropout]]\nat-s = 58.0\nduration-s = 5.0\n", 60.0);
    assert!(
        e.starts_with("d.toml:5: dropout 1:") && e.contains("not inside"),
        "{e}"
    );
    let e = err("[[dropout]]\nat-s = 5.0\nduration-s = 0.0\n", 60.0);
    assert!(
        e.contains("d.toml:5:") && e.contains("must be positive"),
        "{e}"
    );
    let e = err("[[dropout]]\nat-s = -1.0\nduration-s = 1.0\n", 60.0);
    assert!(e.contains("d.toml:5:") && e.contains(">= 0"), "{e}");
    let e = err(
        "[random-dropouts]\nper-hour = 2.0\nmean-duration-s = -1.0\n",
        60.0,
    );
    assert!(e.starts_with("d.toml:5: random-dropouts:"), "{e}");
    let endless = "name = \"t\"\n[[segment]]\nkind = \"static\"\n\
                   [random-dropouts]\nper-hour = 2.0\nmean-duration-s = 1.0\n";
    let e = Scenario::from_toml_str(endless, "d.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("d.toml:4:") && e.contains("scenario that ends"),
        "{e}"
    );
    let e = err("[[dropout]]\nat-s = 5.0\nlength-s = 1.0\n", 60.0);
    assert!(e.contains("d.toml:") && e.contains("length-s"), "{e}");
}

/// Random dropouts are a Poisson process of starts with exponential lengths, reproducible
/// from the seed: over 200 h at 6 an hour, 1200 expected (sd 35) of mean length 2 s (the
/// mean of 1200 exponentials is within 0.12 s at 2 sd).
#[test]
fn random_dropouts_follow_their_rate_and_mean_length_from_the_seed() {
    let text = with_dropouts(
        200.0 * 3600.0,
        "[random-dropouts]\nper-hour = 6.0\nmean-duration-s = 2.0\n",
    );
    let s = Scenario::from_toml_str(&text, "r.toml").unwrap();
    let a = s.compile(7);
    assert_eq!(a.dropouts(), s.compile(7).dropouts());
    assert_ne!(a.dropouts(), s.compile(8).dropouts());
    let d = a.dropouts();
    let n = d.len() as f64;
    assert!((n - 1200.0).abs() < 4.0 * 1200f64.sqrt(), "{n} dropouts");
    let mean_s = d.iter().map(|w| w.end_s - w.start_s).sum::<f64>() / n;
    assert!(
        (mean_s - 2.0).abs() < 4.0 * 2.0 / n.sqrt(),
        "mean length {mean_s} s"
    );
    assert!(d.windows(2).all(|w| w[0].end_s < w[1].start_s));
    assert!(
        d.iter()
            .all(|w| w.start_s > 0.0 && w.end_s <= 200.0 * 3600.0)
    );
}
