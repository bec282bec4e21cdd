//! Fuzz target: arbitrary bytes in arbitrary chunks through `MipDecoder`; checks that every byte
//! is reported exactly once, in order, that every packet event is a valid packet, and that the
//! typed decoders never panic on a valid packet.

#![no_main]

use imu_proto::mip::{ImuData, MipCommand, MipDecoder, MipEvent, MipReply, Packet};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // Layout of the input: [n_chunk_sizes, chunk sizes..., stream].
    let Some((&n_sizes, rest)) = data.split_first() else {
        return;
    };
    let n_sizes = usize::from(n_sizes % 8).min(rest.len());
    let (sizes, stream) = rest.split_at(n_sizes);

    let mut d = MipDecoder::new();
    let mut rebuilt = Vec::with_capacity(stream.len());
    let drain = |d: &mut MipDecoder, rebuilt: &mut Vec<u8>| {
        while let Some(ev) = d.next_event() {
            assert_eq!(ev.offset(), rebuilt.len() as u64, "events are contiguous");
            assert!(!ev.bytes().is_empty(), "no empty events");
            if let MipEvent::Packet { packet, .. } = &ev {
                assert_eq!(Packet::parse(packet.as_bytes()).as_ref(), Ok(packet));
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
            "conservation"
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
