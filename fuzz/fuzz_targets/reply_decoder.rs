//! Fuzz target: 3DM-GX1 replies (host side) through `imu_fuzz::Target::ReplyDecoder`'s checks (every byte accounted for
//! once, events rebuilding the stream, no panic); the same checks the stable harness runs in CI.

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| imu_fuzz::Target::ReplyDecoder.check(data));
