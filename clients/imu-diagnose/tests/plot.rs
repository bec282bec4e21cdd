//! `imu-diagnose --plot DIR` (as the other clients' `--plot`): the report's charts as SVG files,
//! numbered in the report's order, each the same SVG the report inlines; with or without
//! `--report`.

use std::path::{Path, PathBuf};
use std::process::Command;

use imu_analysis::render::html::inline_svgs;

fn config(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../config")
        .join(rel)
}

fn run(args: &[&std::ffi::OsStr]) {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-diagnose"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "imu-diagnose failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn svg_files(dir: &Path) -> Vec<(String, String)> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    names
        .into_iter()
        .map(|n| {
            let svg = std::fs::read_to_string(dir.join(&n)).unwrap();
            (n, svg)
        })
        .collect()
}

#[test]
fn plot_writes_the_reports_charts() {
    let dir = tempfile::tempdir().unwrap();
    let s = imud::offline::record_session(
        dir.path(),
        "t",
        &config("scenarios/workbench-demo.toml"),
        Some(&config("models/workbench-demo.toml")),
        11,
        None,
    )
    .unwrap();
    let (report, plots, alone) = (
        dir.path().join("r.html"),
        dir.path().join("plots"),
        dir.path().join("alone"),
    );
    let args = [
        s.recording.as_os_str(),
        "--reference".as_ref(),
        s.truth.as_os_str(),
    ];
    run(&[
        &args[..],
        &[
            "--report".as_ref(),
            report.as_os_str(),
            "--plot".as_ref(),
            plots.as_os_str(),
        ],
    ]
    .concat());
    let html = std::fs::read_to_string(&report).unwrap();
    let inline = inline_svgs(&html);
    let files = svg_files(&plots);
    assert!(files.len() >= 4, "{} charts", files.len());
    assert_eq!(files.len(), inline.len());
    for (i, ((name, svg), want)) in files.iter().zip(&inline).enumerate() {
        assert_eq!(name, &format!("diagnose-{:02}.svg", i + 1));
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert_eq!(svg.trim_end(), *want);
    }
    // --plot alone: the same charts, no report needed.
    run(&[&args[..], &["--plot".as_ref(), alone.as_os_str()]].concat());
    assert_eq!(svg_files(&alone), files);
}
