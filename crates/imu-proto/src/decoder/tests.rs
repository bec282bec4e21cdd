//! Tests of both decoders: framing, resynchronisation after garbage and the byte accounting.

use super::*;
use crate::reply::Filter;

#[test]
fn expired_partial_command_releases_the_command_inside_it() {
    let mut d = CommandDecoder::new();
    // A stray 0x29 (write EEPROM, 7 bytes) followed by a real poll 0x01.
    d.push(&[0x29, 0x71, 0x00, 0x01]);
    assert_eq!(
        d.next_event(),
        None,
        "waits for the rest of the 0x29 command"
    );
    assert!(matches!(
        d.expire_partial(),
        Some(CommandEvent::Rejected { reason: CommandRejectReason::Truncated, ref bytes, .. }) if bytes == &[0x29]
    ));
    // 0x71 and 0x00 are unknown codes, then the poll is decoded.
    let events: Vec<_> = std::iter::from_fn(|| d.next_event()).collect();
    assert_eq!(
        events.last(),
        Some(&CommandEvent::Command(Command::RawSensorBits))
    );
    assert_eq!(d.expire_partial(), None);
    assert_eq!(d.stats().truncated_commands, 1);
}

fn drain(d: &mut ReplyDecoder) -> Vec<DecodeEvent> {
    std::iter::from_fn(|| d.next_event()).collect()
}

fn temp(raw: u16, ticks: u16) -> Reply {
    Reply::Temperature { raw, ticks }
}

fn euler(ticks: u16) -> Reply {
    Reply::Euler {
        kind: Filter::Stabilized,
        rpy: [0x0E0E, 0x0D0D, 0x0101],
        ticks,
    }
}

fn kinds(events: &[DecodeEvent]) -> Vec<(u64, usize, Option<RejectReason>)> {
    events
        .iter()
        .map(|e| match e {
            DecodeEvent::Frame { offset, bytes, .. } => (*offset, bytes.len(), None),
            DecodeEvent::Rejected {
                offset,
                bytes,
                reason,
            } => (*offset, bytes.len(), Some(*reason)),
        })
        .collect()
}

#[test]
fn clean_stream_byte_by_byte() {
    let replies = [temp(1, 2), euler(3), temp(0xFFFF, 0x0707)];
    let stream: Vec<u8> = replies.iter().flat_map(Reply::to_bytes).collect();
    let mut d = ReplyDecoder::new();
    let mut got = Vec::new();
    for b in &stream {
        d.push(std::slice::from_ref(b));
        got.extend(drain(&mut d));
    }
    let decoded: Vec<Reply> = got
        .iter()
        .map(|e| match e {
            DecodeEvent::Frame { reply, .. } => *reply,
            other => panic!("unexpected {other:?}"),
        })
        .collect();
    assert_eq!(decoded, replies);
    let s = d.stats();
    assert_eq!((s.frames, s.resyncs, s.rejected_bytes), (3, 0, 0));
    assert_eq!(s.bytes_in, stream.len() as u64);
    assert_eq!(d.pending_len(), 0);
}

#[test]
fn garbage_then_frame_is_one_run_and_one_resync() {
    let mut d = ReplyDecoder::new();
    d.push(&[0x00, 0x55, 0xAA]);
    d.push(&temp(5, 6).to_bytes());
    let ev = drain(&mut d);
    assert_eq!(
        kinds(&ev),
        vec![(0, 3, Some(RejectReason::Garbage)), (3, 7, None)]
    );
    assert_eq!(d.stats().garbage_bytes, 3);
    assert_eq!(d.stats().resyncs, 1);
}

#[test]
fn garbage_is_held_until_sync_or_flush() {
    let mut d = ReplyDecoder::new();
    d.push(&[0x00, 0x55]);
    assert_eq!(d.next_event(), None);
    assert_eq!(d.pending_len(), 2);
    d.push(&[0xAA]);
    assert_eq!(d.next_event(), None);
    d.flush();
    assert_eq!(
        d.next_event(),
        Some(DecodeEvent::Rejected {
            bytes: vec![0x00, 0x55, 0xAA],
            offset: 0,
            reason: RejectReason::Garbage
        })
    );
    assert_eq!(d.next_event(), None);
    assert_eq!(d.pending_len(), 0);
}

#[test]
fn truncated_frame_before_good_frame() {
    // An euler frame (11 bytes) loses its last 4 bytes on the line; the next frame is intact.
    let mut stream = euler(1).to_bytes();
    stream.truncate(7);
    let good = temp(0x1234, 0x42).to_bytes();
    stream.extend_from_slice(&good);
    let mut d = ReplyDecoder::new();
    d.push(&stream);
    // Header-like bytes inside the cut frame start candidates longer than what follows,
    // so without an end of stream the decoder waits for more bytes instead of guessing.
    assert_eq!(d.next_event(), None);
    d.flush();
    let ev = drain(&mut d);
    assert_eq!(
        kinds(&ev),
        vec![(0, 7, Some(RejectReason::Truncated)), (7, 7, None)]
    );
    assert_eq!(d.stats().truncated_frames, 1);
    assert_eq!(d.stats().checksum_failures, 0);
    assert_eq!(d.stats().resyncs, 1);
}

#[test]
fn corrupted_frame_is_bad_checksum_and_next_frame_survives() {
    let mut stream = euler(1).to_bytes();
    stream[4] ^= 0x40;
    stream.extend_from_slice(&euler(2).to_bytes());
    let mut d = ReplyDecoder::new();
    d.push(&stream);
    d.flush();
    let ev = drain(&mut d);
    assert_eq!(
        kinds(&ev),
        vec![(0, 11, Some(RejectReason::BadChecksum)), (11, 11, None)]
    );
    assert_eq!(d.stats().checksum_failures, 1);
}

#[test]
fn waits_for_lookahead_before_calling_truncation() {
    // A failed candidate with a header-like byte inside whose own frame is not complete yet:
    // the decoder must wait rather than guess.
    let mut stream = euler(1).to_bytes();
    stream[10] ^= 1; // bad checksum
    stream[8] = 0x06; // a 5-byte candidate starting at 8 needs 13 bytes buffered
    let mut d = ReplyDecoder::new();
    d.push(&stream);
    assert_eq!(d.next_event(), None);
    d.flush();
    let ev = drain(&mut d);
    assert_eq!(kinds(&ev), vec![(0, 11, Some(RejectReason::BadChecksum))]);
}

#[test]
fn flush_reports_partial_frame_as_truncated() {
    let bytes = euler(9).to_bytes();
    let mut d = ReplyDecoder::new();
    d.push(&bytes[..6]);
    assert_eq!(d.next_event(), None);
    d.flush();
    let ev = drain(&mut d);
    assert_eq!(kinds(&ev), vec![(0, 6, Some(RejectReason::Truncated))]);
    // decoding continues after a flush
    d.push(&bytes);
    let ev = drain(&mut d);
    assert_eq!(kinds(&ev), vec![(6, 11, None)]);
}

#[test]
fn expected_codes_restrict_frame_starts() {
    let mut d = ReplyDecoder::new();
    d.set_expected(&[0x07]);
    let mut stream = euler(1).to_bytes();
    stream.extend_from_slice(&temp(1, 1).to_bytes());
    d.push(&stream);
    let ev = drain(&mut d);
    assert_eq!(
        kinds(&ev),
        vec![(0, 11, Some(RejectReason::Garbage)), (11, 7, None)]
    );
}

#[test]
fn malformed_continuous_reply() {
    // 10 01 02 00 00 | checksum 0x10 + 0x0102 + 0x0000 = 0x0112
    let mut d = ReplyDecoder::new();
    d.push(&[0x10, 0x01, 0x02, 0x00, 0x00, 0x01, 0x12]);
    d.flush();
    let ev = drain(&mut d);
    assert_eq!(kinds(&ev), vec![(0, 7, Some(RejectReason::Malformed))]);
    assert_eq!(d.stats().malformed_frames, 1);
}

#[test]
fn long_garbage_is_split_and_memory_stays_bounded() {
    let mut d = ReplyDecoder::new();
    let junk = vec![0x00u8; 10 * MAX_GARBAGE_RUN + 5];
    for chunk in junk.chunks(333) {
        d.push(chunk);
        for ev in drain(&mut d) {
            assert!(ev.bytes().len() <= MAX_GARBAGE_RUN);
        }
        assert!(d.pending_len() <= MAX_GARBAGE_RUN + 333);
        assert!(d.sb.buf.capacity() <= 4 * (MAX_GARBAGE_RUN + 333));
    }
    d.flush();
    drain(&mut d);
    assert_eq!(d.stats().garbage_bytes, junk.len() as u64);
}

fn drain_cmd(d: &mut CommandDecoder) -> Vec<CommandEvent> {
    std::iter::from_fn(|| d.next_event()).collect()
}

#[test]
fn command_bad_key_rejects_only_the_code() {
    let mut d = CommandDecoder::new();
    // 0F C1 01: bad tare key; 01 is then a raw-sensor-bits command.
    d.push(&[0x0F, 0xC1, 0x01]);
    let ev = drain_cmd(&mut d);
    assert_eq!(
        ev,
        vec![
            CommandEvent::Rejected {
                bytes: vec![0x0F],
                offset: 0,
                reason: CommandRejectReason::BadArgument
            },
            CommandEvent::Rejected {
                bytes: vec![0xC1],
                offset: 1,
                reason: CommandRejectReason::UnknownCode
            },
            CommandEvent::Command(Command::RawSensorBits),
        ]
    );
    assert_eq!(d.stats().bad_arguments, 1);
    assert_eq!(d.stats().unknown_bytes, 1);
}

#[test]
fn command_partial_waits_then_truncates_on_flush() {
    let mut d = CommandDecoder::new();
    d.push(&[0x29, 0x71, 0x00]);
    assert_eq!(d.next_event(), None);
    d.push(&[0x82, 0x27, 0x10, 0xAA]);
    assert_eq!(
        d.next_event(),
        Some(CommandEvent::Command(Command::WriteEeprom {
            address: 130,
            value: 10_000
        }))
    );
    d.push(&[0x28, 0x00]);
    d.flush();
    assert_eq!(
        d.next_event(),
        Some(CommandEvent::Rejected {
            bytes: vec![0x28, 0x00],
            offset: 7,
            reason: CommandRejectReason::Truncated
        })
    );
    assert_eq!(d.next_event(), None);
    assert_eq!(d.stats().truncated_commands, 1);
    assert_eq!(d.stats().command_bytes, 7);
}
