//! Fuzz target: MIP packets through `imu_fuzz::Target::MipDecoder`'s checks (every byte accounted for
//! once, events rebuilding the stream, no panic); the same checks the stable harness runs in CI.

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| imu_fuzz::Target::MipDecoder.check(data));
