//! The text reader: layouts, headers, units, columns, labels, errors, two files.

use super::*;
use crate::input::G0;

#[test]
fn csv_with_header_units_and_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.csv");
    std::fs::write(
        &p,
        "t,ax,ay,az,gx,gy,gz\n10.0,0,0,1,0,0,90\n10.01,0,0,1,0,0,-90\n",
    )
    .unwrap();
    let s = read_csv(
        &p,
        &CsvOptions {
            time_scale_s: 1.0,
            accel: AccelUnit::G,
            gyro: GyroUnit::DegPerSecond,
            gyro_file: None,
            ..CsvOptions::default()
        },
    )
    .unwrap();
    assert_eq!(s.len(), 2);
    assert!((s.t_s[1] - 0.01).abs() < 1e-12);
    assert!((s.accel_m_s2[0][2] - G0).abs() < 1e-12);
    assert!((s.gyro_rad_s[1][2] + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    assert!((s.sample_rate_hz() - 100.0).abs() < 1e-6);
    std::fs::write(&p, "t,ax,ay,az,gx,gy,gz\n1,2,3,4,5,6,7\n1,2,x,4,5,6,7\n").unwrap();
    let e = read_csv(&p, &CsvOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("a.csv:3:"), "{e}");
    assert!(e.contains("column 3 is not a number"), "{e}");
    std::fs::write(&p, "1,2,3,4,5,6,7\n0.5,2,3,4,5,6,7\n").unwrap();
    let e = read_csv(&p, &CsvOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a.csv:2:") && e.contains("does not increase"),
        "{e}"
    );
    std::fs::write(&p, "t,ax,ay,az\n1,2,3,4\n").unwrap();
    let e = read_csv(&p, &CsvOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a.csv:2:") && e.contains("expected 7 columns"),
        "{e}"
    );
}

/// Raw counts with a scale, and the accelerometer and gyro in two files on one clock (the
/// gyro at its own, offset times, interpolated to the accelerometer's; accelerometer
/// samples outside the gyro's span dropped).
#[test]
fn csv_counts_and_two_files() {
    assert_eq!("g".parse::<AccelUnit>(), Ok(AccelUnit::G));
    assert_eq!("counts:0.5".parse::<GyroUnit>(), Ok(GyroUnit::Counts(0.5)));
    assert!(
        "counts:x"
            .parse::<AccelUnit>()
            .unwrap_err()
            .contains("counts:SCALE")
    );
    assert!("furlongs".parse::<GyroUnit>().is_err());
    let dir = tempfile::tempdir().unwrap();
    let (a, g) = (dir.path().join("acc.csv"), dir.path().join("gyr.csv"));
    let mut at = String::from("time_ns,ax,ay,az\n");
    for k in 0..10 {
        at += &format!("{},{},0,100\n", 1_000_000_000 + k * 10_000_000, k);
    }
    std::fs::write(&a, at).unwrap();
    // Gyro at 5 ms after each accel sample, starting one accel sample later: z = 2 t.
    let mut gt = String::from("time_ns,gx,gy,gz\n");
    for k in 1..12 {
        let t = 1_000_000_000 + k * 10_000_000 + 5_000_000;
        gt += &format!("{t},0,0,{}\n", 2 * (t - 1_000_000_000) / 1_000_000);
    }
    std::fs::write(&g, gt).unwrap();
    let s = read_csv(
        &a,
        &CsvOptions {
            time_scale_s: 1e-9,
            accel: AccelUnit::Counts(0.01),
            gyro: GyroUnit::Counts(1e-3),
            gyro_file: Some(g.clone()),
            ..CsvOptions::default()
        },
    )
    .unwrap();
    // Accel samples 0 and 1 precede the gyro's first (15 ms): dropped.
    assert_eq!(s.len(), 8, "{:?}", s.t_s);
    assert!((s.accel_m_s2[0][0] - 0.02).abs() < 1e-12);
    assert!((s.accel_m_s2[0][2] - 1.0).abs() < 1e-12);
    for (k, w) in s.gyro_rad_s.iter().enumerate() {
        // Accel sample k + 2 at (k + 2) x 10 ms: gyro z = 2 x ms x 1e-3.
        let want = 2.0 * (10.0 * (k + 2) as f64) * 1e-3;
        assert!((w[2] - want).abs() < 1e-9, "{k}: {} vs {want}", w[2]);
    }
    assert!(s.origin.contains("acc.csv + "), "{}", s.origin);
    // Files on different clocks do not overlap: a clear error naming the gyro file.
    std::fs::write(&g, "0,0,0,0\n0.5,0,0,0\n").unwrap();
    let e = read_csv(
        &a,
        &CsvOptions {
            time_scale_s: 1e-9,
            gyro_file: Some(g.clone()),
            ..CsvOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("gyr.csv") && e.contains("one clock"), "{e}");
}

/// The truth of the layout tests: 100 Hz, distinct values on every axis and sample.
fn truth(k: usize) -> (f64, [f64; 3], [f64; 3]) {
    let x = k as f64;
    (
        12.5 + 0.01 * x,
        [0.125 * x, -0.25 + 0.001 * x, 9.75 - 0.5 * x],
        [0.015625 * x, -0.03125, 0.0625 - 0.0078125 * x],
    )
}

const N: usize = 40;

fn write(dir: &Path, name: &str, text: String) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn assert_truth(s: &ImuSeries, what: &str) {
    assert_eq!(s.len(), N, "{what}");
    for k in 0..N {
        let (t, a, g) = truth(k);
        assert!((s.t_s[k] - (t - 12.5)).abs() < 1e-9, "{what} t[{k}]");
        for i in 0..3 {
            assert!(
                (s.accel_m_s2[k][i] - a[i]).abs() < 1e-9,
                "{what} a[{k}][{i}]"
            );
            assert!(
                (s.gyro_rad_s[k][i] - g[i]).abs() < 1e-12,
                "{what} g[{k}][{i}]"
            );
        }
    }
}

/// Every separator, with and without a header, `#` and `%` comments, any extension: the
/// parsed values equal the truth they were written from.
#[test]
fn every_layout_reads_back_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let line = |k: usize, sep: &str| {
        let (t, a, g) = truth(k);
        [t, a[0], a[1], a[2], g[0], g[1], g[2]]
            .map(|v| format!("{v:?}"))
            .join(sep)
    };
    let body = |sep: &str| (0..N).map(|k| line(k, sep) + "\n").collect::<String>();
    let files = [
        ("a.csv", format!("t,ax,ay,az,gx,gy,gz\n{}", body(","))),
        ("a.dat", format!("# no header\n{}", body(";"))),
        (
            "a.tsv",
            format!("time\tax\tay\taz\tgx\tgy\tgz\n{}", body("\t")),
        ),
        (
            "a.mat",
            format!("% MATLAB -ascii\n%  t ax ay az gx gy gz\n{}", body("   ")),
        ),
        ("a.txt", format!("\n  {}", body(" \t "))),
        (
            "no_extension",
            format!("t, ax, ay, az, gx, gy, gz\n{}", body(", ")),
        ),
    ];
    for (name, text) in files {
        let p = write(dir.path(), name, text);
        let s = read_csv(&p, &CsvOptions::default()).unwrap();
        assert_truth(&s, name);
        assert_eq!(s.input.files, vec![p.clone()]);
        assert_eq!(s.labels, None);
    }
}

/// An unsigned 16-bit raw-count file with mid-scale 32768 whose first line is data (whitespace
/// separated, `.txt`): the first line is kept, and `counts:SCALE@OFFSET` (one offset, and per
/// axis) gives the physical values.
#[test]
fn raw_unsigned_counts_with_offsets_and_a_numeric_first_line() {
    let dir = tempfile::tempdir().unwrap();
    let (ka, kg) = (0.00241, 0.000_2);
    let acc_off = [32768.0, 32768.0, 32790.0];
    let mut text = String::new();
    let mut want = Vec::new();
    for k in 0..N {
        let c: [u16; 6] = [
            32768 + 3 * k as u16,
            32768 - 400,
            32768 + 4069 - k as u16,
            32768 + 20 + k as u16,
            32768 - 25,
            32768 + 17,
        ];
        text += &format!(
            "{} {} {} {} {} {} {}\n",
            0.01 * k as f64,
            c[0],
            c[1],
            c[2],
            c[3],
            c[4],
            c[5]
        );
        want.push(c);
    }
    let p = write(dir.path(), "raw.txt", text);
    let options = CsvOptions {
        accel: "counts:0.00241@32768,32768,32790".parse().unwrap(),
        gyro: "counts:0.0002@32768".parse().unwrap(),
        ..CsvOptions::default()
    };
    let s = read_csv(&p, &options).unwrap();
    assert_eq!(s.len(), N, "the numeric first line is data");
    for (k, c) in want.iter().enumerate() {
        for i in 0..3 {
            let a = (f64::from(c[i]) - acc_off[i]) * ka;
            let g = (f64::from(c[i + 3]) - 32768.0) * kg;
            assert!((s.accel_m_s2[k][i] - a).abs() < 1e-12, "a[{k}][{i}]");
            assert!((s.gyro_rad_s[k][i] - g).abs() < 1e-15, "g[{k}][{i}]");
        }
    }
    // At rest the gyro reads near zero, not 32768 x scale.
    assert!(s.gyro_rad_s[0].iter().all(|w| w.abs() < 0.01));
}

/// Columns chosen by header name in any order, or by 0-based index; a `part` column is carried
/// per sample with its names; two whitespace files (accel, gyro) aligned by time.
#[test]
fn columns_by_name_or_index_labels_and_two_files() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("gz gy part gx time az ay ax\n");
    for k in 0..N {
        let (t, a, g) = truth(k);
        let part = if k < 15 {
            "face +z"
        } else if k < 30 {
            "turn_x"
        } else {
            "face +z"
        };
        let part = part.replace(' ', "_");
        text += &format!(
            "{:?} {:?} {part} {:?} {:?} {:?} {:?} {:?}\n",
            g[2], g[1], g[0], t, a[2], a[1], a[0]
        );
    }
    let p = write(dir.path(), "shuffled.dat", text);
    let by_name: Vec<ColumnRef> = "time,ax,ay,az,gx,gy,gz"
        .split(',')
        .map(|c| c.parse().unwrap())
        .collect();
    let columns = Columns {
        main: Some(by_name),
        ..Columns::default()
    };
    let s = read_text(&p, &CsvOptions::default(), &columns).unwrap();
    assert_truth(&s, "by name");
    let labels = s.labels.as_ref().expect("the part column is carried");
    assert_eq!(labels.names, vec!["face_+z", "turn_x"]);
    assert_eq!(labels.per_sample.len(), N);
    for k in 0..N {
        let want = if (15..30).contains(&k) {
            "turn_x"
        } else {
            "face_+z"
        };
        assert_eq!(labels.of(k), want, "sample {k}");
    }
    let by_index = Columns {
        main: Some(
            [4, 7, 6, 5, 3, 1, 0]
                .into_iter()
                .map(ColumnRef::Index)
                .collect(),
        ),
        label: Some(ColumnRef::Name("PART".into())),
        ..Columns::default()
    };
    let s2 = read_text(&p, &CsvOptions::default(), &by_index).unwrap();
    assert_eq!(s2, s);
    // Two files, whitespace, no header; the gyro's columns chosen (time last).
    let (mut at, mut gt) = (String::new(), String::new());
    for k in 0..N {
        let (t, a, g) = truth(k);
        at += &format!("{t:?} {:?} {:?} {:?}\n", a[0], a[1], a[2]);
        gt += &format!("{:?}\t{:?}\t{:?}\t{t:?}\n", g[0], g[1], g[2]);
    }
    let (a, g) = (
        write(dir.path(), "acc.txt", at),
        write(dir.path(), "gyro.txt", gt),
    );
    let two = read_text(
        &a,
        &CsvOptions {
            gyro_file: Some(g.clone()),
            ..CsvOptions::default()
        },
        &Columns {
            gyro: Some([3, 0, 1, 2].into_iter().map(ColumnRef::Index).collect()),
            ..Columns::default()
        },
    )
    .unwrap();
    assert_truth(&two, "two files");
    assert_eq!(two.input.files, vec![a, g]);
}

/// Errors name the file, the line and the column, and say what is wrong.
#[test]
fn errors_name_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("% acc\n");
    for k in 0..5 {
        text += &format!("{} 1 2 3\n", k);
    }
    text += "5 1 1.2.3 3\n";
    let p = write(dir.path(), "acc.txt", text);
    let g = write(dir.path(), "g.txt", "0 0 0 0\n9 0 0 0\n".into());
    let options = CsvOptions {
        gyro_file: Some(g),
        ..CsvOptions::default()
    };
    let e = read_csv(&p, &options).unwrap_err().to_string();
    assert!(
        e.contains("acc.txt:7: column 3 is not a number: `1.2.3`"),
        "{e}"
    );
    let named = Columns {
        main: Some(vec![ColumnRef::Name("t".into()); 4]),
        ..Columns::default()
    };
    let e = read_text(&p, &options, &named).unwrap_err().to_string();
    assert!(
        e.contains("acc.txt:2:") && e.contains("no header line"),
        "{e}"
    );
    let short = Columns {
        main: Some(vec![ColumnRef::Index(0); 3]),
        ..Columns::default()
    };
    let e = read_text(&p, &options, &short).unwrap_err().to_string();
    assert!(
        e.contains("3 columns chosen for 4 (time, ax, ay, az)"),
        "{e}"
    );
}

/// A Latin-1 header (0xB0, the degree sign, is not UTF-8) is still text, told by content
/// through `read_any`, and its data reads back the truth.
#[test]
fn an_eight_bit_header_is_text() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = b"t [s]\tax [m/s\xb2]\tay\taz\tgx [\xb0/s]\tgy\tgz\n".to_vec();
    for k in 0..N {
        let (t, a, g) = truth(k);
        let v = [t, a[0], a[1], a[2], g[0], g[1], g[2]].map(|v| format!("{v:?}"));
        bytes.extend((v.join("\t") + "\n").into_bytes());
    }
    let p = dir.path().join("latin1.tsv");
    std::fs::write(&p, bytes).unwrap();
    let s = crate::input::read_any(&p, crate::input::Source::Raw, &CsvOptions::default()).unwrap();
    assert_truth(&s, "latin1");
}

/// A file without a time column, like a published labelled session: parts concatenated, each
/// with a sample index that restarts at 0, raw counts. At `--rate-hz` row `n` is at
/// `start + n / rate` across the parts; the index is a column that is not read.
#[test]
fn a_file_without_time_is_timed_by_its_rows_at_the_rate() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("part,samples,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z\n");
    let parts = ["x_p", "x_a", "x_rot"];
    for (k, part) in parts.iter().enumerate() {
        for i in 0..5 {
            let n = 5 * k + i;
            text += &format!("{part},{i},{n},{},-3,{},0,1\n", 2 * n, -(n as i64));
        }
    }
    let p = write(dir.path(), "session.csv", text);
    let columns = Columns {
        main: Some(
            ["acc_x", "acc_y", "acc_z", "gyr_x", "gyr_y", "gyr_z"]
                .map(|c| ColumnRef::Name(c.into()))
                .to_vec(),
        ),
        ..Columns::default()
    };
    let options = CsvOptions {
        rate_hz: Some(204.8),
        start_s: 12.5,
        accel: AccelUnit::Counts(0.5),
        ..CsvOptions::default()
    };
    let s = read_text(&p, &options, &columns).unwrap();
    assert_eq!(s.len(), 15);
    for (n, t) in s.t_s.iter().enumerate() {
        assert_eq!(*t, (12.5 + n as f64 / 204.8) - 12.5, "row {n}");
        assert_eq!(s.accel_m_s2[n], [0.5 * n as f64, n as f64, -1.5], "row {n}");
        assert_eq!(s.gyro_rad_s[n], [-(n as f64), 0.0, 1.0], "row {n}");
    }
    assert_eq!(s.t0_ns, 12_500_000_000);
    let labels = s.labels.as_ref().unwrap();
    assert_eq!(labels.names, parts);
    assert_eq!(labels.of(14), "x_rot");
    // Without --columns the first six columns but the label: the index is read as ax.
    let s = read_text(&p, &options, &Columns::default()).unwrap();
    assert_eq!(s.accel_m_s2[6][0], 0.5);
    // Six values and a time chosen at a rate: the count is wrong, and the message says so.
    let seven = Columns {
        main: Some((1..8).map(ColumnRef::Index).collect()),
        ..Columns::default()
    };
    let e = read_text(&p, &options, &seven).unwrap_err().to_string();
    assert!(
        e.contains("7 columns chosen for 6 (ax, ay, az, gx, gy, gz)"),
        "{e}"
    );
    // The per-part index as a time column: refused where it restarts, pointing at the rate.
    let timed = Columns {
        main: Some((1..8).map(ColumnRef::Index).collect()),
        ..Columns::default()
    };
    let e = read_text(&p, &CsvOptions::default(), &timed)
        .unwrap_err()
        .to_string();
    assert!(e.contains("session.csv:7:"), "{e}");
    assert!(e.contains("--rate-hz"), "{e}");
    // A rate that cannot time anything.
    let zero = CsvOptions {
        rate_hz: Some(0.0),
        ..CsvOptions::default()
    };
    let e = read_text(&p, &zero, &columns).unwrap_err().to_string();
    assert!(e.contains("give a positive rate"), "{e}");
}

/// Two time-less files at one rate: the gyro's rows are the accelerometer's.
#[test]
fn two_files_without_time_share_the_rate() {
    let dir = tempfile::tempdir().unwrap();
    let a = write(dir.path(), "acc.txt", "0 0 1\n0 0 2\n0 0 3\n".into());
    let g = write(dir.path(), "gyr.txt", "1 0 0\n2 0 0\n3 0 0\n".into());
    let options = CsvOptions {
        rate_hz: Some(100.0),
        gyro_file: Some(g),
        ..CsvOptions::default()
    };
    let s = read_csv(&a, &options).unwrap();
    assert_eq!(s.t_s, vec![0.0, 0.01, 0.02]);
    for k in 0..3 {
        assert_eq!(s.accel_m_s2[k][2], (k + 1) as f64);
        assert_eq!(s.gyro_rad_s[k][0], (k + 1) as f64);
    }
}
