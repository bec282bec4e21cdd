//! `ReplyDecoder`: every byte reported exactly once, in order; every frame event a valid frame.

use imu_proto::decoder::{DecodeEvent, ReplyDecoder};
use imu_proto::reply::Reply;

use super::{push_in_chunks, split_chunk_sizes};

/// Input: `[n_chunk_sizes, chunk sizes..., n_expected, expected reply codes..., stream]`.
pub(crate) fn reply_decoder(data: &[u8]) {
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
    let mut rebuilt = Vec::with_capacity(stream.len());
    push_in_chunks(stream, sizes, |chunk| {
        d.push(chunk);
        drain(&mut d, &mut rebuilt);
    });
    d.flush();
    drain(&mut d, &mut rebuilt);
    assert_eq!(d.pending_len(), 0, "flush reports everything");
    assert_eq!(rebuilt, stream, "events rebuild the stream");
}

fn drain(d: &mut ReplyDecoder, rebuilt: &mut Vec<u8>) {
    while let Some(ev) = d.next_event() {
        assert_eq!(ev.offset(), rebuilt.len() as u64, "events are contiguous");
        assert!(!ev.bytes().is_empty(), "no empty events");
        if let DecodeEvent::Frame { reply, bytes, .. } = &ev {
            assert_eq!(
                Reply::decode(bytes).as_ref(),
                Ok(reply),
                "a frame event is a valid frame"
            );
        }
        rebuilt.extend_from_slice(ev.bytes());
    }
    let s = d.stats();
    assert_eq!(
        s.bytes_in,
        rebuilt.len() as u64 + d.pending_len() as u64,
        "conservation: bytes in = bytes reported + pending"
    );
    assert_eq!(
        s.bytes_in,
        s.frame_bytes + s.rejected_bytes + d.pending_len() as u64,
        "conservation: bytes in = frame + rejected + pending"
    );
}
