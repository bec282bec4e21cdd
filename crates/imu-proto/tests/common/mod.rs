//! Shared proptest strategies for replies, commands and nasty byte streams.

#![allow(dead_code)] // each test binary uses a different subset

use imu_proto::command::KNOWN_COMMAND_CODES;
use imu_proto::reply::{Filter, KNOWN_REPLY_CODES};
use imu_proto::{Command, Reply};
use proptest::prelude::*;

/// A byte that is often a known header code, so frames and garbage are full of false starts.
pub fn nasty_byte() -> impl Strategy<Value = u8> {
    prop_oneof![
        2 => any::<u8>(),
        1 => prop::sample::select(KNOWN_REPLY_CODES.to_vec()),
        1 => Just(0x00u8),
    ]
}

/// A 16-bit word made of nasty bytes half of the time.
pub fn nasty_word() -> impl Strategy<Value = u16> {
    prop_oneof![
        any::<u16>(),
        (nasty_byte(), nasty_byte()).prop_map(|(hi, lo)| u16::from_be_bytes([hi, lo])),
    ]
}

fn iword() -> impl Strategy<Value = i16> {
    nasty_word().prop_map(|w| w as i16)
}

fn u3() -> impl Strategy<Value = [u16; 3]> {
    prop::array::uniform3(nasty_word())
}

fn i3() -> impl Strategy<Value = [i16; 3]> {
    prop::array::uniform3(iword())
}

fn i4() -> impl Strategy<Value = [i16; 4]> {
    prop::array::uniform4(iword())
}

pub fn filter() -> impl Strategy<Value = Filter> {
    prop_oneof![Just(Filter::Stabilized), Just(Filter::Instantaneous)]
}

/// Any reply, every variant and field value reachable.
pub fn reply() -> impl Strategy<Value = Reply> {
    let t = nasty_word;
    prop_oneof![
        (u3(), u3(), u3(), t()).prop_map(|(mag, accel, rate, ticks)| Reply::RawSensorBits {
            mag,
            accel,
            rate,
            ticks
        }),
        (filter(), i3(), i3(), i3(), t()).prop_map(|(kind, mag, accel, rate, ticks)| {
            Reply::Vectors {
                kind,
                mag,
                accel,
                rate,
                ticks,
            }
        }),
        (filter(), i4(), t()).prop_map(|(kind, q, ticks)| Reply::Quaternion { kind, q, ticks }),
        t().prop_map(|ticks| Reply::CaptureGyroBias { ticks }),
        (t(), t()).prop_map(|(raw, ticks)| Reply::Temperature { raw, ticks }),
        (filter(), prop::array::uniform9(iword()), t())
            .prop_map(|(kind, m, ticks)| Reply::OrientationMatrix { kind, m, ticks }),
        (filter(), i4(), i3(), i3(), i3(), t()).prop_map(|(kind, q, mag, accel, rate, ticks)| {
            Reply::QuaternionVectors {
                kind,
                q,
                mag,
                accel,
                rate,
                ticks,
            }
        }),
        (filter(), i3(), t()).prop_map(|(kind, rpy, ticks)| Reply::Euler { kind, rpy, ticks }),
        (i3(), i3(), i3(), t()).prop_map(|(rpy, accel, rate, ticks)| Reply::EulerVectors {
            rpy,
            accel,
            rate,
            ticks
        }),
        (nasty_byte(), t()).prop_map(|(command, ticks)| Reply::Continuous { command, ticks }),
        t().prop_map(|ticks| Reply::Tare { ticks }),
        t().prop_map(|ticks| Reply::RemoveTare { ticks }),
        (t(), t()).prop_map(|(value, ticks)| Reply::EepromRead { value, ticks }),
        (t(), t()).prop_map(|(value, ticks)| Reply::EepromWrite { value, ticks }),
        t().prop_map(|version| Reply::FirmwareVersion { version }),
        t().prop_map(|serial| Reply::SerialNumber { serial }),
    ]
}

/// Any command, every variant and argument value reachable.
pub fn command() -> impl Strategy<Value = Command> {
    let simple: Vec<Command> = KNOWN_COMMAND_CODES
        .iter()
        .filter_map(|&c| Command::from_code(c))
        .collect();
    prop_oneof![
        prop::sample::select(simple),
        any::<u8>().prop_map(|command| Command::SetContinuous { command }),
        any::<u16>().prop_map(|address| Command::ReadEeprom { address }),
        (any::<u16>(), any::<u16>())
            .prop_map(|(address, value)| Command::WriteEeprom { address, value }),
    ]
}

/// Chunk sizes to cut a stream into; cycled until the stream is used up.
pub fn chunk_sizes() -> impl Strategy<Value = Vec<usize>> {
    prop::collection::vec(1usize..70, 1..12)
}

/// Splits `stream` into chunks of the given (cycled) sizes.
pub fn chunks<'a>(stream: &'a [u8], sizes: &'a [usize]) -> impl Iterator<Item = &'a [u8]> + 'a {
    let mut at = 0;
    let mut i = 0;
    std::iter::from_fn(move || {
        if at >= stream.len() {
            return None;
        }
        let n = sizes[i % sizes.len()].max(1).min(stream.len() - at);
        i += 1;
        let chunk = &stream[at..at + n];
        at += n;
        Some(chunk)
    })
}
