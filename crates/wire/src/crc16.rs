//! CRC-16/XMODEM (polynomial 0x1021, initial value 0, no reflection, no final
//! XOR): the checksum RoboClaw packet serial puts on every packet.
//!
//! Table-driven; the table is built at compile time so nothing allocates.

/// The CRC polynomial (x^16 + x^12 + x^5 + 1).
pub const POLY: u16 = 0x1021;

const fn build_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ POLY
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

static TABLE: [u16; 256] = build_table();

/// A running CRC-16/XMODEM, fed byte by byte or slice by slice.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Crc16(u16);

impl Crc16 {
    /// A CRC at its initial value 0.
    pub const fn new() -> Self {
        Self(0)
    }

    /// Feeds one byte.
    pub fn push(&mut self, b: u8) {
        self.0 = (self.0 << 8) ^ TABLE[((self.0 >> 8) as u8 ^ b) as usize];
    }

    /// Feeds a slice.
    pub fn extend(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.push(b);
        }
    }

    /// The CRC of everything fed so far.
    pub const fn value(&self) -> u16 {
        self.0
    }
}

/// CRC-16/XMODEM of `bytes`.
pub fn crc16(bytes: &[u8]) -> u16 {
    let mut c = Crc16::new();
    c.extend(bytes);
    c.value()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit-by-bit reference, as in the RoboClaw manual's C example.
    fn reference(bytes: &[u8]) -> u16 {
        let mut crc: u16 = 0;
        for &b in bytes {
            crc ^= (b as u16) << 8;
            for _ in 0..8 {
                crc = if crc & 0x8000 != 0 {
                    (crc << 1) ^ 0x1021
                } else {
                    crc << 1
                };
            }
        }
        crc
    }

    #[test]
    fn standard_check_value() {
        // The catalogue check value of CRC-16/XMODEM over "123456789".
        assert_eq!(crc16(b"123456789"), 0x31C3);
        assert_eq!(crc16(&[]), 0);
    }

    #[test]
    fn table_matches_bitwise_reference() {
        let data: Vec<u8> = (0..=255u8).chain((0..=255u8).rev()).collect();
        for n in 0..data.len() {
            assert_eq!(crc16(&data[..n]), reference(&data[..n]), "prefix {n}");
        }
    }

    #[test]
    fn incremental_equals_one_shot() {
        let mut c = Crc16::new();
        c.push(0x80);
        c.extend(&[0x25, 1, 2, 3]);
        assert_eq!(c.value(), crc16(&[0x80, 0x25, 1, 2, 3]));
    }
}
