//! Bytes → lines. Accepts LF, CR or CRLF as one line end, never assumes
//! read() boundaries (state carries over between calls), and bounds the line
//! length: a longer line is reported once and its rest discarded.

use super::capacity::SCIP_MAX_LINE;

/// What one byte completed.
#[derive(Debug, PartialEq, Eq)]
pub enum LineEvent<'a> {
    /// A complete line without its terminator (may be empty: end of a reply).
    Line(&'a [u8]),
    /// A complete line that held bytes no SCIP line carries (control or
    /// non-ASCII bytes): line noise or a desync.
    Garbage,
    /// The line grew past [`SCIP_MAX_LINE`]; its rest up to the next line end
    /// is discarded silently.
    Overlong,
}

/// The line framer state.
#[derive(Clone, Debug, Default)]
pub struct LineFramer {
    buf: heapless::Vec<u8, SCIP_MAX_LINE>,
    clear_next: bool,
    after_cr: bool,
    overflowed: bool,
    garbage: bool,
}

impl LineFramer {
    /// An empty framer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets any partial line.
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// True when no partial line is buffered.
    pub fn is_idle(&self) -> bool {
        (self.buf.is_empty() || self.clear_next) && !self.overflowed && !self.garbage
    }

    /// Feeds bytes until one completes an event; returns how many bytes were
    /// consumed and that event. Same result as [`LineFramer::push`] byte by
    /// byte, but copies whole runs at once (the scan hot path).
    pub fn push_slice(&mut self, input: &[u8]) -> (usize, Option<LineEvent<'_>>) {
        let mut at = 0;
        while at < input.len() {
            if self.clear_next {
                self.buf.clear();
                self.clear_next = false;
            }
            if self.after_cr {
                self.after_cr = false;
                if input[at] == b'\n' {
                    at += 1;
                    continue;
                }
            }
            let rest = &input[at..];
            let end = rest
                .iter()
                .position(|&b| b == b'\n' || b == b'\r')
                .unwrap_or(rest.len());
            let run = &rest[..end];
            if !self.overflowed {
                let room = SCIP_MAX_LINE - self.buf.len();
                if run.len() > room {
                    // Same as byte by byte: the byte that does not fit reports.
                    let fits = &run[..room];
                    if fits.iter().any(|b| !(0x20..=0x7e).contains(b)) {
                        self.garbage = true;
                    }
                    let _ = self.buf.extend_from_slice(fits);
                    self.overflowed = true;
                    self.garbage = false;
                    return (at + room + 1, Some(LineEvent::Overlong));
                }
                if run.iter().any(|b| !(0x20..=0x7e).contains(b)) {
                    self.garbage = true;
                }
                let _ = self.buf.extend_from_slice(run);
            }
            at += end;
            if at == input.len() {
                break;
            }
            // A line end.
            let byte = input[at];
            at += 1;
            self.after_cr = byte == b'\r';
            self.clear_next = true;
            let overflowed = core::mem::replace(&mut self.overflowed, false);
            let garbage = core::mem::replace(&mut self.garbage, false);
            if overflowed {
                continue;
            }
            return if garbage {
                (at, Some(LineEvent::Garbage))
            } else {
                (at, Some(LineEvent::Line(&self.buf)))
            };
        }
        (input.len(), None)
    }

    /// Feeds one byte; returns the event it completed, if any.
    pub fn push(&mut self, byte: u8) -> Option<LineEvent<'_>> {
        if self.clear_next {
            self.buf.clear();
            self.clear_next = false;
        }
        let after_cr = core::mem::replace(&mut self.after_cr, false);
        match byte {
            b'\n' if after_cr => None,
            b'\n' | b'\r' => {
                self.after_cr = byte == b'\r';
                self.clear_next = true;
                let overflowed = core::mem::replace(&mut self.overflowed, false);
                let garbage = core::mem::replace(&mut self.garbage, false);
                if overflowed {
                    None
                } else if garbage {
                    Some(LineEvent::Garbage)
                } else {
                    Some(LineEvent::Line(&self.buf))
                }
            }
            _ if self.overflowed => None,
            _ => {
                if !(0x20..=0x7e).contains(&byte) {
                    self.garbage = true;
                }
                if self.buf.push(byte).is_err() {
                    self.overflowed = true;
                    self.garbage = false;
                    return Some(LineEvent::Overlong);
                }
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(input: &[u8]) -> Vec<Result<Vec<u8>, &'static str>> {
        let mut f = LineFramer::new();
        let mut out = Vec::new();
        for &b in input {
            match f.push(b) {
                Some(LineEvent::Line(l)) => out.push(Ok(l.to_vec())),
                Some(LineEvent::Garbage) => out.push(Err("garbage")),
                Some(LineEvent::Overlong) => out.push(Err("overlong")),
                None => {}
            }
        }
        out
    }

    #[test]
    fn lf_cr_and_crlf_are_one_line_end_each() {
        let want = vec![Ok(b"VV".to_vec()), Ok(b"00P".to_vec()), Ok(vec![])];
        assert_eq!(lines(b"VV\n00P\n\n"), want);
        assert_eq!(lines(b"VV\r00P\r\r"), want);
        assert_eq!(lines(b"VV\r\n00P\r\n\r\n"), want);
        assert_eq!(lines(b"VV\r\n00P\n\r"), want);
    }

    #[test]
    fn overlong_lines_are_reported_once_and_skipped() {
        let mut input = vec![b'A'; SCIP_MAX_LINE + 50];
        input.extend_from_slice(b"\nok\n");
        assert_eq!(lines(&input), vec![Err("overlong"), Ok(b"ok".to_vec())]);
    }

    #[test]
    fn control_bytes_make_a_garbage_line() {
        assert_eq!(
            lines(b"0\x001\nok\n"),
            vec![Err("garbage"), Ok(b"ok".to_vec())]
        );
        assert_eq!(lines(b"\xff\n"), vec![Err("garbage")]);
    }

    /// The bulk path gives exactly the events of the byte path, for inputs
    /// mixing every line end, noise and overlong lines, cut at every offset.
    #[test]
    fn push_slice_matches_push() {
        let mut input = b"VV\r\n00P\rA\x01B\n\n\r\n".to_vec();
        input.extend(core::iter::repeat_n(b'x', SCIP_MAX_LINE + 3));
        input.extend_from_slice(b"\r\nok\n");
        input.extend(core::iter::repeat_n(b'y', SCIP_MAX_LINE));
        input.extend_from_slice(b"\n\r");
        let want = lines(&input);
        for cut in 0..input.len() {
            let mut f = LineFramer::new();
            let mut got = Vec::new();
            for part in [&input[..cut], &input[cut..]] {
                let mut rest = part;
                while !rest.is_empty() {
                    let (n, ev) = f.push_slice(rest);
                    assert!(n >= 1);
                    rest = &rest[n..];
                    match ev {
                        Some(LineEvent::Line(l)) => got.push(Ok(l.to_vec())),
                        Some(LineEvent::Garbage) => got.push(Err("garbage")),
                        Some(LineEvent::Overlong) => got.push(Err("overlong")),
                        None => {}
                    }
                }
            }
            assert_eq!(got, want, "cut at {cut}");
        }
    }

    #[test]
    fn a_line_of_exactly_the_capacity_passes() {
        let mut input = vec![b'0'; SCIP_MAX_LINE];
        input.push(b'\n');
        assert_eq!(lines(&input), vec![Ok(vec![b'0'; SCIP_MAX_LINE])]);
    }
}
