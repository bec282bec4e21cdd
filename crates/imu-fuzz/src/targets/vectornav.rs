//! `VnDecoder` (VectorNav ASCII sentences and binary messages on one port): every byte reported
//! exactly once, in order; every binary or ASCII event a valid message or sentence; the typed
//! decoders never panic on one.

use imu_proto::vectornav::{BinaryMessage, Sentence, VnCommand, VnDecoder, VnEvent, VnReply};

use super::{assert_contiguous, check_stream, split_chunk_sizes, stream};
use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "vectornav_decoder",
    about: "VectorNav ASCII sentences and binary messages (imu_proto::vectornav::VnDecoder)",
    check,
    seeds: Some(crate::seeds::vectornav_decoder),
    dictionary: &[
        &[0xFA],
        &[0xFA, 0x01],
        &[0xFA, 0x07],
        &[0xFA, 0x80],
        &[0xFF, 0x87],
        b"$VN",
        b"$VNRRG,",
        b"$VNWRG,75,",
        b"$VNERR,",
        b"*XX\r\n",
        b"*",
        b"\r\n",
        b",",
        &[0x00],
    ],
    ci_mutations: 1_000_000,
};

/// Input: `[n_chunk_sizes, chunk sizes..., stream]`.
fn check(data: &[u8]) {
    if let Some((sizes, stream)) = split_chunk_sizes(data) {
        check_stream(VnDecoder::new(), sizes, stream);
    }
}

stream!(VnDecoder, VnEvent, frame_bytes, account);

/// Checks one event and appends its bytes to `rebuilt`.
fn account(ev: VnEvent, rebuilt: &mut Vec<u8>) {
    assert_contiguous(ev.offset(), ev.bytes(), rebuilt);
    match &ev {
        VnEvent::Binary { message, .. } => {
            // Compared through `Debug`: a device may send NaN in a float field (the decoder
            // passes it on as sent), and NaN != NaN would fail an equal message.
            let reparsed = BinaryMessage::parse(message.as_bytes());
            assert_eq!(
                format!("{:?}", reparsed.as_ref()),
                format!("{:?}", Ok::<_, ()>(message)),
                "a binary event is a valid message"
            );
        }
        VnEvent::Ascii { sentence, .. } => {
            assert_eq!(
                Sentence::parse(sentence.as_bytes()).as_ref(),
                Ok(sentence),
                "an ASCII event is a valid sentence"
            );
            let _ = VnReply::decode(sentence);
            let _ = VnCommand::decode(sentence);
        }
        VnEvent::Rejected { .. } => {}
    }
    rebuilt.extend_from_slice(ev.bytes());
}
