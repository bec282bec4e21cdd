//! `ReplyDecoder` (3DM-GX1 replies, host side): every byte reported exactly once, in order;
//! every frame event a valid frame.

use imu_proto::decoder::{DecodeEvent, ReplyDecoder};
use imu_proto::reply::Reply;

use super::{assert_contiguous, check_stream, split_chunk_sizes, stream};
use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "reply_decoder",
    about: "3DM-GX1 replies, host side (imu_proto::decoder::ReplyDecoder)",
    check,
    seeds: Some(crate::seeds::reply_decoder),
    dictionary: super::command::GX1_DICTIONARY,
    ci_mutations: 1_000_000,
};

/// Input: `[n_chunk_sizes, chunk sizes..., n_expected, expected reply codes..., stream]`.
fn check(data: &[u8]) {
    let Some((sizes, rest)) = split_chunk_sizes(data) else {
        return;
    };
    let Some((&n_expected, rest)) = rest.split_first() else {
        return;
    };
    let n_expected = usize::from(n_expected % 4).min(rest.len());
    let (expected, stream) = rest.split_at(n_expected);
    let mut d = ReplyDecoder::new();
    d.set_expected(expected);
    check_stream(d, sizes, stream);
}

stream!(ReplyDecoder, DecodeEvent, frame_bytes, account);

/// Checks one event and appends its bytes to `rebuilt`.
fn account(ev: DecodeEvent, rebuilt: &mut Vec<u8>) {
    assert_contiguous(ev.offset(), ev.bytes(), rebuilt);
    if let DecodeEvent::Frame { reply, bytes, .. } = &ev {
        assert_eq!(
            Reply::decode(bytes).as_ref(),
            Ok(reply),
            "a frame event is a valid frame"
        );
    }
    rebuilt.extend_from_slice(ev.bytes());
}
