//! The offline tools link no shared-memory code (ARCHITECTURE.md): `imu-rec`, the library and
//! every offline client resolve, for the code they link (normal dependencies, proc macros
//! excluded: those run at compile time only), to no iceoryx2 crate but the `ZeroCopySend`
//! marker trait, which has no dependencies and no code of the transport.

use std::process::Command;

/// The offline packages: the file formats, the analysis library, the shared CLI code, the
/// simulator, the offline clients and the Python package.
const OFFLINE: [&str; 9] = [
    "imu-rec",
    "imu-analysis",
    "imu-cli",
    "imu-sim",
    "imu-analyze",
    "imu-calibrate",
    "imu-diagnose",
    "imu-noise",
    "imud-python",
];

/// The one iceoryx2 crate an offline package may link: the marker trait the sample types derive.
const ALLOWED_ICEORYX2: &str = "iceoryx2-bb-elementary-traits";

/// The packages `package` links, one name per entry (from `cargo tree`).
fn linked_packages(package: &str) -> Vec<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_string());
    let manifest = concat!(env!("CARGO_MANIFEST_DIR"), "/../../Cargo.toml");
    let out = Command::new(cargo)
        .args([
            "tree",
            "--offline",
            "--manifest-path",
            manifest,
            "-p",
            package,
        ])
        .args([
            "-e",
            "normal,no-proc-macro",
            "--prefix",
            "none",
            "-f",
            "{p}",
        ])
        .output()
        .expect("run cargo tree");
    assert!(
        out.status.success(),
        "cargo tree -p {package} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .expect("cargo tree prints UTF-8")
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_string)
        .collect()
}

#[test]
fn offline_tools_link_no_shared_memory_code() {
    for package in OFFLINE {
        let linked = linked_packages(package);
        // The tree starts with the package itself: an empty answer would prove nothing.
        assert_eq!(linked.first().map(String::as_str), Some(package));
        assert!(
            linked.iter().any(|p| p == "imu-rec"),
            "{package} does not use imu-rec"
        );
        let shm: Vec<&String> = linked
            .iter()
            .filter(|p| p.as_str() == "imu-bus" || p.starts_with("iceoryx2"))
            .filter(|p| p.as_str() != ALLOWED_ICEORYX2)
            .collect();
        assert!(
            shm.is_empty(),
            "{package} links shared-memory code: {shm:?}"
        );
    }
}

#[test]
fn the_daemon_links_the_transport() {
    // The check above would pass vacuously if the names it looks for never appeared.
    let linked = linked_packages("imud");
    assert!(linked.iter().any(|p| p == "imu-bus"));
    assert!(linked.iter().any(|p| p == "iceoryx2"));
}
