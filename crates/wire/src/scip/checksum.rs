//! SCIP checksums: the sum of the covered bytes, low 6 bits, plus 0x30, so
//! always a character between `0` and `o`.
//!
//! Coverage rules:
//! - status lines and data lines: every byte before the checksum character;
//! - `KEY:value;X` lines of VV, PP and II: `KEY:value`, **without** the `;`.
//!
//! Firmware quirks (VV/II only, opt-in, always counted): the checksum computed
//! over `KEY:value;` (n−1 bytes), over the text before a `<-` comment, or
//! simply wrong on the URG-04LX `SERI` line.

/// The SCIP checksum character of `bytes`.
pub fn checksum(bytes: &[u8]) -> u8 {
    let sum = bytes.iter().fold(0u8, |acc, &b| acc.wrapping_add(b));
    (sum & 0x3f) + 0x30
}

/// A line's checksum did not match, or the line was too short to carry one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ChecksumError {
    /// The line has no room for a checksum (or, for `KEY:value;X`, no `;`).
    #[error("line too short or malformed to carry a checksum")]
    Malformed,
    /// Computed and received checksum characters differ.
    #[error("checksum mismatch: computed {expected:?}, received {found:?}")]
    Mismatch {
        /// The checksum computed over the covered bytes.
        expected: char,
        /// The checksum character received.
        found: char,
    },
}

/// Which firmware quirk a leniently accepted `KEY:value;X` line showed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KvQuirk {
    /// The checksum also covers the `;` separator (n−1 bytes).
    IncludesSeparator,
    /// The checksum stops before a `<-` comment (some UTM-30LX firmware).
    StopsBeforeComment,
    /// The checksum is simply wrong on the `SERI` line (some URG-04LX firmware).
    SerialLine,
}

/// Verifies a status or data line (`payload` + checksum character) and returns
/// the payload.
pub fn verify_data_line(line: &[u8]) -> Result<&[u8], ChecksumError> {
    let Some((&sum, payload)) = line.split_last() else {
        return Err(ChecksumError::Malformed);
    };
    let expected = checksum(payload);
    if expected == sum {
        Ok(payload)
    } else {
        Err(ChecksumError::Mismatch {
            expected: expected as char,
            found: sum as char,
        })
    }
}

/// Verifies a `KEY:value;X` line and returns `KEY:value` with the quirk that
/// had to be tolerated (`None` when the checksum is exactly right). Quirks are
/// accepted only when `lenient` is set.
pub fn verify_kv_line(
    line: &[u8],
    lenient: bool,
) -> Result<(&[u8], Option<KvQuirk>), ChecksumError> {
    let n = line.len();
    if n < 2 || line[n - 2] != b';' {
        return Err(ChecksumError::Malformed);
    }
    let sum = line[n - 1];
    let payload = &line[..n - 2];
    let expected = checksum(payload);
    if expected == sum {
        return Ok((payload, None));
    }
    if lenient {
        if checksum(&line[..n - 1]) == sum {
            return Ok((payload, Some(KvQuirk::IncludesSeparator)));
        }
        if let Some(pos) = payload.windows(2).position(|w| w == b"<-") {
            if checksum(&payload[..pos]) == sum {
                return Ok((payload, Some(KvQuirk::StopsBeforeComment)));
            }
        }
        if payload.starts_with(b"SERI:") {
            return Ok((payload, Some(KvQuirk::SerialLine)));
        }
    }
    Err(ChecksumError::Mismatch {
        expected: expected as char,
        found: sum as char,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_checksums_match_the_documented_examples() {
        for (code, sum) in [
            (b"00", b'P'),
            (b"99", b'b'),
            (b"0E", b'e'),
            (b"02", b'R'),
            (b"03", b'S'),
            (b"04", b'T'),
            (b"10", b'Q'),
            (b"0L", b'l'),
        ] {
            assert_eq!(checksum(code), sum, "{}", String::from_utf8_lossy(code));
        }
    }

    #[test]
    fn kv_checksum_excludes_the_separator() {
        let line = b"MODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N";
        let (payload, quirk) = verify_kv_line(line, false).unwrap();
        assert_eq!(payload, b"MODL:URG-04LX(Hokuyo Automatic Co.,Ltd.)");
        assert_eq!(quirk, None);
        assert_eq!(checksum(&line[..line.len() - 1]), b'I');
    }

    #[test]
    fn kv_quirks_only_in_lenient_mode() {
        let mut line = b"SERI:H0706400;".to_vec();
        line.push(checksum(b"SERI:H0706400;"));
        assert!(verify_kv_line(&line, false).is_err());
        assert_eq!(
            verify_kv_line(&line, true).unwrap().1,
            Some(KvQuirk::IncludesSeparator)
        );

        let mut c = b"SCSP:Initial(600[rpm])<-Default setting by user;".to_vec();
        c.push(checksum(b"SCSP:Initial(600[rpm])"));
        assert!(verify_kv_line(&c, false).is_err());
        assert_eq!(
            verify_kv_line(&c, true).unwrap().1,
            Some(KvQuirk::StopsBeforeComment)
        );

        let wrong = b"SERI:H0706400;!";
        assert!(verify_kv_line(wrong, false).is_err());
        assert_eq!(
            verify_kv_line(wrong, true).unwrap().1,
            Some(KvQuirk::SerialLine)
        );
        assert!(verify_kv_line(b"PROD:x;!", true).is_err());
    }

    #[test]
    fn malformed_lines_are_typed_errors() {
        assert_eq!(verify_data_line(b""), Err(ChecksumError::Malformed));
        assert_eq!(verify_kv_line(b"A", true), Err(ChecksumError::Malformed));
        assert_eq!(
            verify_kv_line(b"DMIN:20:4", true),
            Err(ChecksumError::Malformed)
        );
        assert!(matches!(
            verify_data_line(b"00Q"),
            Err(ChecksumError::Mismatch { .. })
        ));
        assert_eq!(verify_data_line(b"00P"), Ok(&b"00"[..]));
    }
}
