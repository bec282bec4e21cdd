//! The MIP packet checksum: Fletcher-16 over sync bytes, header and payload.

/// The two running 8-bit sums over `bytes` (everything before the checksum), as the u16 that is
/// sent big-endian: sum1 (the plain byte sum) in the high byte, sum2 (the sum of the running
/// sum1s) in the low byte.
///
/// ```
/// use imu_proto::mip::checksum::fletcher16;
/// // The ping packet of mip_sdk test/c/mip/test_mip_format.c: 75 65 01 02 02 01, checksum E0 C6.
/// assert_eq!(fletcher16(&[0x75, 0x65, 0x01, 0x02, 0x02, 0x01]), 0xE0C6);
/// ```
pub fn fletcher16(bytes: &[u8]) -> u16 {
    let (sum1, sum2) = bytes.iter().fold((0u8, 0u8), |(s1, s2), &b| {
        let s1 = s1.wrapping_add(b);
        (s1, s2.wrapping_add(s1))
    });
    u16::from_be_bytes([sum1, sum2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_input_sums_to_zero() {
        assert_eq!(fletcher16(&[]), 0);
    }

    #[test]
    fn sums_wrap_modulo_256() {
        // sum1 = 0xFF + 0x02 = 0x101 -> 0x01; sum2 = 0xFF + 0x01 = 0x100 -> 0x00.
        assert_eq!(fletcher16(&[0xFF, 0x02]), 0x0100);
    }
}
