//! Fault injection switches of the emulated URG, parsed from the
//! `--faults` list, e.g. `checksum=7,drop=11,crlf,split,stall=20:1.5,unplug=30:0.5`.
//!
//! Scan faults hit every N-th scan the emulator sends (counting from 1), so
//! a test knows exactly which scans were damaged; the emulator's log records
//! each one ([`super::SentScan::fault`]).

use std::fmt;

/// What was done to one scan on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScanFault {
    /// One data line's checksum character was changed.
    Checksum,
    /// One payload byte of a data line was left out.
    DroppedByte,
    /// One extra payload byte was inserted into a data line.
    ExtraByte,
    /// The scan was replaced by an error status block (no data).
    ErrorStatus,
    /// The scan is intact but repeats the previous scan's timestamp.
    StuckClock,
}

impl ScanFault {
    /// Whether the scan's data were damaged (a correct driver discards it).
    pub fn corrupts(&self) -> bool {
        !matches!(self, ScanFault::ErrorStatus | ScanFault::StuckClock)
    }

    /// Whether a correct driver still delivers the scan.
    pub fn delivered(&self) -> bool {
        matches!(self, ScanFault::StuckClock)
    }
}

/// Every fault switch; all off by default.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Faults {
    /// Corrupt a data-line checksum of every N-th scan (0 = never).
    pub(crate) checksum_every: u32,
    /// Drop one byte of every N-th scan.
    pub(crate) drop_every: u32,
    /// Insert one extra byte into every N-th scan.
    pub(crate) extra_every: u32,
    /// Replace every N-th scan by an error status block.
    pub(crate) status_every: u32,
    /// Repeat the previous timestamp in every N-th scan (a stuck clock).
    pub(crate) stuck_every: u32,
    /// After the N-th scan the firmware hangs: no scans, no answers, except
    /// to RB twice (reboot), which cures it. Happens once.
    pub(crate) hang_after: u32,
    /// Send a line of line noise (control and non-ASCII bytes) before every
    /// N-th scan; the scan itself is intact.
    pub(crate) noise_every: u32,
    /// The status code used by `status` (a hardware fault by default).
    pub(crate) status_code: [u8; 2],
    /// End lines with CR LF instead of LF.
    pub crlf: bool,
    /// Split every write at random points, with short pauses between parts.
    pub(crate) split_writes: bool,
    /// After every N-th scan, go silent for the given seconds (no scans, input
    /// left unread), then carry on.
    pub stall: Option<(u32, f64)>,
    /// Start the 24-bit clock 2 s before it wraps.
    pub(crate) clock_wrap: bool,
    /// A URG-04LX firmware without the undocumented `FF` intensity mode: a
    /// request for it is refused (status `03`, as for a bad cluster count).
    pub(crate) no_ff: bool,
    /// After every N-th scan, unplug for the given seconds, then replug (a
    /// new pty, the sensor rebooted).
    pub unplug: Option<(u32, f64)>,
}

/// A `--faults` list that could not be parsed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("bad fault `{item}`: {why} (known: checksum=N, drop=N, extra=N, status=N[:CODE], stuck=N, noise=N, hang=N, crlf, split, stall=N:SECONDS, wrap, unplug=N:SECONDS, no-ff)")]
pub struct FaultSpecError {
    /// The offending item.
    pub item: String,
    /// What is wrong with it.
    pub why: String,
}

fn every(item: &str, v: Option<&str>) -> Result<u32, FaultSpecError> {
    let bad = |why: &str| FaultSpecError {
        item: item.to_string(),
        why: why.to_string(),
    };
    let v = v.ok_or_else(|| bad("needs =N (every N-th scan)"))?;
    match v.parse::<u32>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(bad("N must be a whole number > 0")),
    }
}

fn every_for(item: &str, v: Option<&str>) -> Result<(u32, f64), FaultSpecError> {
    let bad = |why: &str| FaultSpecError {
        item: item.to_string(),
        why: why.to_string(),
    };
    let (n, s) = v
        .and_then(|v| v.split_once(':'))
        .ok_or_else(|| bad("needs =N:SECONDS"))?;
    let n = every(item, Some(n))?;
    match s.parse::<f64>() {
        Ok(d) if d.is_finite() && d > 0.0 => Ok((n, d)),
        _ => Err(bad("SECONDS must be a positive number")),
    }
}

impl std::str::FromStr for Faults {
    type Err = FaultSpecError;
    fn from_str(spec: &str) -> Result<Self, FaultSpecError> {
        let mut f = Faults {
            status_code: *b"50",
            ..Faults::default()
        };
        for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (name, value) = match item.split_once('=') {
                Some((n, v)) => (n, Some(v)),
                None => (item, None),
            };
            let flag = |b: &mut bool| {
                if value.is_some() {
                    Err(FaultSpecError {
                        item: item.to_string(),
                        why: "takes no value".to_string(),
                    })
                } else {
                    *b = true;
                    Ok(())
                }
            };
            match name {
                "checksum" => f.checksum_every = every(item, value)?,
                "drop" => f.drop_every = every(item, value)?,
                "extra" => f.extra_every = every(item, value)?,
                "status" => {
                    let (n, code) = match value.and_then(|v| v.split_once(':')) {
                        Some((n, c)) => (Some(n), Some(c)),
                        None => (value, None),
                    };
                    f.status_every = every(item, n)?;
                    if let Some(c) = code {
                        let b = c.as_bytes();
                        if b.len() != 2 || !b.iter().all(|x| x.is_ascii_alphanumeric()) {
                            return Err(FaultSpecError {
                                item: item.to_string(),
                                why: "CODE must be two letters or digits".to_string(),
                            });
                        }
                        f.status_code = [b[0], b[1]];
                    }
                }
                "stuck" => f.stuck_every = every(item, value)?,
                "noise" => f.noise_every = every(item, value)?,
                "hang" => f.hang_after = every(item, value)?,
                "crlf" => flag(&mut f.crlf)?,
                "split" => flag(&mut f.split_writes)?,
                "wrap" => flag(&mut f.clock_wrap)?,
                "no-ff" => flag(&mut f.no_ff)?,
                "stall" => f.stall = Some(every_for(item, value)?),
                "unplug" => f.unplug = Some(every_for(item, value)?),
                _ => {
                    return Err(FaultSpecError {
                        item: item.to_string(),
                        why: "unknown fault".to_string(),
                    })
                }
            }
        }
        Ok(f)
    }
}

impl Faults {
    /// The fault (if any) for the `n`-th scan sent (from 1).
    pub(crate) fn scan_fault(&self, n: u64) -> Option<ScanFault> {
        let hit = |every: u32| every > 0 && n.is_multiple_of(u64::from(every));
        if hit(self.checksum_every) {
            Some(ScanFault::Checksum)
        } else if hit(self.drop_every) {
            Some(ScanFault::DroppedByte)
        } else if hit(self.extra_every) {
            Some(ScanFault::ExtraByte)
        } else if hit(self.status_every) {
            Some(ScanFault::ErrorStatus)
        } else if hit(self.stuck_every) {
            Some(ScanFault::StuckClock)
        } else {
            None
        }
    }
}

impl fmt::Display for ScanFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ScanFault::Checksum => "corrupted checksum",
            ScanFault::DroppedByte => "dropped byte",
            ScanFault::ExtraByte => "extra byte",
            ScanFault::ErrorStatus => "error status",
            ScanFault::StuckClock => "repeated timestamp",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_switch() {
        let f: Faults =
            "checksum=7, drop=11,extra=13,status=17:0L,crlf,split,stall=20:1.5,wrap,unplug=30:0.5,no-ff"
                .parse()
                .unwrap();
        assert_eq!(f.checksum_every, 7);
        assert_eq!(f.drop_every, 11);
        assert_eq!(f.extra_every, 13);
        assert_eq!(f.status_every, 17);
        assert_eq!(&f.status_code, b"0L");
        assert!(f.crlf && f.split_writes && f.clock_wrap && f.no_ff);
        assert_eq!(f.stall, Some((20, 1.5)));
        assert_eq!(f.unplug, Some((30, 0.5)));
        assert_eq!(f.scan_fault(7), Some(ScanFault::Checksum));
        assert_eq!(f.scan_fault(11), Some(ScanFault::DroppedByte));
        assert_eq!(f.scan_fault(1), None);
        let none: Faults = "".parse().unwrap();
        assert_eq!(none.scan_fault(1), None);
    }

    #[test]
    fn bad_specs_are_typed_errors() {
        for bad in [
            "nope",
            "checksum",
            "checksum=0",
            "checksum=x",
            "crlf=1",
            "stall=3",
            "stall=3:-1",
            "status=2:ABC",
        ] {
            let e = bad.parse::<Faults>().unwrap_err();
            assert!(e.to_string().contains("bad fault"), "{bad}: {e}");
        }
    }
}
