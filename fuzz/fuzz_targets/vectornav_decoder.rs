//! Fuzz target: VectorNav binary messages and ASCII sentences through
//! `imu_fuzz::Target::VectornavDecoder`'s checks (every byte accounted for once, events
//! rebuilding the stream, no panic); the same checks the stable harness runs in CI.

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| imu_fuzz::Target::VectornavDecoder.check(data));
