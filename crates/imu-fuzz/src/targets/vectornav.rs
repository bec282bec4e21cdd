//! `VnDecoder`: every byte reported exactly once, in order; every binary or ASCII event a valid
//! message or sentence; the typed decoders never panic on one.

use imu_proto::vectornav::{BinaryMessage, Sentence, VnCommand, VnDecoder, VnEvent, VnReply};

use super::{push_in_chunks, split_chunk_sizes};

/// Input: `[n_chunk_sizes, chunk sizes..., stream]`.
pub(crate) fn vectornav_decoder(data: &[u8]) {
    let Some((sizes, stream)) = split_chunk_sizes(data) else {
        return;
    };
    let mut d = VnDecoder::new();
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

fn drain(d: &mut VnDecoder, rebuilt: &mut Vec<u8>) {
    while let Some(ev) = d.next_event() {
        assert_eq!(ev.offset(), rebuilt.len() as u64, "events are contiguous");
        assert!(!ev.bytes().is_empty(), "no empty events");
        match &ev {
            VnEvent::Binary { message, .. } => {
                let again = BinaryMessage::parse(message.as_bytes());
                assert_eq!(
                    again.as_ref(),
                    Ok(message),
                    "a binary event is a valid message"
                );
            }
            VnEvent::Ascii { sentence, .. } => {
                let again = Sentence::parse(sentence.as_bytes());
                assert_eq!(
                    again.as_ref(),
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
    let s = d.stats();
    assert_eq!(
        s.bytes_in,
        s.frame_bytes + s.rejected_bytes + d.pending_len() as u64,
        "conservation: bytes in = frame + rejected + pending"
    );
}
