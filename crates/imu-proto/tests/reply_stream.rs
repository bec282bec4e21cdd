//! Property tests of replies and the streaming reply decoder: round trips, recovery, conservation.

mod common;

use imu_proto::decoder::{DecodeEvent, RejectReason, ReplyDecoder};
use imu_proto::reply::KNOWN_REPLY_CODES;
use imu_proto::{FrameError, Reply};
use proptest::prelude::*;

/// Feeds `stream` in chunks, draining after each push and checking the conservation law at
/// every step; then flushes. Returns every event in order.
fn run(decoder: &mut ReplyDecoder, stream: &[u8], sizes: &[usize]) -> Vec<DecodeEvent> {
    let mut events = Vec::new();
    let mut out_bytes = 0u64;
    let mut drain = |d: &mut ReplyDecoder, events: &mut Vec<DecodeEvent>| {
        while let Some(ev) = d.next_event() {
            out_bytes += ev.bytes().len() as u64;
            events.push(ev);
        }
        let s = d.stats();
        assert_eq!(
            s.bytes_in,
            out_bytes + d.pending_len() as u64,
            "conservation"
        );
        assert_eq!(
            s.bytes_in,
            s.frame_bytes + s.rejected_bytes + d.pending_len() as u64
        );
    };
    for chunk in common::chunks(stream, sizes) {
        decoder.push(chunk);
        drain(decoder, &mut events);
    }
    decoder.flush();
    drain(decoder, &mut events);
    assert_eq!(decoder.pending_len(), 0, "flush reports everything");
    events
}

/// Events are contiguous, in order, non-empty, and their bytes are exactly the input stream.
fn assert_contiguous(events: &[DecodeEvent], stream: &[u8]) {
    let mut at = 0u64;
    let mut rebuilt = Vec::with_capacity(stream.len());
    for ev in events {
        assert_eq!(ev.offset(), at, "event offsets are contiguous: {ev:?}");
        assert!(!ev.bytes().is_empty(), "no empty events");
        at += ev.bytes().len() as u64;
        rebuilt.extend_from_slice(ev.bytes());
        if let DecodeEvent::Frame { reply, bytes, .. } = ev {
            assert_eq!(Reply::decode(bytes), Ok(*reply), "frame events decode");
            assert_eq!(&reply.to_bytes(), bytes, "frame events re-encode");
        }
    }
    assert_eq!(rebuilt, stream, "events rebuild the stream");
}

/// Every expected `(offset, reply)` appears as a `Frame` event at that offset, unless a false
/// frame (a `Frame` event that is not one of the expected frames: a 1-in-65536 checksum
/// coincidence in garbage or damaged bytes) overlaps it, which a 16-bit checksum cannot rule out.
fn assert_recovered(events: &[DecodeEvent], expected: &[(u64, Reply)]) {
    let frames: Vec<(u64, usize, Reply)> = events
        .iter()
        .filter_map(|e| match e {
            DecodeEvent::Frame {
                reply,
                bytes,
                offset,
            } => Some((*offset, bytes.len(), *reply)),
            DecodeEvent::Rejected { .. } => None,
        })
        .collect();
    let false_frames: Vec<&(u64, usize, Reply)> = frames
        .iter()
        .filter(|(o, _, r)| !expected.contains(&(*o, *r)))
        .collect();
    for (offset, reply) in expected {
        let found = frames.iter().any(|(o, _, r)| o == offset && r == reply);
        let end = offset + reply.encoded_len() as u64;
        let overlapped = false_frames
            .iter()
            .any(|(o, n, _)| *o < end && o + *n as u64 > *offset);
        assert!(
            found || overlapped,
            "frame at {offset} ({reply:?}) lost; events: {events:?}"
        );
    }
}

#[derive(Debug, Clone)]
enum Damage {
    /// XOR one byte (index taken modulo the frame length) with a non-zero mask.
    Flip(usize, u8),
    /// Keep only a prefix (length taken modulo the frame length): bytes lost on the line.
    Cut(usize),
}

#[derive(Debug, Clone)]
struct Item {
    garbage_before: Vec<u8>,
    reply: Reply,
    damage: Option<Damage>,
}

fn item() -> impl Strategy<Value = Item> {
    let damage = prop_oneof![
        3 => (any::<usize>(), 1u8..=255).prop_map(|(i, x)| Damage::Flip(i, x)),
        1 => any::<usize>().prop_map(Damage::Cut),
    ];
    (
        prop::option::weighted(0.2, prop::collection::vec(common::nasty_byte(), 1..40)),
        common::reply(),
        prop::option::weighted(0.15, damage),
    )
        .prop_map(|(garbage, reply, damage)| Item {
            garbage_before: garbage.unwrap_or_default(),
            reply,
            damage,
        })
}

/// Builds the stream; returns it with the `(offset, reply)` of every intact frame and how many
/// of those directly follow garbage or a damaged frame (the hard cases).
fn build(items: &[Item]) -> (Vec<u8>, Vec<(u64, Reply)>, usize) {
    let mut stream = Vec::new();
    let mut intact = Vec::new();
    let mut hard = 0;
    let mut previous_damaged = false;
    for item in items {
        stream.extend_from_slice(&item.garbage_before);
        let mut bytes = item.reply.to_bytes();
        match item.damage {
            Some(Damage::Flip(i, x)) => {
                let i = i % bytes.len();
                bytes[i] ^= x;
            }
            Some(Damage::Cut(n)) => bytes.truncate(n % bytes.len()),
            None => {
                intact.push((stream.len() as u64, item.reply));
                if previous_damaged || !item.garbage_before.is_empty() {
                    hard += 1;
                }
            }
        }
        previous_damaged = item.damage.is_some();
        stream.extend_from_slice(&bytes);
    }
    (stream, intact, hard)
}

fn count_rejected(events: &[DecodeEvent], want: RejectReason) -> u64 {
    events
        .iter()
        .filter(|e| matches!(e, DecodeEvent::Rejected { reason, .. } if *reason == want))
        .count() as u64
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn reply_round_trips(reply in common::reply()) {
        let bytes = reply.to_bytes();
        prop_assert_eq!(bytes.len(), reply.encoded_len());
        prop_assert_eq!(Some(bytes.len()), imu_proto::reply_len_for_code(reply.code()));
        prop_assert_eq!(bytes[0], reply.code());
        prop_assert_eq!(Reply::decode(&bytes), Ok(reply));
        // and through the streaming decoder, one byte at a time
        let mut d = ReplyDecoder::new();
        let events = run(&mut d, &bytes, &[1]);
        prop_assert_eq!(events.len(), 1);
        let is_frame = matches!(&events[0],
            DecodeEvent::Frame { reply: r, offset: 0, .. } if *r == reply);
        prop_assert!(is_frame);
    }

    #[test]
    fn any_single_bit_flip_is_detected(reply in common::reply(), bit in 0usize..(31 * 8)) {
        let mut bytes = reply.to_bytes();
        let bit = bit % (bytes.len() * 8);
        bytes[bit / 8] ^= 1 << (bit % 8);
        // A flipped header byte may turn into another code (wrong length or unknown) or into a
        // code of the same length, whose checksum then differs; anything else must be a
        // checksum failure.
        match Reply::decode(&bytes) {
            Err(FrameError::BadChecksum { .. }) => {}
            Err(FrameError::WrongLength { .. } | FrameError::UnknownCode(_)) => {
                prop_assert!(bit < 8)
            }
            other => prop_assert!(false, "flip at bit {} not caught: {:?}", bit, other),
        }
    }

    #[test]
    fn clean_stream_is_fully_recovered(
        replies in prop::collection::vec(common::reply(), 0..40),
        sizes in common::chunk_sizes(),
    ) {
        let stream: Vec<u8> = replies.iter().flat_map(Reply::to_bytes).collect();
        let mut d = ReplyDecoder::new();
        let events = run(&mut d, &stream, &sizes);
        assert_contiguous(&events, &stream);
        let decoded: Vec<Reply> = events
            .iter()
            .filter_map(|e| match e {
                DecodeEvent::Frame { reply, .. } => Some(*reply),
                DecodeEvent::Rejected { .. } => None,
            })
            .collect();
        prop_assert_eq!(&decoded, &replies);
        let s = d.stats();
        prop_assert_eq!(s.frames, replies.len() as u64);
        prop_assert_eq!(s.rejected_bytes, 0);
        prop_assert_eq!(s.resyncs, 0);
    }

    /// Garbage between frames, damaged frames, random chunking: every intact frame comes out,
    /// in order, at its offset (unless a false frame overlaps it, see `assert_recovered`),
    /// including the frames right after garbage or damage; every byte is accounted for once.
    #[test]
    fn damaged_stream_recovers_every_intact_frame(
        items in prop::collection::vec(item(), 1..40),
        sizes in common::chunk_sizes(),
    ) {
        let (stream, intact, _hard) = build(&items);
        let mut d = ReplyDecoder::new();
        let events = run(&mut d, &stream, &sizes);
        assert_contiguous(&events, &stream);
        assert_recovered(&events, &intact);

        // Stats agree with the events.
        let s = d.stats();
        let frames = events.iter().filter(|e| matches!(e, DecodeEvent::Frame { .. })).count();
        prop_assert_eq!(s.frames, frames as u64);
        prop_assert_eq!(s.checksum_failures, count_rejected(&events, RejectReason::BadChecksum));
        prop_assert_eq!(s.truncated_frames, count_rejected(&events, RejectReason::Truncated));
        prop_assert_eq!(s.malformed_frames, count_rejected(&events, RejectReason::Malformed));
        let garbage: u64 = events
            .iter()
            .filter_map(|e| match e {
                DecodeEvent::Rejected { reason: RejectReason::Garbage, bytes, .. } => {
                    Some(bytes.len() as u64)
                }
                _ => None,
            })
            .sum();
        prop_assert_eq!(s.garbage_bytes, garbage);
        if s.rejected_bytes == 0 {
            prop_assert_eq!(s.resyncs, 0);
        }
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_are_conserved(
        stream in prop::collection::vec(common::nasty_byte(), 0..600),
        sizes in common::chunk_sizes(),
        expected in prop::collection::vec(any::<u8>(), 0..4),
    ) {
        let mut d = ReplyDecoder::new();
        d.set_expected(&expected);
        let events = run(&mut d, &stream, &sizes);
        assert_contiguous(&events, &stream);
        // with a restricted set, no other header may start a frame
        let accepted: Vec<u8> = if expected.is_empty() {
            KNOWN_REPLY_CODES.to_vec()
        } else {
            expected.clone()
        };
        for ev in &events {
            if let DecodeEvent::Frame { bytes, .. } = ev {
                prop_assert!(accepted.contains(&bytes[0]));
            }
        }
    }

    #[test]
    fn flush_midway_then_continue(
        replies in prop::collection::vec(common::reply(), 1..10),
        cut in any::<usize>(),
    ) {
        // A flush in the middle of the stream reports the cut frame as rejected, and the
        // frames wholly before and wholly after the cut still decode.
        let stream: Vec<u8> = replies.iter().flat_map(Reply::to_bytes).collect();
        let cut = cut % stream.len();
        let mut d = ReplyDecoder::new();
        let mut events = Vec::new();
        d.push(&stream[..cut]);
        d.flush();
        events.extend(std::iter::from_fn(|| d.next_event()));
        prop_assert_eq!(d.pending_len(), 0);
        d.push(&stream[cut..]);
        d.flush();
        events.extend(std::iter::from_fn(|| d.next_event()));
        prop_assert_eq!(d.pending_len(), 0);
        assert_contiguous(&events, &stream);
        let mut expected = Vec::new();
        let mut start = 0usize;
        for r in &replies {
            let len = r.encoded_len();
            if start >= cut || start + len <= cut {
                expected.push((start as u64, *r));
            }
            start += len;
        }
        assert_recovered(&events, &expected);
    }
}

/// The decoder really meets the hard cases: a fixed-seed stream with garbage and damage
/// yields frames recovered right after them, and every kind of rejection.
#[test]
fn hard_cases_are_exercised() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    let mut runner = TestRunner::new_with_rng(
        Config::default(),
        TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]),
    );
    let items = prop::collection::vec(item(), 400..401)
        .new_tree(&mut runner)
        .expect("strategy")
        .current();
    let (stream, intact, hard) = build(&items);
    let mut d = ReplyDecoder::new();
    let events = run(&mut d, &stream, &[17, 1, 64, 3]);
    assert_contiguous(&events, &stream);
    assert_recovered(&events, &intact);
    assert!(
        hard > 50,
        "the stream has frames right after trouble: {hard}"
    );
    let s = d.stats();
    // at this seed no checksum coincidence happens: exactly the intact frames come out
    assert_eq!(s.frames as usize, intact.len(), "{s:?}");
    assert!(s.resyncs > 20, "{s:?}");
    assert!(
        s.checksum_failures > 0 && s.truncated_frames > 0 && s.garbage_bytes > 0,
        "{s:?}"
    );
}
