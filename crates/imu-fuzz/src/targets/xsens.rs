//! `XsensDecoder`: every byte reported exactly once, in order; every message event a valid
//! message; the typed decoders never panic on a valid message.

use imu_proto::xsens::{Message, MtData2, XsensCommand, XsensDecoder, XsensEvent, XsensReply};

use super::{push_in_chunks, split_chunk_sizes};

/// Input: `[n_chunk_sizes, chunk sizes..., stream]`.
pub(crate) fn xsens_decoder(data: &[u8]) {
    let Some((sizes, stream)) = split_chunk_sizes(data) else {
        return;
    };
    let mut d = XsensDecoder::new();
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

fn drain(d: &mut XsensDecoder, rebuilt: &mut Vec<u8>) {
    while let Some(ev) = d.next_event() {
        assert_eq!(ev.offset(), rebuilt.len() as u64, "events are contiguous");
        assert!(!ev.bytes().is_empty(), "no empty events");
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
    let s = d.stats();
    assert_eq!(
        s.bytes_in,
        s.frame_bytes + s.rejected_bytes + d.pending_len() as u64,
        "conservation: bytes in = frame + rejected + pending"
    );
}
