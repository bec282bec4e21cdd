//! Fuzz target: arbitrary bytes in arbitrary chunks through `ReplyDecoder`; checks that every
//! byte is reported exactly once, in order, and that every frame event is a valid frame.

#![no_main]

use imu_proto::decoder::{DecodeEvent, ReplyDecoder};
use imu_proto::reply::Reply;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // Layout of the input: [n_chunk_sizes, chunk sizes..., n_expected, expected codes..., stream].
    let Some((&n_sizes, rest)) = data.split_first() else {
        return;
    };
    let n_sizes = usize::from(n_sizes % 8).min(rest.len());
    let (sizes, rest) = rest.split_at(n_sizes);
    let Some((&n_expected, rest)) = rest.split_first() else {
        return;
    };
    let n_expected = usize::from(n_expected % 4).min(rest.len());
    let (expected, stream) = rest.split_at(n_expected);

    let mut d = ReplyDecoder::new();
    d.set_expected(expected);
    let mut rebuilt = Vec::with_capacity(stream.len());
    let drain = |d: &mut ReplyDecoder, rebuilt: &mut Vec<u8>| {
        while let Some(ev) = d.next_event() {
            assert_eq!(ev.offset(), rebuilt.len() as u64, "events are contiguous");
            assert!(!ev.bytes().is_empty(), "no empty events");
            if let DecodeEvent::Frame { reply, bytes, .. } = &ev {
                assert_eq!(Reply::decode(bytes).as_ref(), Ok(reply));
            }
            rebuilt.extend_from_slice(ev.bytes());
        }
        let s = d.stats();
        assert_eq!(
            s.bytes_in,
            rebuilt.len() as u64 + d.pending_len() as u64,
            "conservation"
        );
        assert_eq!(
            s.bytes_in,
            s.frame_bytes + s.rejected_bytes + d.pending_len() as u64
        );
    };

    let mut at = 0;
    let mut i = 0;
    while at < stream.len() {
        let size = sizes
            .get(i % sizes.len().max(1))
            .map_or(stream.len(), |&s| usize::from(s).max(1));
        let end = (at + size).min(stream.len());
        d.push(&stream[at..end]);
        drain(&mut d, &mut rebuilt);
        at = end;
        i += 1;
    }
    d.flush();
    drain(&mut d, &mut rebuilt);
    assert_eq!(d.pending_len(), 0, "flush reports everything");
    assert_eq!(rebuilt, stream, "events rebuild the stream");
});
