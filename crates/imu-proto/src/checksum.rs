//! The 3DM-GX1 reply checksum: unsigned header byte plus every big-endian word, modulo 2^16.

/// Computes the checksum of a reply frame *without* its two trailing checksum bytes.
///
/// The sum starts with the header byte read as an **unsigned** `u8` (one published driver reads
/// it as a signed `char`, which gives a different answer for the 0xF0/0xF1 headers), then adds
/// every big-endian `u16` word from byte offset 1, wrapping modulo 2^16.
///
/// Well-formed frames have an odd length here (header + whole words). For any other input the
/// function still never panics: a dangling last byte counts as the high byte of a word whose low
/// byte is zero, and an empty slice sums to 0.
///
/// ```
/// use imu_proto::checksum::checksum;
/// // temperature reply: 0x07 + 0x1234 + 0x0042 = 0x127D
/// assert_eq!(checksum(&[0x07, 0x12, 0x34, 0x00, 0x42]), 0x127D);
/// ```
pub fn checksum(frame_without_checksum: &[u8]) -> u16 {
    let Some((&header, words)) = frame_without_checksum.split_first() else {
        return 0;
    };
    let mut sum = u16::from(header);
    let mut pairs = words.chunks_exact(2);
    for pair in &mut pairs {
        sum = sum.wrapping_add(u16::from_be_bytes([pair[0], pair[1]]));
    }
    if let [last] = pairs.remainder() {
        sum = sum.wrapping_add(u16::from_be_bytes([*last, 0]));
    }
    sum
}

/// Returns the checksum stored in the last two bytes of `frame` (big-endian), if it has them.
pub fn stored_checksum(frame: &[u8]) -> Option<u16> {
    match frame {
        [.., hi, lo] if frame.len() >= 3 => Some(u16::from_be_bytes([*hi, *lo])),
        _ => None,
    }
}

/// Checks a complete reply frame (header, words, checksum).
///
/// Returns `false` for anything that cannot be a frame: shorter than header + checksum (3 bytes),
/// or an even total length (frames are header + whole words + checksum, so always odd).
pub fn verify(frame: &[u8]) -> bool {
    if frame.len() < 3 || frame.len().is_multiple_of(2) {
        return false;
    }
    let (body, _) = frame.split_at(frame.len() - 2);
    stored_checksum(frame) == Some(checksum(body))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_unsigned() {
        // 0xF0 + 0x0C1E = 0x0D0E; the signed reading gives 0x0C1E - 0x10 = 0x0C0E.
        let body = [0xF0, 0x0C, 0x1E];
        assert_eq!(checksum(&body), 0x0D0E);
        // The buggy driver sign-extends the header: 0xF0 as i8 = -16.
        let signed = (i32::from(0xF0u8 as i8) + 0x0C1E) as u16;
        assert_eq!(signed, 0x0C0E);
        assert_ne!(checksum(&body), signed);
    }

    #[test]
    fn wraps_modulo_2_16() {
        // 0x01 + 0xFFFF + 0xFFFF = 0x1FFFF -> 0xFFFF
        assert_eq!(checksum(&[0x01, 0xFF, 0xFF, 0xFF, 0xFF]), 0xFFFF);
        // 0x06 + 0xFFFA = 0x10000 -> 0x0000
        assert_eq!(checksum(&[0x06, 0xFF, 0xFA]), 0x0000);
    }

    #[test]
    fn verify_accepts_good_and_rejects_bad() {
        assert!(verify(&[0x06, 0xAB, 0xCD, 0xAB, 0xD3]));
        assert!(!verify(&[0x06, 0xAB, 0xCD, 0xAB, 0xD4]));
        assert!(!verify(&[0x06, 0xAB, 0xCD, 0xAB]));
        assert!(!verify(&[]));
        assert!(!verify(&[0x06, 0x00]));
    }

    #[test]
    fn odd_inputs_do_not_panic() {
        assert_eq!(checksum(&[]), 0);
        assert_eq!(checksum(&[0x07]), 7);
        // dangling byte counts as a high byte: 0x07 + 0x1200
        assert_eq!(checksum(&[0x07, 0x12]), 0x1207);
        assert_eq!(stored_checksum(&[1, 2]), None);
        assert_eq!(stored_checksum(&[1, 2, 3]), Some(0x0203));
    }
}
