//! `MipDecoder`: every byte reported exactly once, in order; every packet event a valid packet;
//! the typed decoders never panic on a valid packet.

use imu_proto::mip::{ImuData, MipCommand, MipDecoder, MipEvent, MipReply, Packet};

use super::{push_in_chunks, split_chunk_sizes};

/// Input: `[n_chunk_sizes, chunk sizes..., stream]`.
pub(crate) fn mip_decoder(data: &[u8]) {
    let Some((sizes, stream)) = split_chunk_sizes(data) else {
        return;
    };
    let mut d = MipDecoder::new();
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

fn drain(d: &mut MipDecoder, rebuilt: &mut Vec<u8>) {
    while let Some(ev) = d.next_event() {
        assert_eq!(ev.offset(), rebuilt.len() as u64, "events are contiguous");
        assert!(!ev.bytes().is_empty(), "no empty events");
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
    let s = d.stats();
    assert_eq!(
        s.bytes_in,
        s.frame_bytes + s.rejected_bytes + d.pending_len() as u64,
        "conservation: bytes in = frame + rejected + pending"
    );
}
