//! The device layer's invariant (ARCHITECTURE.md): nothing outside `daemon/src/drivers/` names
//! a protocol. Outside it, the non-test code of every source file may use `imu_proto` only for
//! the protocol's name a user configures (`DeviceProtocol`), the codec-neutral decoder counters
//! and reject reasons, the one representation of a unit's GNSS time every codec converts to
//! (`gnss_time::GnssTime`), and the configuration's documented defaults; it never imports a codec
//! (commands, replies, decoders, MIP) or a protocol's driver.

use std::path::Path;

/// What non-driver code may name of `imu_proto`.
const ALLOWED: [&str; 5] = [
    "imu_proto::DeviceProtocol",
    "imu_proto::decoder::{DecoderStats, RejectReason}",
    "imu_proto::gnss_time::GnssTime",
    "imu_proto::GainScales::DEFAULT_FALLBACK",
    "imu_proto::ticks::DEFAULT_TICK_PERIOD_S",
];

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn nothing_outside_drivers_names_a_protocol() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut offences = Vec::new();
    for f in files {
        if f.starts_with(src.join("drivers")) {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap();
        // The tests at the end of a file may use a protocol as a fixture.
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        for (i, line) in code.lines().enumerate() {
            let line = line.trim_start();
            if line.starts_with("//") {
                continue;
            }
            let names_codec = line.contains("imu_proto::")
                && !ALLOWED
                    .iter()
                    .any(|a| line.contains(a) && line.matches("imu_proto::").count() == 1);
            let names_driver = ["drivers::gx1", "drivers::mip", "drivers::xsens"]
                .iter()
                .any(|d| line.contains(d));
            if names_codec || names_driver {
                offences.push(format!("{}:{}: {line}", f.display(), i + 1));
            }
        }
    }
    assert!(
        offences.is_empty(),
        "protocol named outside drivers/:\n{}",
        offences.join("\n")
    );
}
