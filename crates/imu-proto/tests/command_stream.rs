//! Property tests of commands and the device-side streaming command decoder.

mod common;

use imu_proto::Command;
use imu_proto::decoder::{CommandDecoder, CommandEvent, CommandRejectReason};
use proptest::prelude::*;

/// Feeds `stream` in chunks, draining and checking conservation after each push; then flushes.
fn run(d: &mut CommandDecoder, stream: &[u8], sizes: &[usize]) -> Vec<CommandEvent> {
    let mut events = Vec::new();
    let mut out_bytes = 0u64;
    let mut drain = |d: &mut CommandDecoder, events: &mut Vec<CommandEvent>| {
        while let Some(ev) = d.next_event() {
            out_bytes += match &ev {
                CommandEvent::Command(c) => c.encoded_len(),
                CommandEvent::Rejected { bytes, .. } => bytes.len(),
            } as u64;
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
            s.command_bytes + s.rejected_bytes + d.pending_len() as u64
        );
    };
    for chunk in common::chunks(stream, sizes) {
        d.push(chunk);
        drain(d, &mut events);
    }
    d.flush();
    drain(d, &mut events);
    assert_eq!(d.pending_len(), 0);
    events
}

/// The events, re-encoded, are exactly the input stream, and rejected offsets line up.
fn assert_rebuilds(events: &[CommandEvent], stream: &[u8]) {
    let mut rebuilt = Vec::new();
    for ev in events {
        match ev {
            CommandEvent::Command(c) => c.encode(&mut rebuilt),
            CommandEvent::Rejected { bytes, offset, .. } => {
                assert_eq!(*offset, rebuilt.len() as u64, "{ev:?}");
                assert!(!bytes.is_empty());
                rebuilt.extend_from_slice(bytes);
            }
        }
    }
    assert_eq!(rebuilt, stream);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn command_round_trips(cmd in common::command()) {
        let bytes = cmd.to_bytes();
        prop_assert_eq!(bytes.len(), cmd.encoded_len());
        prop_assert_eq!(Command::decode(&bytes), Ok(cmd));
        let mut d = CommandDecoder::new();
        let events = run(&mut d, &bytes, &[1]);
        prop_assert_eq!(events, vec![CommandEvent::Command(cmd)]);
        prop_assert_eq!(d.stats().commands, 1);
    }

    #[test]
    fn command_stream_is_fully_recovered(
        cmds in prop::collection::vec(common::command(), 0..50),
        sizes in common::chunk_sizes(),
    ) {
        let stream: Vec<u8> = cmds.iter().flat_map(Command::to_bytes).collect();
        let mut d = CommandDecoder::new();
        let events = run(&mut d, &stream, &sizes);
        let expected: Vec<CommandEvent> = cmds.iter().copied().map(CommandEvent::Command).collect();
        prop_assert_eq!(events, expected);
        prop_assert_eq!(d.stats().rejected_bytes, 0);
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_are_conserved(
        stream in prop::collection::vec(
            prop_oneof![any::<u8>(), Just(0xC1u8), Just(0x71), Just(0xAA), Just(0x10), Just(0x29)],
            0..600),
        sizes in common::chunk_sizes(),
    ) {
        let mut d = CommandDecoder::new();
        let events = run(&mut d, &stream, &sizes);
        assert_rebuilds(&events, &stream);
        let s = d.stats();
        let n_bad = events.iter().filter(|e| matches!(e,
            CommandEvent::Rejected { reason: CommandRejectReason::BadArgument, bytes, .. }
                if bytes.len() == 1)).count() as u64;
        prop_assert_eq!(s.bad_arguments, n_bad);
        prop_assert!(s.truncated_commands <= 1, "only the tail can be cut");
    }

    #[test]
    fn bad_keys_lose_only_the_code_byte(
        cmds in prop::collection::vec(common::command(), 1..20),
        which in any::<usize>(),
    ) {
        // Break the key of one tare/write command (if any): that code byte is rejected; the
        // commands before it all come out unchanged.
        let mut stream = Vec::new();
        let mut broken_at = None;
        for (i, c) in cmds.iter().enumerate() {
            let start = stream.len();
            c.encode(&mut stream);
            if broken_at.is_none() && matches!(c, Command::Tare | Command::RemoveTare
                | Command::WriteEeprom { .. } | Command::SetContinuous { .. }) && i >= which % cmds.len() {
                stream[start + 1] ^= 0x01;
                broken_at = Some(i);
            }
        }
        let mut d = CommandDecoder::new();
        let events = run(&mut d, &stream, &[5]);
        assert_rebuilds(&events, &stream);
        match broken_at {
            None => prop_assert_eq!(d.stats().bad_arguments, 0),
            Some(i) => {
                prop_assert!(d.stats().bad_arguments >= 1);
                let decoded: Vec<Command> = events.iter().filter_map(|e| match e {
                    CommandEvent::Command(c) => Some(*c),
                    CommandEvent::Rejected { .. } => None,
                }).collect();
                prop_assert_eq!(&decoded[..i], &cmds[..i]);
            }
        }
    }
}
