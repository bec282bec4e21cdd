//! Tests of reference logs: headers and units, table logs, clock alignment.

use super::*;

#[test]
fn header_names_columns_and_units() {
    let log = ReferenceLog::from_csv_str(
        "# a rate table\nt_ms,wz_deg_s,wx_deg_s,wy_deg_s\n1000,90,0,0\n1010,-90,0,0\n",
        "r.csv",
    )
    .unwrap();
    assert_eq!(log.t_s, [1.0, 1.01]);
    assert!((log.angular_rate_rad_s[0][2] - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    assert!(log.specific_force_m_s2.is_none());
    let e = ReferenceLog::from_csv_str("t_s,wx_deg_s,wy_deg_s,wz_dg_s\n", "r.csv")
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("r.csv:1:") && e.contains("did you mean `wz_deg_s`"),
        "{e}"
    );
    let e = ReferenceLog::from_csv_str("t_s,wx_deg_s,wy_deg_s\n0,0,0\n", "r.csv")
        .unwrap_err()
        .to_string();
    assert!(e.contains("all three angular rate"), "{e}");
    let e = ReferenceLog::from_csv_str(
        "t_s,wx_deg_s,wy_deg_s,wz_deg_s\n0,0,0,0\n0,0,0,0\n",
        "r.csv",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("r.csv:3:") && e.contains("does not increase"),
        "{e}"
    );
}

#[test]
fn a_table_log_has_one_rate_column_about_its_axis() {
    let log = ReferenceLog::from_csv_str(
        "# table-axis = -y\n# latitude-deg = 40\nt_s,rate_deg_s\n0,10\n1,20\n\
         # table_axis = [1, 0, 1]\n2,30\n",
        "t.csv",
    )
    .unwrap();
    let t = log.table.as_ref().unwrap();
    let d = DEG_TO_RAD;
    assert_eq!(log.angular_rate_rad_s[0], [0.0, -10.0 * d, 0.0]);
    let w2 = Vec3::from(log.angular_rate_rad_s[2]);
    assert!((w2 - Vec3::new(1.0, 0.0, 1.0).normalize() * (30.0 * d)).norm() < 1e-15);
    assert_eq!(t.axis_lines.len(), 2);
    assert_eq!((t.axis_lines[1].0, t.axis_lines[1].1), (6, 2));
    assert!((t.gravity_m_s2 - normal_gravity_m_s2(40.0, 0.0)).abs() < 1e-12);
    assert_eq!(t.latitude_deg, Some(40.0));
    // Without an axis the rate cannot be placed: say how to give it.
    let e = ReferenceLog::from_csv_str("t_s,rate_deg_s\n0,1\n1,2\n", "t.csv")
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("t.csv:2:") && e.contains("`# table-axis = +z`"),
        "{e}"
    );
    // A misspelt setting is named, not taken for a comment.
    let e = ReferenceLog::from_csv_str("# table-axs = +z\nt_s,rate_deg_s\n0,1\n1,2\n", "t.csv")
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("t.csv:1:") && e.contains("did you mean `table-axis`"),
        "{e}"
    );
    // Table settings in a three-axis log.
    let e = ReferenceLog::from_csv_str(
        "# gravity-m-s2 = 9.81\nt_s,wx_deg_s,wy_deg_s,wz_deg_s\n0,0,0,1\n1,0,0,2\n",
        "t.csv",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("t.csv:1:") && e.contains("apply to a rate table's one-column log"),
        "{e}"
    );
    let e = ReferenceLog::from_csv_str("t_s,rate_deg_s,wz_deg_s\n0,1,1\n1,2,2\n", "t.csv")
        .unwrap_err()
        .to_string();
    assert!(e.contains("or one table rate column"), "{e}");
}

#[test]
fn a_table_log_takes_its_axis_as_vertical_and_checks_the_turn() {
    let g = STANDARD_GRAVITY_M_S2;
    let seg = |kind, accel: [f64; 3], gyro: [f64; 3], t: f64| Segment {
        kind,
        start_s: t,
        end_s: t + 10.0,
        first_sample: (t * 100.0).round() as usize,
        n: 1000,
        mean_accel_m_s2: accel,
        mean_gyro_rad_s: gyro,
        std_accel_m_s2: [0.01; 3],
        std_gyro_rad_s: [0.001; 3],
    };
    let mut csv = String::from("# table-axis = +z\nt_s,rate_deg_s\n");
    for k in 0..400 {
        let t = k as f64 * 0.1;
        csv.push_str(&format!("{t},{}\n", if t < 20.0 { 0.0 } else { 30.0 }));
    }
    let log = ReferenceLog::from_csv_str(&csv, "t.csv")
        .unwrap()
        .with_offset(0.0);
    // (Only its clock is used, for the segments' conditions.)
    let series = ImuSeries {
        t_s: (0..4000).map(|k| k as f64 * 0.01).collect(),
        ..ImuSeries::default()
    };
    let w = 30f64.to_radians();
    // The unit upside down on the table: gravity along -z, so up is -z.
    let segs = [
        seg(SegmentKind::Static, [0.02, 0.0, -g], [0.0; 3], 2.0),
        seg(SegmentKind::Plateau, [0.0, 0.0, -g], [0.0, 0.0, w], 25.0),
    ];
    let truth = log.segment_truth(&series, &segs).unwrap();
    assert_eq!(truth[0].specific_force_m_s2, [0.0, 0.0, -g]);
    assert_eq!(truth[1].specific_force_m_s2, [0.0, 0.0, -g]);
    assert!((truth[1].angular_rate_rad_s[2] - w).abs() < 1e-12);
    // Without a latitude, all of Earth's rate is unknown.
    let sd = log.gyro_bias_std_rad_s(&segs).unwrap();
    assert!(
        sd.iter()
            .all(|s| (s - EARTH_RATE_RAD_S / 3f64.sqrt()).abs() < 1e-18)
    );
    // Gravity across the axis: the table is not vertical (or the axis is wrong).
    let tilted = [seg(SegmentKind::Static, [g, 0.0, 0.0], [0.0; 3], 2.0)];
    let e = log.segment_truth(&series, &tilted).unwrap_err().to_string();
    assert!(
        e.contains(
            "segment 1 at 2.0-12.0 s: the measured specific force +x is not along the table axis +z"
        ),
        "{e}"
    );
    // The table turning the other way about the axis than the log says.
    let reversed = [seg(
        SegmentKind::Plateau,
        [0.0, 0.0, g],
        [0.0, 0.0, -w],
        25.0,
    )];
    let e = log
        .segment_truth(&series, &reversed)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("measured -30.00 deg/s about +z, the log says 30.00 deg/s")
            && e.contains("(table-axis -z)"),
        "{e}"
    );
}

/// Steps of rate about z on a 100 Hz grid; the log runs on a clock `offset` ahead.
#[test]
fn finds_a_clock_offset_between_repeated_patterns() {
    let rate = |t: f64| -> f64 {
        // Three identical runs of 0, 20, 40, 0 deg/s, 10 s each, with 0.5 s ramps between
        // levels: a repeated pattern.
        let levels = [0.0, 20.0, 40.0, 0.0];
        let u = t.rem_euclid(40.0);
        let k = ((u / 10.0) as usize).min(3);
        let ramp = ((u - 10.0 * k as f64) / 0.5).min(1.0);
        levels[(k + 3) % 4] + (levels[k] - levels[(k + 3) % 4]) * ramp
    };
    let n = 12_000;
    let t_s: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
    let series = ImuSeries {
        gyro_rad_s: t_s
            .iter()
            .map(|&t| [0.003, -0.002, rate(t).to_radians() * 1.01 + 0.01])
            .collect(),
        accel_m_s2: vec![[0.0, 0.0, 9.8]; n],
        t_s: t_s.clone(),
        ..ImuSeries::default()
    };
    let offset = 1234.56;
    let mut csv = String::from("t_s,wx_deg_s,wy_deg_s,wz_deg_s\n");
    for t in (0..n).map(|i| i as f64 * 0.02 - 3.0) {
        csv.push_str(&format!("{},0,0,{}\n", t + offset, rate(t)));
    }
    let log = ReferenceLog::from_csv_str(&csv, "r.csv").unwrap();
    let a = log.align(&series).unwrap();
    assert!((a.offset_s - offset).abs() < 0.005, "{}", a.offset_s);
    assert!(a.correlation.unwrap() > 0.95);
}
