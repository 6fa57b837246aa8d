//! Lines → replies. A reply is an echo line, a status line, zero or more
//! checksummed data lines and an empty line. Every checksum is verified with
//! its coverage rule as lines arrive; a broken reply is reported once as a
//! typed [`FrameError`] and the decoder resynchronises at the next reply
//! boundary (empty line) or at the next line that is a valid command echo
//! (a lost empty line, or the `QT` echo arriving in the middle of a stream).
//!
//! Fixed capacity, no allocation: a completed [`RawReply`] borrows the
//! decoder's buffers until the next call to [`Decoder::feed`].

use super::capacity::{SCIP_MAX_LINE, SCIP_MAX_REPLY_BODY, SCIP_MAX_REPLY_LINES};

use super::checksum::{self, ChecksumError};
use super::command::{CommandKind, TaggedCommand};
use super::framer::{LineEvent, LineFramer};
use super::status::{Status, StatusCode};

/// Decoder settings.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecoderOptions {
    /// Accept known firmware checksum quirks on VV and II `KEY:value;X` lines
    /// (`;` included, stops before `<-`, wrong `SERI`). Each acceptance is
    /// counted in [`DecoderStats::lenient_accepts`]. Never applies to PP,
    /// status, timestamp or scan data lines.
    pub lenient_kv: bool,
}

/// Counters of everything the decoder saw, for health reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecoderStats {
    /// Bytes fed.
    pub bytes: u64,
    /// Lines completed (including empty ones).
    pub lines: u64,
    /// Complete, checksum-verified replies delivered.
    pub replies: u64,
    /// Status lines whose checksum failed.
    pub status_checksum_errors: u64,
    /// Data, timestamp and TM1 lines whose checksum failed.
    pub data_checksum_errors: u64,
    /// `KEY:value;X` lines whose checksum failed.
    pub kv_checksum_errors: u64,
    /// `KEY:value;X` lines accepted only thanks to a lenient firmware quirk.
    pub lenient_accepts: u64,
    /// SCIP 1.1 (one-character, unchecked) status lines seen.
    pub scip1_statuses: u64,
    /// Lines longer than the line capacity.
    pub overlong_lines: u64,
    /// Lines holding control or non-ASCII bytes.
    pub garbage_lines: u64,
    /// Replies cut short by the echo of a new command (`QT` in a stream, a lost
    /// empty line).
    pub truncated_replies: u64,
    /// Replies dropped for any reason (each also reported as an event).
    pub dropped_replies: u64,
    /// Times the decoder had to skip input to find a reply boundary.
    pub desyncs: u64,
    /// The most recent frame error, for health reports.
    pub last_error: Option<FrameError>,
}

impl DecoderStats {
    /// All checksum failures together.
    pub fn checksum_errors(&self) -> u64 {
        self.status_checksum_errors + self.data_checksum_errors + self.kv_checksum_errors
    }
}

/// Why input was dropped. Each is reported once; the decoder then skips to the
/// next reply boundary by itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// A line longer than the line capacity.
    #[error("line longer than {SCIP_MAX_LINE} bytes (desync or line noise)")]
    Overlong,
    /// A line holding control or non-ASCII bytes.
    #[error("line holds control or non-ASCII bytes (line noise)")]
    Garbage,
    /// A line where an echo was expected that cannot be one.
    #[error("expected a command echo, got a line that cannot be one (desync)")]
    UnexpectedLine,
    /// The status line has the wrong length.
    #[error("status line of {0} bytes (expected 3, or 1 for SCIP 1.1)")]
    BadStatusLine(usize),
    /// The status checksum failed.
    #[error("status line checksum: {0}")]
    StatusChecksum(ChecksumError),
    /// A data line checksum failed (`line` counts from 0 after the status).
    #[error("data line {line} checksum: {error}")]
    DataChecksum {
        /// Index of the data line in its reply.
        line: u16,
        /// The mismatch.
        error: ChecksumError,
    },
    /// A `KEY:value;X` line checksum failed.
    #[error("parameter line {line} checksum: {error}")]
    KvChecksum {
        /// Index of the line in its reply.
        line: u16,
        /// The mismatch.
        error: ChecksumError,
    },
    /// The reply carries more data than any valid reply.
    #[error("reply longer than the largest valid reply")]
    BodyOverflow,
    /// The reply was cut short by the echo of a new command (e.g. `QT` in the
    /// middle of an MD stream, or a lost empty line).
    #[error("reply cut short by the echo of a new {0:?} command")]
    Truncated(Option<CommandKind>),
}

/// A complete reply whose every checksum has been verified, borrowing the
/// decoder's buffers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawReply<'a> {
    /// The echo line, as received.
    pub echo: &'a [u8],
    /// The status line.
    pub status: Status,
    body: &'a [u8],
    line_ends: &'a [u16],
    /// Lines accepted only thanks to a lenient firmware quirk.
    pub quirks: u16,
}

impl<'a> RawReply<'a> {
    /// A reply from its parts (used by tests and by the encoders' round trip).
    /// `body` is the payloads concatenated, `line_ends` the end offset of each.
    pub fn from_parts(
        echo: &'a [u8],
        status: Status,
        body: &'a [u8],
        line_ends: &'a [u16],
    ) -> Self {
        RawReply {
            echo,
            status,
            body,
            line_ends,
            quirks: 0,
        }
    }

    /// The command kind named by the echo, when it is a known one.
    pub fn kind(&self) -> Option<CommandKind> {
        if self.echo == b"SCIP2.0" {
            return Some(CommandKind::Scip20);
        }
        match self.echo {
            [a, b, ..] => CommandKind::from_mnemonic([*a, *b]),
            _ => None,
        }
    }

    /// Number of data lines.
    pub fn line_count(&self) -> usize {
        self.line_ends.len()
    }

    /// Payload of data line `i` (checksum and, for `KEY:value;X`, the `;X` removed).
    pub fn line(&self, i: usize) -> Option<&'a [u8]> {
        let end = usize::from(*self.line_ends.get(i)?);
        let start = if i == 0 {
            0
        } else {
            usize::from(self.line_ends[i - 1])
        };
        self.body.get(start..end)
    }

    /// Payloads of all data lines in order.
    pub fn lines(&self) -> impl Iterator<Item = &'a [u8]> + '_ {
        (0..self.line_ends.len()).filter_map(|i| self.line(i))
    }

    /// The payloads of lines `from..` concatenated (scan values straddle lines).
    pub fn joined_from(&self, from: usize) -> &'a [u8] {
        if from >= self.line_ends.len() {
            return &[];
        }
        let start = if from == 0 {
            0
        } else {
            usize::from(self.line_ends[from - 1])
        };
        self.body.get(start..).unwrap_or(&[])
    }
}

/// What [`Decoder::feed`] delivers.
#[derive(Debug, PartialEq, Eq)]
pub enum Event<'a> {
    /// A complete, verified reply.
    Reply(RawReply<'a>),
    /// Input was dropped; the decoder resynchronises by itself.
    Error(FrameError),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Between replies: the next non-empty line is an echo.
    Idle,
    /// Echo seen; `tentative` when it was only guessed while resynchronising.
    Status { tentative: bool },
    /// Status seen; data lines until the empty line.
    Body,
    /// The reply is complete; buffers hold it until the next line starts.
    Done,
    /// Skipping to the next reply boundary.
    Discard,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    Reply,
    Error(FrameError),
}

#[derive(Debug)]
struct Assembler {
    state: State,
    kv: bool,
    lenient_allowed: bool,
    options: DecoderOptions,
    echo: heapless::Vec<u8, SCIP_MAX_LINE>,
    status: Status,
    body: heapless::Vec<u8, SCIP_MAX_REPLY_BODY>,
    line_ends: heapless::Vec<u16, SCIP_MAX_REPLY_LINES>,
    quirks: u16,
    stats: DecoderStats,
}

/// The SCIP reply decoder: feed it bytes as they come, get typed events.
#[derive(Debug)]
pub struct Decoder {
    framer: LineFramer,
    asm: Assembler,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new(DecoderOptions::default())
    }
}

fn looks_like_echo(line: &[u8]) -> bool {
    line.len() >= 2
        && line.len() <= 2 + 13 + 1 + 16
        && line[0].is_ascii_uppercase()
        && line[1].is_ascii_uppercase()
}

/// The command echo a broken line holds, if any: the whole line when it is a
/// valid command, or a `QT`/`RS` echo glued to the end of a cut-off line (the
/// stop command's echo arriving in the middle of a stream).
fn echo_in(line: &[u8]) -> Option<&[u8]> {
    if TaggedCommand::parse(line).is_ok() {
        return Some(line);
    }
    let tail = line.get(line.len().checked_sub(2)?..)?;
    (tail == b"QT" || tail == b"RS").then_some(tail)
}

impl Decoder {
    /// A decoder with the given options.
    pub fn new(options: DecoderOptions) -> Self {
        Decoder {
            framer: LineFramer::new(),
            asm: Assembler {
                state: State::Idle,
                kv: false,
                lenient_allowed: false,
                options,
                echo: heapless::Vec::new(),
                status: Status::Scip1(b'0'),
                body: heapless::Vec::new(),
                line_ends: heapless::Vec::new(),
                quirks: 0,
                stats: DecoderStats::default(),
            },
        }
    }

    /// The counters so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.asm.stats
    }

    /// The options in use.
    pub fn options(&self) -> DecoderOptions {
        self.asm.options
    }

    /// Changes the options (e.g. lenient mode once the model is known).
    pub fn set_options(&mut self, options: DecoderOptions) {
        self.asm.options = options;
    }

    /// Forgets any partial line or reply (after a reconnect); keeps the counters.
    pub fn reset(&mut self) {
        self.framer.reset();
        self.asm.state = State::Idle;
        self.asm.clear();
    }

    /// True when no partial line or reply is buffered.
    pub fn is_idle(&self) -> bool {
        self.framer.is_idle() && matches!(self.asm.state, State::Idle | State::Done)
    }

    /// Consumes bytes from `input` up to and including the first one that
    /// completes an event; returns how many bytes were consumed and the event.
    /// Call again with the rest of the input until it is all consumed.
    pub fn feed(&mut self, input: &[u8]) -> (usize, Option<Event<'_>>) {
        let mut at = 0;
        while at < input.len() {
            let (n, line) = self.framer.push_slice(&input[at..]);
            at += n;
            let Some(line) = line else {
                continue;
            };
            if let Some(outcome) = self.asm.on_line(line) {
                self.asm.stats.bytes += at as u64;
                if let Outcome::Error(e) = outcome {
                    self.asm.stats.last_error = Some(e);
                }
                return (at, Some(self.asm.event(outcome)));
            }
        }
        self.asm.stats.bytes += input.len() as u64;
        (input.len(), None)
    }

    /// Feeds all of `input`, handing every event to `on_event` in order.
    pub fn feed_each(&mut self, mut input: &[u8], mut on_event: impl FnMut(Event<'_>)) {
        while !input.is_empty() {
            let (n, ev) = self.feed(input);
            input = &input[n..];
            if let Some(ev) = ev {
                on_event(ev);
            }
        }
    }
}

impl Assembler {
    fn clear(&mut self) {
        self.echo.clear();
        self.body.clear();
        self.line_ends.clear();
        self.quirks = 0;
    }

    fn event(&self, outcome: Outcome) -> Event<'_> {
        match outcome {
            Outcome::Reply => Event::Reply(RawReply {
                echo: &self.echo,
                status: self.status,
                body: &self.body,
                line_ends: &self.line_ends,
                quirks: self.quirks,
            }),
            Outcome::Error(e) => Event::Error(e),
        }
    }

    fn fail(&mut self, e: FrameError) -> Option<Outcome> {
        self.stats.desyncs += 1;
        if matches!(self.state, State::Status { .. } | State::Body) {
            self.stats.dropped_replies += 1;
        }
        self.state = State::Discard;
        Some(Outcome::Error(e))
    }

    fn start_reply(&mut self, line: &[u8], tentative: bool) {
        self.clear();
        // The caller checked the length against the line capacity.
        let _ = self.echo.extend_from_slice(line);
        let kind = match line {
            [a, b, ..] => CommandKind::from_mnemonic([*a, *b]),
            _ => None,
        };
        self.kv = kind.is_some_and(|k| k.has_kv_lines());
        self.lenient_allowed = matches!(kind, Some(CommandKind::Vv | CommandKind::Ii));
        self.state = State::Status { tentative };
    }

    fn interrupted(&mut self, line: &[u8]) -> Option<Outcome> {
        let by = match line {
            [a, b, ..] => CommandKind::from_mnemonic([*a, *b]),
            _ => None,
        };
        self.stats.truncated_replies += 1;
        self.stats.dropped_replies += 1;
        self.stats.desyncs += 1;
        // Tentative: if no status follows, skip on silently (already reported).
        self.start_reply(line, true);
        Some(Outcome::Error(FrameError::Truncated(by)))
    }

    fn on_line(&mut self, ev: LineEvent<'_>) -> Option<Outcome> {
        self.stats.lines += 1;
        let line = match ev {
            LineEvent::Line(l) => l,
            LineEvent::Garbage => {
                self.stats.garbage_lines += 1;
                return self.noise(FrameError::Garbage);
            }
            LineEvent::Overlong => {
                self.stats.overlong_lines += 1;
                return self.noise(FrameError::Overlong);
            }
        };
        match self.state {
            State::Idle | State::Done => {
                if line.is_empty() {
                    self.state = State::Idle;
                    return None;
                }
                if looks_like_echo(line) {
                    self.start_reply(line, false);
                    None
                } else {
                    self.state = State::Idle;
                    self.fail(FrameError::UnexpectedLine)
                }
            }
            State::Discard => {
                if line.is_empty() {
                    self.state = State::Idle;
                } else if let Some(echo) = echo_in(line) {
                    self.start_reply(echo, true);
                }
                None
            }
            State::Status { tentative } => self.on_status(line, tentative),
            State::Body => self.on_body(line),
        }
    }

    /// Noise inside a reply drops it; noise between replies is reported and
    /// skipped up to the next boundary.
    fn noise(&mut self, e: FrameError) -> Option<Outcome> {
        match self.state {
            State::Discard => None,
            State::Status { tentative: true } => {
                self.state = State::Discard;
                None
            }
            _ => self.fail(e),
        }
    }

    fn on_status(&mut self, line: &[u8], tentative: bool) -> Option<Outcome> {
        let status = match line.len() {
            1 => Ok(Status::Scip1(line[0])),
            3 => match checksum::verify_data_line(line) {
                Ok(code) => Ok(Status::Scip2(StatusCode([code[0], code[1]]))),
                Err(e) => Err(FrameError::StatusChecksum(e)),
            },
            n => Err(FrameError::BadStatusLine(n)),
        };
        match status {
            Ok(s) => {
                if matches!(s, Status::Scip1(_)) {
                    self.stats.scip1_statuses += 1;
                }
                self.status = s;
                self.state = State::Body;
                None
            }
            Err(_) if tentative => {
                // The guessed echo was not one; keep skipping.
                self.state = if line.is_empty() {
                    State::Idle
                } else {
                    State::Discard
                };
                None
            }
            Err(e) => {
                if let Some(echo) = echo_in(line) {
                    return self.interrupted(echo);
                }
                if matches!(e, FrameError::StatusChecksum(_)) {
                    self.stats.status_checksum_errors += 1;
                }
                if line.is_empty() {
                    // Echo then an empty line: the reply is already over.
                    self.stats.desyncs += 1;
                    self.stats.dropped_replies += 1;
                    self.state = State::Idle;
                    return Some(Outcome::Error(e));
                }
                self.fail(e)
            }
        }
    }

    fn on_body(&mut self, line: &[u8]) -> Option<Outcome> {
        if line.is_empty() {
            self.state = State::Done;
            self.stats.replies += 1;
            return Some(Outcome::Reply);
        }
        let index = self.line_ends.len() as u16;
        let verified = if self.kv {
            let lenient = self.options.lenient_kv && self.lenient_allowed;
            checksum::verify_kv_line(line, lenient).map(|(payload, quirk)| {
                if quirk.is_some() {
                    self.quirks += 1;
                    self.stats.lenient_accepts += 1;
                }
                payload
            })
        } else {
            checksum::verify_data_line(line)
        };
        match verified {
            Ok(payload) => {
                if self.body.extend_from_slice(payload).is_err()
                    || self.line_ends.push(self.body.len() as u16).is_err()
                {
                    return self.fail(FrameError::BodyOverflow);
                }
                None
            }
            Err(error) => {
                if let Some(echo) = echo_in(line) {
                    return self.interrupted(echo);
                }
                if self.kv {
                    self.stats.kv_checksum_errors += 1;
                    self.fail(FrameError::KvChecksum { line: index, error })
                } else {
                    self.stats.data_checksum_errors += 1;
                    self.fail(FrameError::DataChecksum { line: index, error })
                }
            }
        }
    }
}
