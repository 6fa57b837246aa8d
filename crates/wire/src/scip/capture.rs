//! Byte captures in the hokuyoaist log format (`.logr` = bytes read from the
//! sensor, `.logw` = bytes written to it): records of big-endian u32 seconds,
//! u32 microseconds, u32 length, then that many bytes. Used by the golden
//! tests and by replay tools.

use alloc::vec::Vec;
/// One record of a capture.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureRecord {
    /// Host time of the record (s).
    pub time: f64,
    /// The bytes, exactly as read or written at that time.
    pub bytes: Vec<u8>,
}

/// Why a capture file could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CaptureError {
    /// The file ends inside a record header or its bytes.
    #[error("capture truncated at byte {offset}: record needs {needed} more bytes")]
    Truncated {
        /// Offset of the incomplete record.
        offset: usize,
        /// Bytes missing.
        needed: usize,
    },
    /// A record's microseconds field is 1,000,000 or more.
    #[error("capture record at byte {0} has an invalid microseconds field")]
    BadTime(usize),
}

fn be_u32(b: &[u8]) -> u32 {
    u32::from_be_bytes([b[0], b[1], b[2], b[3]])
}

/// Splits a capture file into its records.
pub fn parse_capture(data: &[u8]) -> Result<Vec<CaptureRecord>, CaptureError> {
    let mut out = Vec::new();
    let mut at = 0usize;
    while at < data.len() {
        let rest = &data[at..];
        if rest.len() < 12 {
            return Err(CaptureError::Truncated {
                offset: at,
                needed: 12 - rest.len(),
            });
        }
        let (secs, micros, len) = (
            be_u32(rest),
            be_u32(&rest[4..]),
            be_u32(&rest[8..]) as usize,
        );
        if micros >= 1_000_000 {
            return Err(CaptureError::BadTime(at));
        }
        let body = &rest[12..];
        if body.len() < len {
            return Err(CaptureError::Truncated {
                offset: at,
                needed: len - body.len(),
            });
        }
        out.push(CaptureRecord {
            time: f64::from(secs) + f64::from(micros) * 1e-6,
            bytes: body[..len].to_vec(),
        });
        at += 12 + len;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_and_truncation() {
        let mut d = vec![0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 3, b'a', b'b', b'c'];
        let r = parse_capture(&d).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].bytes, b"abc");
        assert!((r[0].time - 1.000002).abs() < 1e-9);
        d.pop();
        assert_eq!(
            parse_capture(&d),
            Err(CaptureError::Truncated {
                offset: 0,
                needed: 1
            })
        );
        assert_eq!(
            parse_capture(&d[..5]),
            Err(CaptureError::Truncated {
                offset: 0,
                needed: 7
            })
        );
        let bad = [0, 0, 0, 1, 0, 0x0f, 0x42, 0x40, 0, 0, 0, 0];
        assert_eq!(parse_capture(&bad), Err(CaptureError::BadTime(0)));
        assert_eq!(parse_capture(&[]), Ok(vec![]));
    }
}
