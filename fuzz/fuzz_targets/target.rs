//! The libFuzzer binary of every target: `IMU_FUZZ_TARGET=<name>` (`imu-fuzz list`) picks one
//! of `imu_fuzz::ALL`, whose checks it runs on each input (the same checks the stable harness
//! runs in CI). One binary for all targets: a new target needs no change here.

#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;

fn target() -> &'static imu_fuzz::Target {
    static TARGET: OnceLock<&'static imu_fuzz::Target> = OnceLock::new();
    TARGET.get_or_init(|| {
        let name = std::env::var("IMU_FUZZ_TARGET").unwrap_or_default();
        imu_fuzz::Target::from_name(&name).unwrap_or_else(|| {
            let known: Vec<_> = imu_fuzz::ALL.iter().map(|t| t.name).collect();
            eprintln!(
                "set IMU_FUZZ_TARGET to one of: {} (it is `{name}`)",
                known.join(", ")
            );
            std::process::exit(64)
        })
    })
}

fuzz_target!(|data: &[u8]| target().check(data));
