//! MIP packet framing: a checked packet held inline ([`Packet`]), its fields ([`Field`]), and
//! the builder that lays fields out and appends the checksum ([`PacketBuilder`]).

use std::fmt;

use super::checksum::fletcher16;
use super::{CHECKSUM_LEN, HEADER_LEN, MAX_PACKET_LEN, MAX_PAYLOAD_LEN, MipError, SYNC1, SYNC2};

/// One field of a packet's payload: descriptor and data (without the length and descriptor
/// bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field<'a> {
    /// Field descriptor.
    pub descriptor: u8,
    /// Field data.
    pub data: &'a [u8],
}

/// A packet with good sync bytes, checksum, descriptor set and field layout, held inline (at
/// most [`MAX_PACKET_LEN`] bytes, so decoding one allocates nothing).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Packet {
    len: u16,
    bytes: [u8; MAX_PACKET_LEN],
}

impl Packet {
    /// Checks a complete packet: sync, length byte against the slice, checksum, a non-zero
    /// descriptor set and fields that tile the payload exactly.
    pub fn parse(bytes: &[u8]) -> Result<Self, MipError> {
        let expected = packet_len(bytes)?;
        if bytes.len() != expected {
            return Err(MipError::WrongLength {
                expected,
                found: bytes.len(),
            });
        }
        let (body, sum) = bytes.split_at(expected - CHECKSUM_LEN);
        let computed = fletcher16(body);
        let found = u16::from_be_bytes([sum[0], sum[1]]);
        if computed != found {
            return Err(MipError::BadChecksum {
                expected: computed,
                found,
            });
        }
        if bytes[2] == 0 {
            return Err(MipError::ZeroDescriptorSet);
        }
        check_fields(&body[HEADER_LEN..])?;
        let mut out = Self {
            len: expected as u16,
            bytes: [0; MAX_PACKET_LEN],
        };
        out.bytes[..expected].copy_from_slice(bytes);
        Ok(out)
    }

    /// The whole packet, sync bytes to checksum.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..usize::from(self.len)]
    }

    /// The descriptor set byte.
    pub fn descriptor_set(&self) -> u8 {
        self.bytes[2]
    }

    /// The payload (the fields, without header and checksum).
    pub fn payload(&self) -> &[u8] {
        &self.bytes[HEADER_LEN..usize::from(self.len) - CHECKSUM_LEN]
    }

    /// The fields in order (the layout was checked when the packet was made).
    pub fn fields(&self) -> impl Iterator<Item = Field<'_>> + '_ {
        let mut rest = self.payload();
        std::iter::from_fn(move || {
            let (&len, _) = rest.split_first()?;
            let (field, tail) = rest.split_at(usize::from(len).min(rest.len()));
            rest = tail;
            Some(Field {
                descriptor: field[1],
                data: &field[2..],
            })
        })
    }
}

impl fmt::Debug for Packet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Packet({:02X?})", self.as_bytes())
    }
}

impl AsRef<[u8]> for Packet {
    fn as_ref(&self) -> &[u8] {
        self.as_bytes()
    }
}

/// The total packet length its header announces (needs the first [`HEADER_LEN`] bytes).
pub(crate) fn packet_len(bytes: &[u8]) -> Result<usize, MipError> {
    if bytes.len() < HEADER_LEN + CHECKSUM_LEN {
        return Err(MipError::TooShort(bytes.len()));
    }
    if bytes[0] != SYNC1 || bytes[1] != SYNC2 {
        return Err(MipError::BadSync(bytes[0], bytes[1]));
    }
    Ok(HEADER_LEN + usize::from(bytes[3]) + CHECKSUM_LEN)
}

/// Every field is at least its length and descriptor bytes, and the fields end exactly where
/// the payload does.
fn check_fields(payload: &[u8]) -> Result<(), MipError> {
    let mut at = 0;
    while at < payload.len() {
        let len = payload[at];
        if len < 2 || at + usize::from(len) > payload.len() {
            return Err(MipError::BadFieldLength { offset: at, len });
        }
        at += usize::from(len);
    }
    Ok(())
}

/// Lays out fields and finishes a [`Packet`] with its checksum.
///
/// ```
/// use imu_proto::mip::PacketBuilder;
/// // The accel packet of mip_sdk test/cpp/packet_interface.cpp: field 0x04 holding (1, 2, -3) g.
/// let mut b = PacketBuilder::new(0x80);
/// let data: Vec<u8> = [1.0f32, 2.0, -3.0].iter().flat_map(|v| v.to_be_bytes()).collect();
/// b.field(0x04, &data).unwrap();
/// let packet = b.build();
/// assert_eq!(&packet.as_bytes()[packet.as_bytes().len() - 2..], [0x79, 0xED]);
/// ```
#[derive(Clone)]
pub struct PacketBuilder {
    descriptor_set: u8,
    payload_len: usize,
    payload: [u8; MAX_PAYLOAD_LEN],
}

impl PacketBuilder {
    /// An empty packet of `descriptor_set`.
    pub fn new(descriptor_set: u8) -> Self {
        Self {
            descriptor_set,
            payload_len: 0,
            payload: [0; MAX_PAYLOAD_LEN],
        }
    }

    /// Appends one field. Fails (and appends nothing) when it does not fit the payload.
    pub fn field(&mut self, descriptor: u8, data: &[u8]) -> Result<&mut Self, MipError> {
        let len = data.len() + 2;
        let end = self.payload_len + len;
        if end > MAX_PAYLOAD_LEN {
            return Err(MipError::PayloadFull(end));
        }
        let at = self.payload_len;
        self.payload[at] = len as u8;
        self.payload[at + 1] = descriptor;
        self.payload[at + 2..end].copy_from_slice(data);
        self.payload_len = end;
        Ok(self)
    }

    /// The finished packet, checksum appended.
    pub fn build(&self) -> Packet {
        let n = self.payload_len;
        let mut bytes = [0u8; MAX_PACKET_LEN];
        bytes[..HEADER_LEN].copy_from_slice(&[SYNC1, SYNC2, self.descriptor_set, n as u8]);
        bytes[HEADER_LEN..HEADER_LEN + n].copy_from_slice(&self.payload[..n]);
        let sum = fletcher16(&bytes[..HEADER_LEN + n]);
        bytes[HEADER_LEN + n..HEADER_LEN + n + CHECKSUM_LEN].copy_from_slice(&sum.to_be_bytes());
        Packet {
            len: (HEADER_LEN + n + CHECKSUM_LEN) as u16,
            bytes,
        }
    }
}

/// Big-endian readers over a field's data, each checking the exact size.
pub(crate) struct Reader<'a> {
    data: &'a [u8],
    set: u8,
    descriptor: u8,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(set: u8, field: Field<'a>) -> Self {
        Self {
            data: field.data,
            set,
            descriptor: field.descriptor,
        }
    }

    pub(crate) fn error(&self, problem: &'static str) -> MipError {
        MipError::BadField {
            set: self.set,
            descriptor: self.descriptor,
            problem,
        }
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N], MipError> {
        let Some((head, tail)) = self.data.split_first_chunk::<N>() else {
            return Err(self.error("field data too short"));
        };
        self.data = tail;
        Ok(*head)
    }

    pub(crate) fn u8(&mut self) -> Result<u8, MipError> {
        Ok(self.take::<1>()?[0])
    }

    pub(crate) fn u16(&mut self) -> Result<u16, MipError> {
        self.take().map(u16::from_be_bytes)
    }

    pub(crate) fn u32(&mut self) -> Result<u32, MipError> {
        self.take().map(u32::from_be_bytes)
    }

    pub(crate) fn u64(&mut self) -> Result<u64, MipError> {
        self.take().map(u64::from_be_bytes)
    }

    pub(crate) fn f32(&mut self) -> Result<f32, MipError> {
        self.take().map(f32::from_be_bytes)
    }

    pub(crate) fn f64(&mut self) -> Result<f64, MipError> {
        self.take().map(f64::from_be_bytes)
    }

    pub(crate) fn vec3(&mut self) -> Result<[f32; 3], MipError> {
        Ok([self.f32()?, self.f32()?, self.f32()?])
    }

    pub(crate) fn bytes<const N: usize>(&mut self) -> Result<[u8; N], MipError> {
        self.take()
    }

    /// Nothing may be left over.
    pub(crate) fn end(&self) -> Result<(), MipError> {
        if self.data.is_empty() {
            Ok(())
        } else {
            Err(self.error("field data too long"))
        }
    }

    pub(crate) fn remaining(&self) -> usize {
        self.data.len()
    }
}

/// Big-endian writer of a field's data (at most a field's 253 bytes).
#[derive(Default)]
pub(crate) struct Writer {
    pub(crate) data: Vec<u8>,
}

impl Writer {
    pub(crate) fn u8(&mut self, v: u8) -> &mut Self {
        self.data.push(v);
        self
    }
    pub(crate) fn u16(&mut self, v: u16) -> &mut Self {
        self.data.extend_from_slice(&v.to_be_bytes());
        self
    }
}
