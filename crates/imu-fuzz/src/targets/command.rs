//! `CommandDecoder`: the events, re-encoded, are exactly the input, and the counters agree.

use imu_proto::decoder::{CommandDecoder, CommandEvent};

use super::{push_in_chunks, split_chunk_sizes};

/// Input: `[n_chunk_sizes, chunk sizes..., stream]`.
pub(crate) fn command_decoder(data: &[u8]) {
    let Some((sizes, stream)) = split_chunk_sizes(data) else {
        return;
    };
    let mut d = CommandDecoder::new();
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

fn drain(d: &mut CommandDecoder, rebuilt: &mut Vec<u8>) {
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
        "conservation: bytes in = bytes reported + pending"
    );
    assert_eq!(
        s.bytes_in,
        s.command_bytes + s.rejected_bytes + d.pending_len() as u64,
        "conservation: bytes in = command + rejected + pending"
    );
}
