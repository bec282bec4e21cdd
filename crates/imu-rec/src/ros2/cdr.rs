//! CDR (XCDR1, little-endian) encoding and decoding: the writer and reader every message uses.

use super::*;

/// Why CDR bytes could not be decoded. Offsets count from the first byte of the message
/// (the encapsulation header included).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// The message does not start with the little-endian CDR encapsulation header.
    #[error("encapsulation header {found:02X?} is not little-endian CDR (00 01 00 00)")]
    BadEncapsulation {
        /// The first bytes found (up to four).
        found: Vec<u8>,
    },
    /// The message ends before a field does.
    #[error("message ends at byte {len} inside field `{field}` (needs bytes {offset}..{end})")]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Where the field starts.
        offset: usize,
        /// Where it would end.
        end: usize,
        /// The message length.
        len: usize,
    },
    /// A string is not UTF-8 or lacks its terminating NUL.
    #[error("field `{field}` at byte {offset} is not a NUL-terminated UTF-8 string")]
    BadString {
        /// The field being read.
        field: &'static str,
        /// Where its length prefix starts.
        offset: usize,
    },
}

/// Appends one CDR message to a byte buffer.
pub struct CdrWriter<'a> {
    buf: &'a mut Vec<u8>,
    /// Index of the first byte after the encapsulation header (alignment origin).
    origin: usize,
}

impl<'a> CdrWriter<'a> {
    /// Starts a message at the end of `buf` by appending the encapsulation header.
    pub fn new(buf: &'a mut Vec<u8>) -> Self {
        buf.extend_from_slice(&CDR_LE_HEADER);
        let origin = buf.len();
        Self { buf, origin }
    }

    pub(super) fn align(&mut self, n: usize) {
        let pos = self.buf.len() - self.origin;
        let pad = (n - pos % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// Writes a `uint8`.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// Writes a `bool` (one byte, 0 or 1).
    pub fn bool(&mut self, v: bool) {
        self.buf.push(u8::from(v));
    }

    /// Writes a `uint16`.
    pub fn u16(&mut self, v: u16) {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// Writes an `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// Writes a `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// Writes a `uint64`.
    pub fn u64(&mut self, v: u64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// Writes a `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// Writes a `string` (length including the NUL, the bytes, the NUL).
    ///
    /// A string longer than `u32::MAX - 1` bytes cannot be represented and is cut there.
    pub fn string(&mut self, s: &str) {
        let bytes = &s.as_bytes()[..s.len().min(u32::MAX as usize - 1)];
        self.u32(bytes.len() as u32 + 1);
        self.buf.extend_from_slice(bytes);
        self.buf.push(0);
    }

    /// Writes a `uint8[]` sequence (count, then the bytes). A sequence longer than `u32::MAX`
    /// bytes cannot be represented and is cut there.
    pub fn byte_sequence(&mut self, bytes: &[u8]) {
        let bytes = &bytes[..bytes.len().min(u32::MAX as usize)];
        self.u32(bytes.len() as u32);
        self.buf.extend_from_slice(bytes);
    }

    /// Writes a fixed-size `float64[N]` array (no count).
    pub fn f64_array(&mut self, values: &[f64]) {
        for &v in values {
            self.f64(v);
        }
    }

    /// Writes a fixed-size `int32[N]` array (no count).
    pub fn i32_array(&mut self, values: &[i32]) {
        for &v in values {
            self.i32(v);
        }
    }

    /// Writes a fixed-size `uint8[N]` array (no count).
    pub fn u8_array(&mut self, values: &[u8]) {
        self.buf.extend_from_slice(values);
    }
}

/// Reads one CDR message field by field. Never panics: every read is bounds-checked.
pub struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    /// Checks the encapsulation header and positions the reader on the first field.
    pub fn new(data: &'a [u8]) -> Result<Self, CdrError> {
        // Bytes 2..4 are options, which plain CDR leaves for the writer's use; only the
        // representation identifier (bytes 0..2) decides how to decode.
        match data.get(..4) {
            Some(h) if h[..2] == CDR_LE_HEADER[..2] => Ok(Self { data, pos: 4 }),
            _ => Err(CdrError::BadEncapsulation {
                found: data[..data.len().min(4)].to_vec(),
            }),
        }
    }

    pub(super) fn take(
        &mut self,
        field: &'static str,
        align: usize,
        n: usize,
    ) -> Result<&'a [u8], CdrError> {
        let rel = self.pos - 4;
        let start = self.pos + (align - rel % align) % align;
        let end = start.saturating_add(n);
        match self.data.get(start..end) {
            Some(s) => {
                self.pos = end;
                Ok(s)
            }
            None => Err(CdrError::Truncated {
                field,
                offset: start,
                end,
                len: self.data.len(),
            }),
        }
    }

    pub(super) fn array<const N: usize>(
        &mut self,
        field: &'static str,
        align: usize,
    ) -> Result<[u8; N], CdrError> {
        let s = self.take(field, align, N)?;
        let mut out = [0u8; N];
        out.copy_from_slice(s);
        Ok(out)
    }

    /// Bytes not read yet (a message written by an older schema ends early).
    pub fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    /// Reads a `uint8`.
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.take(field, 1, 1)?[0])
    }

    /// Reads a `bool` (any non-zero byte is true).
    pub fn bool(&mut self, field: &'static str) -> Result<bool, CdrError> {
        Ok(self.u8(field)? != 0)
    }

    /// Reads a `uint16`.
    pub fn u16(&mut self, field: &'static str) -> Result<u16, CdrError> {
        Ok(u16::from_le_bytes(self.array(field, 2)?))
    }

    /// Reads an `int32`.
    pub fn i32(&mut self, field: &'static str) -> Result<i32, CdrError> {
        Ok(i32::from_le_bytes(self.array(field, 4)?))
    }

    /// Reads a `uint32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        Ok(u32::from_le_bytes(self.array(field, 4)?))
    }

    /// Reads a `uint64`.
    pub fn u64(&mut self, field: &'static str) -> Result<u64, CdrError> {
        Ok(u64::from_le_bytes(self.array(field, 8)?))
    }

    /// Reads a `float64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        Ok(f64::from_le_bytes(self.array(field, 8)?))
    }

    /// Reads a `string`. A zero length (written by some implementations for "") is accepted.
    pub fn string(&mut self, field: &'static str) -> Result<String, CdrError> {
        let offset = self.pos;
        let n = self.u32(field)? as usize;
        let bytes = self.take(field, 1, n)?;
        let text = match bytes.split_last() {
            None => &[][..],
            Some((0, text)) => text,
            Some(_) => return Err(CdrError::BadString { field, offset }),
        };
        String::from_utf8(text.to_vec()).map_err(|_| CdrError::BadString { field, offset })
    }

    /// Reads a `uint8[]` sequence.
    pub fn byte_sequence(&mut self, field: &'static str) -> Result<Vec<u8>, CdrError> {
        let n = self.u32(field)? as usize;
        Ok(self.take(field, 1, n)?.to_vec())
    }

    /// Reads a fixed-size `float64[N]` array.
    pub fn f64_array<const N: usize>(&mut self, field: &'static str) -> Result<[f64; N], CdrError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(field)?;
        }
        Ok(out)
    }

    /// Reads a fixed-size `int32[N]` array.
    pub fn i32_array<const N: usize>(&mut self, field: &'static str) -> Result<[i32; N], CdrError> {
        let mut out = [0; N];
        for v in &mut out {
            *v = self.i32(field)?;
        }
        Ok(out)
    }

    /// Reads a fixed-size `uint8[N]` array.
    pub fn u8_array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        self.array(field, 1)
    }
}
