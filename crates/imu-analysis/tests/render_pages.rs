//! Every report page of the characterisation (thermal, impact, dynamic) and the workbench
//! (verdict, ladder, diagnoses with the base model's residuals) rendered from short simulated
//! sessions, and checked mechanically: no text beyond the view box (width estimated from the
//! font size and the number of characters), axes drawn over the data plus a margin, no NaN,
//! no chart whose series are all constant, one number format, headings that agree with the
//! verdict.

use std::path::{Path, PathBuf};

use imu_analysis::characterize::{dynamic, impact, thermal};
use imu_analysis::input::{Source, read_mcap};
use imu_analysis::reference::Reference;
use imu_analysis::render::html::{
    self, Section, diagnose_section_with_base, ladder_section, verdict_section,
};
use imu_analysis::render::svg::{Figure, Style, all_points, axis_ranges};
use imu_analysis::workbench::{DiagnoseOptions, VerdictState, Workbench};
use imu_model::{Calibration, Triad, TriadModel};
use imu_rec::truth::read_truth;

const WIDTH: f64 = 800.0;
const HEIGHT: f64 = 560.0;

/// The attribute `name` of an SVG tag's text, if present.
fn attr(tag: &str, name: &str) -> Option<f64> {
    let key = format!(" {name}=\"");
    let i = tag.find(&key)? + key.len();
    tag[i..].split('"').next()?.parse().ok()
}

/// Every `<text>` of an SVG fits in the view box: width ~ 0.6 x font size per character,
/// placed by its anchor (a rotated label must fit the height instead).
fn check_text_inside(svg: &str, what: &str) {
    let default_size = 12.0;
    for part in svg.split("<text").skip(1) {
        let (tag, rest) = part.split_once('>').unwrap();
        let content = rest.split("</text>").next().unwrap();
        let chars = content
            .replace("&amp;", "&")
            .replace("&lt;", "<")
            .replace("&gt;", ">")
            .replace("&quot;", "\"")
            .replace("&apos;", "'")
            .chars()
            .count() as f64;
        let size = attr(tag, "font-size").unwrap_or(default_size);
        let width = 0.6 * size * chars;
        let (x, y) = (attr(tag, "x").unwrap(), attr(tag, "y").unwrap());
        if tag.contains("rotate(-90") {
            assert!(
                y - width / 2.0 >= 0.0 && y + width / 2.0 <= HEIGHT,
                "{what}: rotated text {content:?} is longer than the chart is high"
            );
            continue;
        }
        let left = if tag.contains("text-anchor=\"middle\"") {
            x - width / 2.0
        } else if tag.contains("text-anchor=\"end\"") {
            x - width
        } else {
            x
        };
        assert!(
            left >= 0.0 && left + width <= WIDTH && y - size >= 0.0 && y <= HEIGHT,
            "{what}: text {content:?} ({left:.0}..{:.0} px at y {y}) leaves the {WIDTH} x {HEIGHT} view box",
            left + width
        );
    }
}

/// The chart shows data (some series varies in y, the data vary in x), and its axes span the
/// data plus at most a margin (5 % per side on a linear axis, rounding to whole decades on a
/// log one).
fn check_chart(f: &Figure, what: &str) {
    let c = &f.chart;
    let data: Vec<Vec<(f64, f64)>> = c
        .series
        .iter()
        .filter(|s| !matches!(s.style, Style::Band { .. }))
        .map(|s| {
            all_points(s)
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .collect()
        })
        .collect();
    let varies = |v: &[f64]| {
        v.iter()
            .any(|a| (a - v[0]).abs() > 1e-12 * (1.0 + v[0].abs()))
    };
    let ys_vary = data.iter().any(|s| {
        let y: Vec<f64> = s.iter().map(|p| p.1).collect();
        !y.is_empty() && varies(&y)
    });
    let xs: Vec<f64> = data.iter().flatten().map(|p| p.0).collect();
    assert!(!xs.is_empty() && varies(&xs), "{what}: x does not vary");
    assert!(ys_vary, "{what}: every series is constant");
    let all: Vec<(f64, f64)> = c.series.iter().flat_map(all_points).collect();
    for (k, log) in [(0, c.log_x), (1, c.log_y)] {
        let v: Vec<f64> = all
            .iter()
            .map(|p| if k == 0 { p.0 } else { p.1 })
            .filter(|v| v.is_finite() && (!log || *v > 0.0))
            .collect();
        let (lo, hi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
                (l.min(x), h.max(x))
            });
        let (a, b) = axis_ranges(c)[k];
        assert!(
            a <= lo && b >= hi,
            "{what}: axis {k} {a}..{b} hides data {lo}..{hi}"
        );
        if log {
            assert!(
                (b / a).log10() <= (hi / lo).log10() + 2.0 + 1e-9,
                "{what}: log axis {k} {a}..{b} for data {lo}..{hi}"
            );
        } else {
            assert!(
                b - a <= 1.1 * (hi - lo) + 1e-9 * (1.0 + lo.abs()),
                "{what}: axis {k} {a}..{b} for data {lo}..{hi}"
            );
        }
    }
}

/// Every figure and the page of its sections, checked; the page is written under
/// `$IMU_RENDER_DIR` when set (to look at, e.g. with a headless browser).
fn check_page(name: &str, sections: &[Section], figures: &[Figure]) {
    for (i, f) in figures.iter().enumerate() {
        let what = format!("{name} figure {i} \"{}\"", f.chart.title);
        let svg = f.to_svg();
        assert!(
            !svg.contains("NaN") && !svg.contains("inf"),
            "{what}: NaN in the SVG"
        );
        check_text_inside(&svg, &what);
        check_chart(f, &what);
    }
    let page = html::page(name, sections);
    assert!(!page.contains("NaN"), "{name}: NaN on the page");
    for zero_p in ["p 0.0000", "p = 0.0000", "(0.0000)"] {
        assert!(
            !page.contains(zero_p),
            "{name}: a p-value written {zero_p:?}"
        );
    }
    for s in page.split("<svg").skip(1) {
        check_text_inside(s.split("</svg>").next().unwrap(), name);
    }
    if let Some(dir) = std::env::var_os("IMU_RENDER_DIR") {
        std::fs::write(Path::new(&dir).join(format!("{name}.html")), &page).unwrap();
    }
}

fn model_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/example-3dm-gx1.toml")
}

/// Records `scenario` through imud's offline path with the truth model `truth` (text),
/// correcting with `calibration` if given; the recording and the truth file.
fn record(
    dir: &Path,
    scenario: &str,
    truth: &str,
    calibration: Option<&Path>,
) -> (PathBuf, PathBuf) {
    let s = dir.join("s.toml");
    std::fs::write(&s, scenario).unwrap();
    let m = dir.join("truth-model.toml");
    std::fs::write(&m, truth).unwrap();
    let mut sim = imu_sim::SimOptions::from_files(&s, Some(&m)).unwrap();
    sim.seed = 3;
    let truth_path = dir.join("truth.mcap");
    sim.truth_out = Some(truth_path.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.join("log");
    c.log.rotate_size_mib = 1 << 20;
    c.name = "t".into();
    c.calibration.path = calibration.map(Path::to_path_buf);
    let out = imud::offline::record(sim, &c).unwrap();
    (out.files[0].clone(), truth_path)
}

#[test]
fn thermal_page() {
    let scenario = r#"
name = "render-thermal"
rate-hz = 50.0
latitude-deg = 40.0
[temperature]
kind = "warmup"
ambient-c = 22.0
operating-c = 38.0
tau-s = 400.0
[[segment]]
kind = "static"
orientation = { roll-deg = 0.0, pitch-deg = 0.0, yaw-deg = 0.0 }
duration-s = 1500.0
"#;
    let dir = tempfile::tempdir().unwrap();
    let truth = format!(
        "{}\n[accel.temp-bias]\nt0-c = 25.0\ncoefficients = [[2e-3, 0.0, 0.0]]\n",
        std::fs::read_to_string(model_path()).unwrap()
    );
    let (rec, _) = record(dir.path(), scenario, &truth, None);
    let series = read_mcap(&rec, Source::Raw, None).unwrap();
    let r = thermal::analyze(&series, &thermal::ThermalOptions::default()).unwrap();
    let figures = thermal::charts(&r);
    let section = html::thermal_section(&r, &figures);
    // The heading follows the verdict; the title is said once.
    assert!(r.axes[0].model_warranted, "{}", r.recommendation);
    assert!(section.html.contains("<strong>warranted</strong>"));
    let page = html::page(&section.title, std::slice::from_ref(&section));
    assert_eq!(
        page.matches("Thermal test (warm-up)").count(),
        2,
        "title and h1"
    );
    assert!(section.html.contains("[mg/K]") && section.html.contains("[deg/h/K]"));
    check_page("thermal", std::slice::from_ref(&section), &figures);
}

const IMPACT_DYNAMIC: &str = r#"
name = "render-impact-dynamic"
rate-hz = 100.0
latitude-deg = 40.0
[[segment]]
kind = "static"
orientation = { z = "up", x = "north" }
duration-s = 5.0
[[segment]]
kind = "impacts"
axis = "z"
count = 4
period-s = 1.0
peak-g = 3.0
width-ms = 40.0
[[segment]]
kind = "index-table"
axis = "z"
step-deg = 30.0
positions = 4
dwell-s = 3.0
move-s = 1.5
[[segment]]
kind = "static"
duration-s = 5.0
"#;

#[test]
fn impact_and_dynamic_pages() {
    let dir = tempfile::tempdir().unwrap();
    let truth = std::fs::read_to_string(model_path()).unwrap();
    // No calibration loaded: the calibrated stream is the raw one, and the page says so.
    let (rec, truth_path) = record(dir.path(), IMPACT_DYNAMIC, &truth, None);
    let raw = read_mcap(&rec, Source::Raw, None).unwrap();
    let corrected = read_mcap(&rec, Source::Corrected, None).unwrap();
    let ir = impact::analyze(&raw, &impact::ImpactOptions::default()).unwrap();
    let figures = impact::charts(&raw, &ir);
    check_page("impact", &[html::impact_section(&ir, &figures)], &figures);

    let reference = dynamic::Reference::from_truth(&read_truth(&truth_path).unwrap(), "truth");
    let o = dynamic::DynamicOptions::default();
    let dr = dynamic::compare(
        &reference,
        Some(dynamic::analyze(&raw, &reference, &o).unwrap()),
        Some(dynamic::analyze(&corrected, &reference, &o).unwrap()),
    );
    assert_eq!(
        dr.calibration,
        dynamic::CalibrationEffect::NoCalibrationLoaded
    );
    assert_eq!(dr.growth_reduction_factor, None);
    assert!(
        dr.summary.contains("no calibration was loaded") && !dr.summary.contains("reduces"),
        "{}",
        dr.summary
    );
    let figures = dynamic::charts(&dr);
    // The raw line is drawn last (on top) and dashed.
    let error = figures.last().unwrap();
    assert!(error.chart.series.last().unwrap().name.starts_with("raw"));
    assert!(error.look.series.last().unwrap().dashed);
    check_page("dynamic", &[html::dynamic_section(&dr, &figures)], &figures);
}

#[test]
fn workbench_pages() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = include_str!("../../../config/scenarios/workbench-demo.toml");
    // The demo's truth: bias, scale, misalignment and a hidden gyro g-sensitivity.
    let truth = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/models/workbench-demo.toml"),
    )
    .unwrap();
    let session =
        imud::offline::record_session_text(dir.path(), "t", scenario, Some(&truth), 11, None)
            .unwrap();
    let series = read_mcap(&session.recording, Source::Raw, None).unwrap();
    let reference = Reference::Truth(read_truth(&session.truth).unwrap());
    let wb = Workbench::new(&series, &reference, DiagnoseOptions::default()).unwrap();
    let mut base = Calibration::identity();
    base.accel = TriadModel::with_effects(&TriadModel::PAPER_BASE);
    base.gyro = TriadModel::with_effects(&TriadModel::PAPER_BASE);
    let ladder = wb.ladder(&base).unwrap();
    let [accel, gyro] = &ladder.final_diagnoses;
    let base_gyro = &ladder.base_diagnoses[1];
    assert_ne!(
        base_gyro.state,
        VerdictState::Consistent,
        "g-sensitivity is hidden"
    );

    let verdict = verdict_section(&[accel, gyro]);
    // The heading says what the verdict says.
    for d in [accel, gyro, base_gyro] {
        let heading = html::verdict_heading(d);
        let consistent_words = d.verdict.consistent;
        assert_eq!(
            heading.starts_with("consistent"),
            consistent_words,
            "{heading} / {}",
            d.verdict
        );
    }
    let sections = [
        verdict,
        ladder_section(&ladder.steps),
        diagnose_section_with_base(
            accel,
            Some(&ladder.base_diagnoses[0]),
            &wb.signal_values(Triad::Accel),
        ),
        diagnose_section_with_base(gyro, Some(base_gyro), &wb.signal_values(Triad::Gyro)),
    ];
    let all = sections
        .iter()
        .map(|s| s.html.to_string())
        .collect::<String>();
    assert!(all.contains("base model: segment residual") && all.contains("final model"));
    assert!(all.contains("noise floor, 95 %"));
    let mut figures = html::ladder_figures(&ladder.steps);
    figures.extend(html::diagnose_figures(
        accel,
        Some(&ladder.base_diagnoses[0]),
        &wb.signal_values(Triad::Accel),
    ));
    figures.extend(html::diagnose_figures(
        gyro,
        Some(base_gyro),
        &wb.signal_values(Triad::Gyro),
    ));
    check_page("workbench", &sections, &figures);
    assert!(
        !all.contains("input magnitude</text>"),
        "a constant signal gets no chart"
    );
}
