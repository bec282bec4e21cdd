//! The device side: the streaming decoder of host commands (the simulator's).

use super::*;

/// Why bytes were rejected by the [`CommandDecoder`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CommandRejectReason {
    /// Bytes that are not a known command code (one event per contiguous run, at most
    /// [`MAX_GARBAGE_RUN`] bytes each).
    UnknownCode,
    /// A known code followed by a wrong fixed byte; only the code byte is rejected and decoding
    /// resumes right after it.
    BadArgument,
    /// A command cut short by the end of the stream ([`CommandDecoder::flush`]).
    Truncated,
}

/// One thing the [`CommandDecoder`] found in the stream.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CommandEvent {
    /// A well-formed command.
    Command(Command),
    /// Bytes that are not (part of) a well-formed command.
    Rejected {
        /// The rejected bytes.
        bytes: Vec<u8>,
        /// Stream byte offset of the first rejected byte.
        offset: u64,
        /// Why they were rejected.
        reason: CommandRejectReason,
    },
}

/// Counters of a [`CommandDecoder`]. Byte counters are updated when the event is emitted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CommandDecoderStats {
    /// Well-formed commands emitted.
    pub commands: u64,
    /// Bytes pushed.
    pub bytes_in: u64,
    /// Bytes of emitted commands.
    pub command_bytes: u64,
    /// Bytes emitted in `Rejected` events of any reason.
    pub rejected_bytes: u64,
    /// Bytes rejected as unknown codes.
    pub unknown_bytes: u64,
    /// Code bytes rejected because a fixed argument byte was wrong.
    pub bad_arguments: u64,
    /// Commands cut short by the end of the stream.
    pub truncated_commands: u64,
}

/// Device-side streaming decoder of host commands (used by the simulator).
///
/// Knows each command's length and checks the fixed argument bytes as soon as they arrive
/// (`10 00`, `0F/11 C1 C3 C5`, `29 71 .. .. .. .. AA`); a wrong one rejects the code byte alone
/// and decoding rescans from the next byte. Commands carry no checksum, so a garbage byte that
/// happens to be a command code is decoded as a command: that is the protocol.
///
/// ```
/// use imu_proto::command::Command;
/// use imu_proto::decoder::{CommandDecoder, CommandEvent};
/// let mut d = CommandDecoder::new();
/// d.push(&[0x10, 0x00, 0x02, 0x07]);
/// assert_eq!(d.next_event(), Some(CommandEvent::Command(Command::SetContinuous { command: 2 })));
/// assert_eq!(d.next_event(), Some(CommandEvent::Command(Command::Temperature)));
/// assert_eq!(d.next_event(), None);
/// ```
#[derive(Debug, Clone, Default)]
pub struct CommandDecoder {
    pub(super) sb: StreamBuf,
    stats: CommandDecoderStats,
}

impl CommandDecoder {
    /// A fresh decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends bytes received from the host.
    pub fn push(&mut self, bytes: &[u8]) {
        self.stats.bytes_in += bytes.len() as u64;
        self.sb.push(bytes);
    }

    /// Marks the end of the stream so far; see [`ReplyDecoder::flush`].
    pub fn flush(&mut self) {
        self.sb.flush();
    }

    /// Bytes pushed but not yet reported in any event.
    pub fn pending_len(&self) -> usize {
        self.sb.pending_len()
    }

    /// The counters so far.
    pub fn stats(&self) -> CommandDecoderStats {
        self.stats
    }

    pub(super) fn emit_unknown(&mut self) -> CommandEvent {
        let (offset, bytes) = self.sb.take_garbage();
        self.stats.unknown_bytes += bytes.len() as u64;
        self.stats.rejected_bytes += bytes.len() as u64;
        CommandEvent::Rejected {
            bytes,
            offset,
            reason: CommandRejectReason::UnknownCode,
        }
    }

    pub(super) fn emit_rejected(&mut self, n: usize, reason: CommandRejectReason) -> CommandEvent {
        let (offset, bytes) = self.sb.consume(n, |offset, b| (offset, b.to_vec()));
        self.stats.rejected_bytes += bytes.len() as u64;
        match reason {
            CommandRejectReason::BadArgument => self.stats.bad_arguments += 1,
            CommandRejectReason::Truncated => self.stats.truncated_commands += 1,
            CommandRejectReason::UnknownCode => self.stats.unknown_bytes += bytes.len() as u64,
        }
        CommandEvent::Rejected {
            bytes,
            offset,
            reason,
        }
    }

    /// The host went quiet in the middle of a command: rejects the incomplete command's code byte
    /// (as [`CommandRejectReason::Truncated`]) so that the bytes after it are decoded afresh.
    ///
    /// Commands carry no checksum, so a stray byte that looks like the start of a long command
    /// (`0x29` takes 7 bytes) would otherwise swallow the next real command while the host waits
    /// for its reply. A device times such partial input out; call this after a quiet period.
    /// Returns `None` when no partial command is pending.
    pub fn expire_partial(&mut self) -> Option<CommandEvent> {
        if self.sb.garbage_len > 0 {
            return None;
        }
        let avail = self.sb.unprocessed();
        let len = command_len_for_code(*avail.first()?)?;
        if avail.len() >= len {
            return None;
        }
        Some(self.emit_rejected(1, CommandRejectReason::Truncated))
    }

    /// The next event, or `None` when more bytes are needed (or everything is reported).
    pub fn next_event(&mut self) -> Option<CommandEvent> {
        loop {
            let eos = self.sb.eos();
            let garbage_len = self.sb.garbage_len;
            let avail = self.sb.unprocessed();
            let Some(&code) = avail.first() else {
                if eos {
                    if garbage_len > 0 {
                        return Some(self.emit_unknown());
                    }
                    self.sb.flush_end = None;
                    if self.sb.unprocessed().is_empty() {
                        return None;
                    }
                    continue;
                }
                return None;
            };
            if garbage_len >= MAX_GARBAGE_RUN {
                return Some(self.emit_unknown());
            }
            let Some(len) = command_len_for_code(code) else {
                let room = MAX_GARBAGE_RUN - garbage_len;
                let skip = avail
                    .iter()
                    .take(room)
                    .position(|&b| command_len_for_code(b).is_some())
                    .unwrap_or(room.min(avail.len()));
                self.sb.garbage_len += skip;
                continue;
            };
            if garbage_len > 0 {
                return Some(self.emit_unknown());
            }
            // Check the fixed bytes we already have, so a bad one is rejected without waiting.
            let have = len.min(avail.len());
            let bad_fixed_byte =
                (1..have).any(|i| fixed_command_byte(code, i).is_some_and(|want| avail[i] != want));
            if bad_fixed_byte {
                return Some(self.emit_rejected(1, CommandRejectReason::BadArgument));
            }
            if avail.len() < len {
                if eos {
                    let n = avail.len();
                    return Some(self.emit_rejected(n, CommandRejectReason::Truncated));
                }
                return None;
            }
            return match Command::decode(&avail[..len]) {
                Ok(command) => {
                    self.sb.consume(len, |_, _| ());
                    self.stats.commands += 1;
                    self.stats.command_bytes += len as u64;
                    Some(CommandEvent::Command(command))
                }
                // Unreachable (length and fixed bytes were checked), but never panic.
                Err(_) => Some(self.emit_rejected(1, CommandRejectReason::BadArgument)),
            };
        }
    }
}
