//! The streaming MIP decoder, used on both sides: push bytes, pull packets and rejected runs;
//! never fails, never panics, and accounts for every input byte exactly once.
//!
//! It is the shared [`FramedDecoder`] (the GX1 decoders' byte buffer, reject reasons and
//! counters), so the conservation law is the same:
//! `bytes_in == frame_bytes + rejected_bytes + pending_len()`, and the events' bytes, in
//! order, are exactly the input stream.

use crate::decoder::framed::{FramedDecoder, Framing, PacketEvent};

use super::{CHECKSUM_LEN, HEADER_LEN, MipError, Packet, SYNC1, SYNC2};

/// One thing the [`MipDecoder`] found in the stream.
pub type MipEvent = PacketEvent<Packet>;

/// Streaming decoder of MIP packets (host side: replies and data; device side: commands): the
/// shared [`FramedDecoder`] over [`MipFraming`], so its resync and byte accounting are the
/// Xsens decoder's too.
///
/// At the head of the stream, a byte that cannot start `0x75 0x65` is garbage. A packet start
/// waits for its header, then for the length the header announces, then:
/// - good checksum and field layout: a `Packet`;
/// - otherwise, if a good packet starts inside the candidate: `Rejected { Truncated }` with the
///   bytes up to that start, and decoding resumes there;
/// - otherwise `Rejected { BadChecksum }` (or `Malformed`: good checksum, bad fields or
///   descriptor set 0) with the candidate's bytes.
pub type MipDecoder = FramedDecoder<MipFraming>;

/// MIP's framing: sync `0x75 0x65`, a one-byte payload length, a Fletcher-16 checksum.
#[derive(Debug, Clone, Copy)]
pub struct MipFraming;

impl Framing for MipFraming {
    type Packet = Packet;

    fn may_start(avail: &[u8], p: usize, eos: bool) -> bool {
        avail[p] == SYNC1
            && match avail.get(p + 1) {
                Some(&b) => b == SYNC2,
                None => !eos,
            }
    }

    fn packet_len(head: &[u8]) -> Option<usize> {
        let header = head.get(..HEADER_LEN)?;
        Some(HEADER_LEN + usize::from(header[3]) + CHECKSUM_LEN)
    }

    fn parse(candidate: &[u8]) -> Result<Packet, bool> {
        Packet::parse(candidate).map_err(|e| matches!(e, MipError::BadChecksum { .. }))
    }

    fn bytes(packet: &Packet) -> &[u8] {
        packet.as_bytes()
    }
}
