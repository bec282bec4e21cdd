//! `CommandDecoder` (3DM-GX1 commands, device side): the events, re-encoded, are exactly the
//! input, and the counters agree.

use imu_proto::decoder::{CommandDecoder, CommandEvent};

use super::{assert_contiguous, check_stream, split_chunk_sizes, stream};
use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "command_decoder",
    about: "3DM-GX1 commands, device side (imu_proto::decoder::CommandDecoder)",
    check,
    seeds: Some(crate::seeds::command_decoder),
    dictionary: GX1_DICTIONARY,
    ci_mutations: 1_000_000,
};

/// Bytes that mean something to the 3DM-GX1 decoders: reply/command codes and their argument
/// bytes, and edge values of words.
pub(crate) const GX1_DICTIONARY: &[&[u8]] = &[
    &[0x01],
    &[0x02],
    &[0x03],
    &[0x0C],
    &[0x10, 0x00],
    &[0x0F, 0xC1, 0xC3, 0xC5],
    &[0x28, 0x00, 0xE6],
    &[0x29, 0x71],
    &[0x31],
    &[0xF0],
    &[0xF1],
    &[0xFF, 0xFF],
    &[0x00, 0x00],
    &[0x80, 0x00],
];

/// Input: `[n_chunk_sizes, chunk sizes..., stream]`.
fn check(data: &[u8]) {
    if let Some((sizes, stream)) = split_chunk_sizes(data) {
        check_stream(CommandDecoder::new(), sizes, stream);
    }
}

stream!(CommandDecoder, CommandEvent, command_bytes, account);

/// Checks one event and appends its bytes to `rebuilt`.
fn account(ev: CommandEvent, rebuilt: &mut Vec<u8>) {
    match ev {
        CommandEvent::Command(c) => c.encode(rebuilt),
        CommandEvent::Rejected { bytes, offset, .. } => {
            assert_contiguous(offset, &bytes, rebuilt);
            rebuilt.extend_from_slice(&bytes);
        }
    }
}
