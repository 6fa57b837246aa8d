//! Reply status codes and what they mean, per command where the meaning
//! differs (BM `02` is success, TM `04` is a mode error, MD `99` is data).

use super::command::CommandKind;

/// A two-character SCIP 2.0 status code such as `00`, `99` or `0E`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct StatusCode(pub [u8; 2]);

impl StatusCode {
    /// `00`: command accepted.
    pub const OK: StatusCode = StatusCode(*b"00");
    /// `99`: scan data follow (MD/MS/ME streams).
    pub const DATA: StatusCode = StatusCode(*b"99");
    /// `0B`: buffer shortage or command repeated; replies may be mismatched.
    pub const BUFFER_SHORTAGE: StatusCode = StatusCode(*b"0B");
    /// `0C`: missing or malformed parameters.
    pub const MISSING_PARAMETERS: StatusCode = StatusCode(*b"0C");
    /// `0D`: undefined command (also used for a command line that is too long).
    pub const TOO_LONG: StatusCode = StatusCode(*b"0D");
    /// `0E`: undefined command (the URG-04LX answers ME, ND, ... with this).
    pub const UNDEFINED: StatusCode = StatusCode(*b"0E");
    /// `0G`: tag longer than 16 characters.
    pub const TAG_TOO_LONG: StatusCode = StatusCode(*b"0G");
    /// `0H`: tag with invalid characters.
    pub const TAG_INVALID: StatusCode = StatusCode(*b"0H");
    /// `10`: denied (laser off for GD; measuring for TM).
    pub const DENIED: StatusCode = StatusCode(*b"10");

    /// A status code from two ASCII characters.
    pub const fn new(a: u8, b: u8) -> Self {
        StatusCode([a, b])
    }

    /// The numeric value when both characters are decimal digits.
    pub fn number(&self) -> Option<u8> {
        let [a, b] = self.0;
        (a.is_ascii_digit() && b.is_ascii_digit()).then(|| (a - b'0') * 10 + (b - b'0'))
    }

    /// The code as text, for messages.
    pub fn as_str(&self) -> &str {
        core::str::from_utf8(&self.0).unwrap_or("??")
    }

    /// True when the code means the command worked for `cmd` (`00`; `99` for
    /// streams; "already so" answers: BM `02`, CR `03`, SS `03`, HS `02`).
    pub fn is_success(&self, cmd: CommandKind) -> bool {
        use CommandKind as K;
        matches!(
            (&self.0, cmd),
            (b"00", _)
                | (b"99", K::Md | K::Ms | K::Me)
                | (b"02", K::Bm)
                | (b"03", K::Cr)
                | (b"03", K::Ss)
                | (b"02", K::Hs)
        )
    }

    /// What the code means as an answer to `cmd`, in words.
    pub fn meaning(&self, cmd: CommandKind) -> &'static str {
        use CommandKind as K;
        let scan = matches!(cmd, K::Gd | K::Gs | K::Ge | K::Md | K::Ms | K::Me);
        match (&self.0, cmd) {
            (b"00", _) => "OK",
            (b"99", K::Md | K::Ms | K::Me) => "scan data follow",
            (b"01", _) if scan => "start step is not numeric",
            (b"02", _) if scan => "end step is not numeric",
            (b"03", _) if scan => "cluster count is not numeric",
            (b"04", _) if scan => "end step out of range",
            (b"05", _) if scan => "end step is smaller than start step",
            (b"06", _) if scan => "skip count is not numeric",
            (b"07", _) if scan => "scan count is not numeric",
            (b"01", K::Bm) => "laser malfunction",
            (b"02", K::Bm) => "laser already on",
            (b"01", K::Tm) => "invalid control code",
            (b"02", K::Tm) => "already in time-adjust mode",
            (b"03", K::Tm) => "not in time-adjust mode",
            (b"04", K::Tm) => "time read while not in time-adjust mode",
            (b"01", K::Ss) => "bit rate is not numeric",
            (b"02", K::Ss) => "invalid bit rate",
            (b"03", K::Ss) => "already at that bit rate",
            (b"04", K::Ss) => "bit rate change not supported by this device",
            (b"01", K::Cr) => "motor speed is not numeric",
            (b"02", K::Cr) => "motor speed out of range",
            (b"03", K::Cr) => "already at that motor speed",
            (b"04", K::Cr) => "motor speed change not supported",
            (b"01", K::Hs) => "invalid sensitivity parameter",
            (b"02", K::Hs) => "already in that sensitivity mode",
            (b"03", K::Hs) => "sensitivity change not supported",
            (b"0A", _) => "could not create transmission data",
            (b"0B", _) => "buffer shortage or command repeated",
            (b"0C", _) => "missing or malformed parameters",
            (b"0D", _) => "undefined command or command too long",
            (b"0E", _) => "undefined command",
            (b"0F", _) => "missing parameters (or Ethernet unit)",
            (b"0G", _) => "tag longer than 16 characters",
            (b"0H", _) => "tag has invalid characters",
            (b"0I", _) => "sensor is in firmware-update mode",
            (b"0L", _) => "sensor is in an error state",
            (b"10", K::Gd | K::Gs | K::Ge) => "denied: laser is off",
            (b"10", K::Tm) => "denied: sensor is measuring",
            (b"10", _) => "denied in the current state",
            (b"98", _) => "resumed after a hardware fault cleared",
            _ => match self.number() {
                Some(21..=49) => "processing stopped to verify an error",
                Some(50..=97) => "hardware fault (laser, motor, ...)",
                _ => "unknown status",
            },
        }
    }
}

impl core::fmt::Display for StatusCode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The status line of a reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Status {
    /// A SCIP 2.0 two-character code (its checksum already verified).
    Scip2(StatusCode),
    /// A SCIP 1.1 one-character status (no checksum), e.g. `0` after the
    /// `SCIP2.0` switch, or `E` from a SCIP 1.1 sensor rejecting a command.
    Scip1(u8),
}

impl Status {
    /// The SCIP 2.0 code, if this is a SCIP 2.0 status.
    pub fn code(&self) -> Option<StatusCode> {
        match self {
            Status::Scip2(c) => Some(*c),
            Status::Scip1(_) => None,
        }
    }

    /// True when the status means success for `cmd`; a SCIP 1.1 `0` counts.
    pub fn is_success(&self, cmd: CommandKind) -> bool {
        match self {
            Status::Scip2(c) => c.is_success(cmd),
            Status::Scip1(b) => *b == b'0',
        }
    }

    /// The meaning in words for `cmd`.
    pub fn meaning(&self, cmd: CommandKind) -> &'static str {
        match self {
            Status::Scip2(c) => c.meaning(cmd),
            Status::Scip1(b'0') => "OK (SCIP 1.1 status)",
            Status::Scip1(_) => "error (SCIP 1.1 status): the sensor speaks SCIP 1.1",
        }
    }
}

impl core::fmt::Display for Status {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Status::Scip2(c) => write!(f, "{c}"),
            Status::Scip1(b) => write!(f, "{} (SCIP 1.1)", char::from(*b).escape_default()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meanings_depend_on_the_command() {
        let c = StatusCode(*b"02");
        assert!(c.is_success(CommandKind::Bm));
        assert!(!c.is_success(CommandKind::Gd));
        assert_eq!(c.meaning(CommandKind::Gd), "end step is not numeric");
        assert_eq!(c.meaning(CommandKind::Tm), "already in time-adjust mode");
        assert!(StatusCode::DATA.is_success(CommandKind::Md));
        assert!(StatusCode(*b"02").is_success(CommandKind::Hs));
        assert!(!StatusCode(*b"03").is_success(CommandKind::Hs));
        assert!(!StatusCode::DATA.is_success(CommandKind::Gd));
        assert_eq!(
            StatusCode(*b"55").meaning(CommandKind::Md),
            "hardware fault (laser, motor, ...)"
        );
        assert_eq!(
            StatusCode(*b"33").meaning(CommandKind::Md),
            "processing stopped to verify an error"
        );
        assert_eq!(
            StatusCode(*b"xx").meaning(CommandKind::Vv),
            "unknown status"
        );
        assert_eq!(
            StatusCode(*b"0E").meaning(CommandKind::Me),
            "undefined command"
        );
        assert!(Status::Scip1(b'0').is_success(CommandKind::Scip20));
        assert!(!Status::Scip1(b'E').is_success(CommandKind::Qt));
        assert_eq!(Status::Scip2(StatusCode::UNDEFINED).to_string(), "0E");
        assert_eq!(Status::Scip1(b'E').to_string(), "E (SCIP 1.1)");
        assert_eq!(StatusCode([0xff, b'0']).as_str(), "??");
    }
}
