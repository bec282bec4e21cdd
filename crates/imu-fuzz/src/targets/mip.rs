//! `MipDecoder` (MIP packets, both sides): every byte reported exactly once, in order; every
//! packet event a valid packet; the typed decoders never panic on a valid packet.

use imu_proto::mip::{ImuData, MipCommand, MipDecoder, MipEvent, MipReply, Packet};

use super::{assert_contiguous, check_stream, split_chunk_sizes, stream};
use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "mip_decoder",
    about: "MIP packets, both sides (imu_proto::mip::MipDecoder)",
    check,
    seeds: Some(crate::seeds::mip_decoder),
    dictionary: &[
        &[0x75, 0x65],
        &[0x75, 0x65, 0x80],
        &[0x75, 0x65, 0x01],
        &[0x75, 0x65, 0x0C],
        &[0x75],
        &[0x80],
        &[0xFF],
        &[0x00],
        &[0x0E, 0x04],
        &[0x06, 0xD3],
        &[0xF1],
    ],
    ci_mutations: 1_000_000,
};

/// Input: `[n_chunk_sizes, chunk sizes..., stream]`.
fn check(data: &[u8]) {
    if let Some((sizes, stream)) = split_chunk_sizes(data) {
        check_stream(MipDecoder::new(), sizes, stream);
    }
}

stream!(MipDecoder, MipEvent, frame_bytes, account);

/// Checks one event and appends its bytes to `rebuilt`.
fn account(ev: MipEvent, rebuilt: &mut Vec<u8>) {
    assert_contiguous(ev.offset(), ev.bytes(), rebuilt);
    if let MipEvent::Packet { packet, .. } = &ev {
        assert_eq!(
            Packet::parse(packet.as_bytes()).as_ref(),
            Ok(packet),
            "a packet event is a valid packet"
        );
        let _ = ImuData::decode_packet(packet);
        let _ = MipReply::decode_packet(packet);
        MipCommand::decode_packet(packet).for_each(drop);
    }
    rebuilt.extend_from_slice(ev.bytes());
}
