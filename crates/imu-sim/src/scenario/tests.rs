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
