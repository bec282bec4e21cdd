//! `XsensDecoder` (Xsens Xbus messages, both sides): every byte reported exactly once, in
//! order; every message event a valid message; the typed decoders never panic on a valid one.

use imu_proto::xsens::{Message, MtData2, XsensCommand, XsensDecoder, XsensEvent, XsensReply};

use super::{assert_contiguous, check_stream, split_chunk_sizes, stream};
use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "xsens_decoder",
    about: "Xsens Xbus messages, both sides (imu_proto::xsens::XsensDecoder)",
    check,
    seeds: Some(crate::seeds::xsens_decoder),
    dictionary: &[
        &[0xFA, 0xFF],
        &[0xFA, 0xFF, 0x36],
        &[0xFA, 0xFF, 0x36, 0xFF],
        &[0xFA, 0xFF, 0xC1],
        &[0xFA],
        &[0xFF],
        &[0x00],
        &[0x10, 0x60, 0x04],
        &[0x40, 0x42, 0x0C],
        &[0x10, 0x10, 0x0C],
    ],
    ci_mutations: 1_000_000,
};

/// Input: `[n_chunk_sizes, chunk sizes..., stream]`.
fn check(data: &[u8]) {
    if let Some((sizes, stream)) = split_chunk_sizes(data) {
        check_stream(XsensDecoder::new(), sizes, stream);
    }
}

stream!(XsensDecoder, XsensEvent, frame_bytes, account);

/// Checks one event and appends its bytes to `rebuilt`.
fn account(ev: XsensEvent, rebuilt: &mut Vec<u8>) {
    assert_contiguous(ev.offset(), ev.bytes(), rebuilt);
    if let XsensEvent::Packet { packet, .. } = &ev {
        assert_eq!(
            Message::parse(packet.as_bytes()).as_ref(),
            Ok(packet),
            "a message event is a valid message"
        );
        let _ = MtData2::decode(packet);
        let _ = XsensReply::decode(packet);
        let _ = XsensCommand::decode(packet);
    }
    rebuilt.extend_from_slice(ev.bytes());
}
