//! Fuzz target: arbitrary bytes in arbitrary chunks through `CommandDecoder`; checks that the
//! events, re-encoded, are exactly the input and that the counters agree.

#![no_main]

use imu_proto::decoder::{CommandDecoder, CommandEvent};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // Layout of the input: [n_chunk_sizes, chunk sizes..., stream].
    let Some((&n_sizes, rest)) = data.split_first() else {
        return;
    };
    let n_sizes = usize::from(n_sizes % 8).min(rest.len());
    let (sizes, stream) = rest.split_at(n_sizes);

    let mut d = CommandDecoder::new();
    let mut rebuilt = Vec::with_capacity(stream.len());
    let drain = |d: &mut CommandDecoder, rebuilt: &mut Vec<u8>| {
        while let Some(ev) = d.next_event() {
            match ev {
                CommandEvent::Command(c) => c.encode(rebuilt),
                CommandEvent::Rejected { bytes, offset, .. } => {
                    assert_eq!(offset, rebuilt.len() as u64, "events are contiguous");
                    assert!(!bytes.is_empty(), "no empty events");
                    rebuilt.extend_from_slice(&bytes);
                }
            }
        }
        let s = d.stats();
        assert_eq!(
            s.bytes_in,
            rebuilt.len() as u64 + d.pending_len() as u64,
            "conservation"
        );
        assert_eq!(
            s.bytes_in,
            s.command_bytes + s.rejected_bytes + d.pending_len() as u64
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
