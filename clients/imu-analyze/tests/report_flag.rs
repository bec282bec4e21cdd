//! Every client that writes an HTML report calls the flag `--report`; imu-analyze's old name
//! `--html` still works but is no longer offered.

use std::process::Command;

fn help(sub: &str) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_imu-analyze"))
        .args([sub, "--help"])
        .output()
        .unwrap();
    assert!(out.status.success());
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn report_is_the_flag_and_html_a_hidden_alias() {
    for sub in ["thermal", "impact", "dynamic"] {
        let h = help(sub);
        assert!(h.contains("--report <REPORT.html>"), "{sub}: {h}");
        assert!(!h.contains("--html"), "{sub}: {h}");
    }
    // The alias parses: the run fails on the missing input (66), not on the flag (64).
    for flag in ["--report", "--html"] {
        let out = Command::new(env!("CARGO_BIN_EXE_imu-analyze"))
            .args(["impact", "/nonexistent/rec.mcap", flag, "/tmp/unused.html"])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(66), "{flag}: {out:?}");
    }
}
