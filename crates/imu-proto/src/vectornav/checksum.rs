//! The two checks VectorNav messages carry: the 8-bit XOR checksum of ASCII sentences and the
//! CRC-16-CCITT of binary messages (also accepted on ASCII sentences as a 4-hex-digit check).

/// XOR of every byte: the ASCII sentence checksum over the bytes between `$` and `*`.
///
/// ```
/// use imu_proto::vectornav::checksum::checksum8;
/// // "$VNRRG,11*73", the read of register 11 that VectorNav's manuals use as their example.
/// assert_eq!(checksum8(b"VNRRG,11"), 0x73);
/// ```
pub fn checksum8(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0, |acc, &b| acc ^ b)
}

/// CRC-16-CCITT, initial value 0, polynomial 0x1021, no reflection, no final XOR (the variant
/// also called CRC-16/XMODEM). A binary message carries it big-endian after its payload, so the
/// CRC over everything after the sync byte, CRC included, is 0 for a good message.
///
/// ```
/// use imu_proto::vectornav::checksum::crc16;
/// // The catalogue check value of CRC-16/XMODEM.
/// assert_eq!(crc16(b"123456789"), 0x31C3);
/// ```
pub fn crc16(bytes: &[u8]) -> u16 {
    // Eight bytes a step (slicing-by-8): the register is 16 bits, so only the first two bytes
    // of a step meet it and the eight lookups are independent, instead of one chain of
    // dependent lookups a byte; the rest a byte at a time.
    let t = &CRC16_TABLES;
    let mut chunks = bytes.chunks_exact(SLICES);
    let mut crc = 0u16;
    for c in &mut chunks {
        let [hi, lo] = crc.to_be_bytes();
        crc = t[7][usize::from(hi ^ c[0])]
            ^ t[6][usize::from(lo ^ c[1])]
            ^ t[5][usize::from(c[2])]
            ^ t[4][usize::from(c[3])]
            ^ t[3][usize::from(c[4])]
            ^ t[2][usize::from(c[5])]
            ^ t[1][usize::from(c[6])]
            ^ t[0][usize::from(c[7])];
    }
    chunks.remainder().iter().fold(crc, |crc, &b| {
        (crc << 8) ^ t[0][usize::from((crc >> 8) as u8 ^ b)]
    })
}

/// Bytes [`crc16`] takes a step.
const SLICES: usize = 8;

/// `CRC16_TABLES[k][i]`: the register after the byte `i` and then `k` zero bytes, from 0. By
/// linearity a step's register is the XOR of each byte's entry at its distance from the end.
const CRC16_TABLES: [[u16; 256]; SLICES] = {
    let mut t = [[0u16; 256]; SLICES];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
            bit += 1;
        }
        t[0][i] = crc;
        i += 1;
    }
    let mut k = 1;
    while k < SLICES {
        let mut i = 0;
        while i < 256 {
            // One zero byte more through the register.
            let prev = t[k - 1][i];
            t[k][i] = (prev << 8) ^ t[0][(prev >> 8) as usize];
            i += 1;
        }
        k += 1;
    }
    t
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_over_message_and_its_crc_is_zero() {
        let body = b"\x01\x02\x00any payload";
        let crc = crc16(body);
        let mut msg = body.to_vec();
        msg.extend_from_slice(&crc.to_be_bytes());
        assert_eq!(crc16(&msg), 0);
    }

    /// The bit-at-a-time definition of CRC-16/XMODEM, which the table must reproduce.
    fn crc16_bitwise(bytes: &[u8]) -> u16 {
        bytes.iter().fold(0u16, |crc, &b| {
            let mut crc = crc ^ (u16::from(b) << 8);
            for _ in 0..8 {
                crc = if crc & 0x8000 != 0 {
                    (crc << 1) ^ 0x1021
                } else {
                    crc << 1
                };
            }
            crc
        })
    }

    #[test]
    fn table_crc_equals_the_bitwise_definition() {
        // Every byte value after every other, so each table entry is met from many states.
        let bytes: Vec<u8> = (0..=255u8)
            .flat_map(|a| [a, a.wrapping_mul(31), !a])
            .collect();
        for n in (0..=40).chain([100, 101, 103, bytes.len()]) {
            assert_eq!(
                crc16(&bytes[..n]),
                crc16_bitwise(&bytes[..n]),
                "first {n} bytes"
            );
        }
    }

    #[test]
    fn empty_input_checks_to_zero() {
        assert_eq!(checksum8(&[]), 0);
        assert_eq!(crc16(&[]), 0);
    }
}
