//! SCIP character encoding: 6 bits per character (code − 0x30), big-endian,
//! in fields of 2 (12 bits), 3 (18 bits) or 4 (24 bits) characters.

use super::sink::{ByteSink, EncodeError};

/// Field width of an encoded value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Width {
    /// 2 characters, 12 bits (GS/MS distances).
    Two = 2,
    /// 3 characters, 18 bits (GD/MD/GE/ME distances and intensities).
    Three = 3,
    /// 4 characters, 24 bits (timestamps).
    Four = 4,
}

impl Width {
    /// Number of characters in the field.
    pub const fn chars(self) -> usize {
        self as usize
    }

    /// Largest value the field can carry.
    pub const fn max_value(self) -> u32 {
        (1u32 << (6 * self as u32)) - 1
    }
}

/// A field held a character outside the encoding alphabet (`0`..=`o`), or had
/// the wrong length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EncodingError {
    /// A character outside 0x30..=0x6F.
    #[error("byte 0x{byte:02x} at offset {offset} is not a SCIP encoded character")]
    BadChar {
        /// The offending byte.
        byte: u8,
        /// Its offset within the field.
        offset: usize,
    },
    /// The field has a length other than 2, 3 or 4 characters.
    #[error("encoded field has {0} characters, expected 2, 3 or 4")]
    BadLength(usize),
}

/// Decodes one 2-, 3- or 4-character field.
pub fn decode_value(field: &[u8]) -> Result<u32, EncodingError> {
    if !(2..=4).contains(&field.len()) {
        return Err(EncodingError::BadLength(field.len()));
    }
    let mut v = 0u32;
    for (offset, &byte) in field.iter().enumerate() {
        let d = byte.wrapping_sub(0x30);
        if d > 0x3f {
            return Err(EncodingError::BadChar { byte, offset });
        }
        v = (v << 6) | u32::from(d);
    }
    Ok(v)
}

/// Encodes `value` into `width` characters, written to `out`.
pub fn encode_value(value: u32, width: Width, out: &mut impl ByteSink) -> Result<(), EncodeError> {
    out.put(&encode_array(value, width)?[..width.chars()])
}

/// Encodes `value` into the first `width` bytes of a 4-byte array.
pub fn encode_array(value: u32, width: Width) -> Result<[u8; 4], EncodeError> {
    if value > width.max_value() {
        return Err(EncodeError::ValueTooLarge {
            value: u64::from(value),
            width: width.chars(),
        });
    }
    let n = width.chars();
    let mut buf = [0u8; 4];
    for (i, slot) in buf.iter_mut().take(n).enumerate() {
        let shift = 6 * (n - 1 - i);
        *slot = ((value >> shift) & 0x3f) as u8 + 0x30;
    }
    Ok(buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn documented_examples() {
        assert_eq!(decode_value(b"0CB"), Ok(1234));
        assert_eq!(decode_value(b"1GP"), Ok(5600));
        assert_eq!(decode_value(b"00D"), Ok(20));
        assert_eq!(decode_value(b"oo"), Ok(4095));
        assert_eq!(decode_value(b"JUGn"), Ok(6_968_830));
        let mut v = Vec::new();
        encode_value(1234, Width::Three, &mut v).unwrap();
        assert_eq!(v, b"0CB");
    }

    #[test]
    fn bad_input_is_typed() {
        assert_eq!(decode_value(b"0"), Err(EncodingError::BadLength(1)));
        assert_eq!(decode_value(b"00000"), Err(EncodingError::BadLength(5)));
        assert_eq!(
            decode_value(b"0p"),
            Err(EncodingError::BadChar {
                byte: b'p',
                offset: 1
            })
        );
        assert_eq!(
            decode_value(b"/0"),
            Err(EncodingError::BadChar {
                byte: b'/',
                offset: 0
            })
        );
        let mut v = Vec::new();
        assert!(encode_value(4096, Width::Two, &mut v).is_err());
        assert!(v.is_empty());
    }

    #[test]
    fn every_width_round_trips_at_its_edges() {
        for w in [Width::Two, Width::Three, Width::Four] {
            for value in [0, 1, 63, 64, w.max_value() / 2, w.max_value()] {
                let a = encode_array(value, w).unwrap();
                assert_eq!(decode_value(&a[..w.chars()]), Ok(value));
            }
        }
    }
}
