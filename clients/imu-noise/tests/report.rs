//! Every figure and the HTML report of `imu-noise`, checked mechanically on a series with known
//! noise (white noise and rate random walk, `imu_model::NoiseGenerator`): each SVG (the files of
//! `--plot` and the ones inlined in `--report`) has every text inside its view box and no two
//! texts overlapping, only finite numbers; each figure's axes span its data plus a small margin
//! and no more; the legend states the fitted values with their units; a term has one colour in
//! every figure.

use std::path::Path;
use std::process::Command;

use imu_analysis::render::allan::{ALLAN_PALETTE, sci};
use imu_analysis::render::html::inline_svgs;
use imu_analysis::render::lint::{check_svg, panel_ranges};
use imu_model::{NoiseGenerator, NoiseModel};

const RATE_HZ: f64 = 20.0;
/// One hour at 20 Hz: the white noise and the random walk both show (crossing near 90 s).
const SAMPLES: usize = 72_000;
const GYRO_N: f64 = 1e-3;
const GYRO_K: f64 = 2e-5;
const ACCEL_N: f64 = 2e-3;

fn write_csv(path: &Path) {
    let gyro = NoiseModel {
        white_density: [GYRO_N; 3],
        random_walk: [GYRO_K; 3],
        ..NoiseModel::default()
    };
    let accel = NoiseModel {
        white_density: [ACCEL_N; 3],
        ..NoiseModel::default()
    };
    let (mut g, mut a) = (
        NoiseGenerator::new(&gyro, RATE_HZ, 7),
        NoiseGenerator::new(&accel, RATE_HZ, 8),
    );
    let mut s = String::from("t,ax,ay,az,gx,gy,gz\n");
    for i in 0..SAMPLES {
        let (av, gv) = (a.next(), g.next());
        s += &format!(
            "{:.3},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e}\n",
            i as f64 / RATE_HZ,
            av[0],
            av[1],
            9.81 + av[2],
            gv[0],
            gv[1],
            gv[2]
        );
    }
    std::fs::write(path, s).unwrap();
}

/// Runs imu-noise with `--json --plot DIR --report FILE`; returns the JSON.
fn run(csv: &Path, plots: &Path, report: &Path) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-noise"))
        .arg(csv)
        .args(["--json", "--kind", "oadev,mdev,tdev,totdev", "--plot"])
        .arg(plots)
        .arg("--report")
        .arg(report)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The (tau, dev_lo, dev_hi) extremes of the curves of one sensor: [tau lo, tau hi, lo, hi].
fn data_range(curves: &[&serde_json::Value]) -> [f64; 4] {
    let mut r = [f64::INFINITY, 0.0, f64::INFINITY, 0.0];
    for c in curves {
        for p in c["points"].as_array().unwrap() {
            let f = |k: &str| p[k].as_f64().unwrap();
            r = [
                r[0].min(f("tau_s")),
                r[1].max(f("tau_s")),
                r[2].min(f("dev_lo")),
                r[3].max(f("dev_hi")),
            ];
        }
    }
    r
}

/// The axes cover the data, beyond it by at most 6 % of its span in decades plus 0.03.
fn assert_tight(name: &str, axis: [f64; 2], data: [f64; 2]) {
    let (span, lo, hi) = (
        (data[1] / data[0]).log10(),
        (data[0] / axis[0]).log10(),
        (axis[1] / data[1]).log10(),
    );
    for (edge, beyond) in [("low", lo), ("high", hi)] {
        assert!(
            (0.0..=0.06 * span + 0.03).contains(&beyond),
            "{name}: the {edge} edge is {beyond:.3} decades beyond the data ({axis:?} for \
             {data:?})"
        );
    }
}

#[test]
fn figures_and_report_are_readable_and_tight() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, plots, report) = (
        dir.path().join("noise.csv"),
        dir.path().join("plots"),
        dir.path().join("noise.html"),
    );
    write_csv(&csv);
    let v = run(&csv, &plots, &report);
    let axes = v.as_array().unwrap();

    let mut files: Vec<String> = std::fs::read_dir(&plots)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    files.sort();
    let want = [
        "allan-accel.svg",
        "allan-gyro.svg",
        "dev-mdev-accel.svg",
        "dev-mdev-gyro.svg",
        "dev-tdev-accel.svg",
        "dev-tdev-gyro.svg",
        "dev-totdev-accel.svg",
        "dev-totdev-gyro.svg",
    ];
    assert_eq!(files, want);
    let html = std::fs::read_to_string(&report).unwrap();
    let inline = inline_svgs(&html);
    assert_eq!(
        inline.len(),
        want.len(),
        "one figure per file in the report"
    );
    for (name, svg) in files.iter().map(|f| {
        let svg = std::fs::read_to_string(plots.join(f)).unwrap();
        (f.clone(), svg)
    }) {
        let problems = check_svg(&svg);
        assert!(problems.is_empty(), "{name}: {problems:#?}");
        assert!(
            inline.iter().any(|s| s.trim() == svg.trim()),
            "{name} is not in the report"
        );
        let sensor = if name.contains("gyro") {
            "gyro"
        } else {
            "accel"
        };
        let mine: Vec<&serde_json::Value> = axes.iter().filter(|a| a["sensor"] == sensor).collect();
        let curves: Vec<&serde_json::Value> = if name.starts_with("allan") {
            mine.iter().map(|a| &a["curve"]).collect()
        } else {
            let kind = name.split('-').nth(1).unwrap();
            mine.iter()
                .flat_map(|a| a["deviations"].as_array().unwrap())
                .filter(|d| d["kind"] == kind)
                .collect()
        };
        let data = data_range(&curves);
        let ranges = panel_ranges(&svg);
        assert_eq!(ranges.len(), 3, "{name}: a panel per axis");
        for r in ranges {
            assert_tight(&format!("{name} x"), [r[0], r[1]], [data[0], data[1]]);
            assert_tight(&format!("{name} y"), [r[2], r[3]], [data[2], data[3]]);
        }
    }
    assert!(html.contains("Fitted IEEE noise terms"));
    assert!(!html.contains("NaN") && !html.contains("inf<"));

    // The fit recovers the truth, and the legend says what it found, with units.
    let gyro_svg = std::fs::read_to_string(plots.join("allan-gyro.svg")).unwrap();
    for a in axes.iter().filter(|a| a["sensor"] == "gyro") {
        let n = &a["fit"]["n_u_per_sqrt_hz"];
        let k = &a["fit"]["k_u_sqrt_hz"];
        let (nv, kv) = (n["value"].as_f64().unwrap(), k["value"].as_f64().unwrap());
        assert!((nv / GYRO_N - 1.0).abs() < 0.1, "N {nv:e}");
        assert!((kv / GYRO_K - 1.0).abs() < 0.5, "K {kv:e}");
        for t in [n, k] {
            let shown = format!(
                "{} \u{b1} {}",
                sci(t["value"].as_f64().unwrap()),
                sci(t["sigma"].as_f64().unwrap())
            );
            assert!(gyro_svg.contains(&shown), "{shown} not in the legend");
        }
    }
    assert!(gyro_svg.contains("rad/s/\u{221a}Hz") && gyro_svg.contains("rad/s\u{b7}\u{221a}Hz"));

    // One colour per term: N in both sensors' figures, and nothing else drawn in it.
    let n_color = ALLAN_PALETTE.terms[1];
    for f in ["allan-accel.svg", "allan-gyro.svg"] {
        let svg = std::fs::read_to_string(plots.join(f)).unwrap();
        let n_paths: Vec<&str> = svg
            .lines()
            .filter(|l| l.contains("data-name=\"N term\""))
            .collect();
        assert_eq!(n_paths.len(), 3, "{f}: an N line per panel");
        for l in &svg
            .lines()
            .filter(|l| l.contains("class=\"series\""))
            .collect::<Vec<_>>()
        {
            assert_eq!(
                l.contains(n_color),
                l.contains("data-name=\"N term\""),
                "{f}: {l}"
            );
        }
    }
}
