//! Xbus framing: a checked message ([`Message`]), its encoding ([`Message::new`]) and the
//! streaming decoder ([`XsensDecoder`], the shared framed decoder over [`XbusFraming`]).

use std::fmt;

use super::{
    BUS_ID, EXTENDED_HEADER_LEN, EXTENDED_LEN, HEADER_LEN, MAX_DATA_LEN, MAX_SHORT_DATA_LEN,
    MAX_SHORT_MESSAGE_LEN, PREAMBLE, XsensError,
};
use crate::decoder::framed::{FramedDecoder, Framing, PacketEvent};

/// A message with good preamble, bus id, length and checksum. Standard-form messages (data up
/// to 254 bytes, which every data message is) are held inline, so decoding one allocates
/// nothing; extended-form ones are held on the heap.
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct Message {
    len: u16,
    short: [u8; MAX_SHORT_MESSAGE_LEN],
    long: Vec<u8>,
}

/// The 8-bit checksum: minus the sum of the bytes after the preamble, so that those bytes and
/// it sum to 0 mod 256.
pub fn checksum(after_preamble: &[u8]) -> u8 {
    after_preamble
        .iter()
        .fold(0u8, |s, &b| s.wrapping_add(b))
        .wrapping_neg()
}

impl Message {
    /// The message `mid` with `data` (bus id 0xFF), in the standard form up to 254 bytes of
    /// data and the extended form beyond.
    pub fn new(mid: u8, data: &[u8]) -> Result<Self, XsensError> {
        let n = data.len();
        if n > MAX_DATA_LEN {
            return Err(XsensError::TooLong(n));
        }
        let mut bytes = Vec::with_capacity(n + EXTENDED_HEADER_LEN + 1);
        bytes.extend_from_slice(&[PREAMBLE, BUS_ID, mid]);
        if n <= MAX_SHORT_DATA_LEN {
            bytes.push(n as u8);
        } else {
            bytes.push(EXTENDED_LEN);
            bytes.extend_from_slice(&(n as u16).to_be_bytes());
        }
        bytes.extend_from_slice(data);
        bytes.push(checksum(&bytes[1..]));
        Ok(Self::from_checked(&bytes))
    }

    fn from_checked(bytes: &[u8]) -> Self {
        let mut out = Self {
            len: bytes.len() as u16,
            short: [0; MAX_SHORT_MESSAGE_LEN],
            long: Vec::new(),
        };
        if bytes.len() <= MAX_SHORT_MESSAGE_LEN {
            out.short[..bytes.len()].copy_from_slice(bytes);
        } else {
            out.long = bytes.to_vec();
        }
        out
    }

    /// Checks a complete message: preamble and bus id, length against the slice, checksum.
    pub fn parse(bytes: &[u8]) -> Result<Self, XsensError> {
        let expected = message_len(bytes)?;
        if bytes.len() != expected {
            return Err(XsensError::WrongLength {
                expected,
                found: bytes.len(),
            });
        }
        let sum = bytes[1..].iter().fold(0u8, |s, &b| s.wrapping_add(b));
        if sum != 0 {
            return Err(XsensError::BadChecksum(sum));
        }
        Ok(Self::from_checked(bytes))
    }

    /// The whole message, preamble to checksum.
    pub fn as_bytes(&self) -> &[u8] {
        let n = usize::from(self.len);
        if n <= MAX_SHORT_MESSAGE_LEN {
            &self.short[..n]
        } else {
            &self.long
        }
    }

    /// The message id.
    pub fn mid(&self) -> u8 {
        self.as_bytes()[2]
    }

    /// The data (without header and checksum).
    pub fn data(&self) -> &[u8] {
        let b = self.as_bytes();
        let start = if b[3] == EXTENDED_LEN {
            EXTENDED_HEADER_LEN
        } else {
            HEADER_LEN
        };
        &b[start..b.len() - 1]
    }
}

impl fmt::Debug for Message {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Message({:02X?})", self.as_bytes())
    }
}

impl AsRef<[u8]> for Message {
    fn as_ref(&self) -> &[u8] {
        self.as_bytes()
    }
}

/// The total message length the header announces; an extended length out of range is an
/// error (the decoder then rejects just the header instead of waiting for up to 64 KiB).
fn message_len(bytes: &[u8]) -> Result<usize, XsensError> {
    if bytes.len() < HEADER_LEN + 1 {
        return Err(XsensError::TooShort(bytes.len()));
    }
    if bytes[0] != PREAMBLE || bytes[1] != BUS_ID {
        return Err(XsensError::BadPreamble(bytes[0], bytes[1]));
    }
    if bytes[3] != EXTENDED_LEN {
        return Ok(HEADER_LEN + usize::from(bytes[3]) + 1);
    }
    let Some(ext) = bytes.get(HEADER_LEN..EXTENDED_HEADER_LEN) else {
        return Err(XsensError::TooShort(bytes.len()));
    };
    let n = usize::from(u16::from_be_bytes([ext[0], ext[1]]));
    // The extended form of a short length is unusual but not forbidden: taken as it is.
    if n > MAX_DATA_LEN {
        return Err(XsensError::BadExtendedLength(n));
    }
    Ok(EXTENDED_HEADER_LEN + n + 1)
}

/// Xbus framing: preamble `0xFA` and bus id `0xFF`, a length byte (or `0xFF` and a u16), a
/// checksum byte.
#[derive(Debug, Clone, Copy)]
pub struct XbusFraming;

impl Framing for XbusFraming {
    type Packet = Message;

    fn may_start(avail: &[u8], p: usize, eos: bool) -> bool {
        avail[p] == PREAMBLE
            && match avail.get(p + 1) {
                Some(&b) => b == BUS_ID,
                None => !eos,
            }
    }

    fn packet_len(head: &[u8]) -> Option<usize> {
        let header = head.get(..HEADER_LEN)?;
        if header[3] != EXTENDED_LEN {
            return Some(HEADER_LEN + usize::from(header[3]) + 1);
        }
        let ext = head.get(HEADER_LEN..EXTENDED_HEADER_LEN)?;
        let n = usize::from(u16::from_be_bytes([ext[0], ext[1]]));
        if n <= MAX_DATA_LEN {
            Some(EXTENDED_HEADER_LEN + n + 1)
        } else {
            // Never a message: the header alone is the candidate, rejected as malformed.
            Some(EXTENDED_HEADER_LEN)
        }
    }

    fn parse(candidate: &[u8]) -> Result<Message, bool> {
        Message::parse(candidate).map_err(|e| matches!(e, XsensError::BadChecksum(_)))
    }

    fn bytes(packet: &Message) -> &[u8] {
        packet.as_bytes()
    }
}

/// One thing the [`XsensDecoder`] found in the stream.
pub type XsensEvent = PacketEvent<Message>;

/// Streaming decoder of Xbus messages, both sides; never fails, accounts for every byte.
pub type XsensDecoder = FramedDecoder<XbusFraming>;
