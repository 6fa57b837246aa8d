//! Typed replies: a verified [`RawReply`] becomes a [`Reply`] (its echo parsed
//! back into the command, its status, and a typed body), and every reply can
//! be encoded byte-exactly as a URG sends it (echo, status + checksum, data
//! lines of at most 64 characters + checksum, empty line).

use super::command::{Command, CommandError, CommandKind, TaggedCommand, TimeControl};
use super::decoder::RawReply;
use super::encoding::{self, EncodingError, Width};
use super::params::{Echo, SensorInfo, SensorParams, VersionInfo};
use super::scan::{ScanData, ScanError};
use super::sink::{ByteSink, EncodeError};
use super::status::{Status, StatusCode};

/// Characters of payload per data line.
pub const DATA_LINE_CHARS: usize = 64;

/// Why a verified reply could not be turned into typed values.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    /// The echo is not a command this codec knows.
    #[error("echo {0:?} is not a known command")]
    UnknownEcho(Echo),
    /// The echo does not parse as a command.
    #[error("echo is malformed: {0}")]
    BadEcho(CommandError),
    /// A text line is not ASCII text.
    #[error("parameter line is not text")]
    NotText,
    /// A parameter line has no `:`.
    #[error("parameter line has no KEY:value form")]
    NotKeyValue,
    /// A required PP key is missing.
    #[error("PP reply lacks {0}")]
    MissingParameter(&'static str),
    /// A PP value is not a number or is inconsistent.
    #[error("PP value {0} is not valid")]
    BadParameter(&'static str),
    /// The reply has the wrong number of data lines for its command.
    #[error("{kind:?} reply has {got} data lines, expected {expected}")]
    LineCount {
        /// The command.
        kind: CommandKind,
        /// Lines received.
        got: usize,
        /// Lines expected.
        expected: usize,
    },
    /// A timestamp or encoded field is malformed.
    #[error("encoded field: {0}")]
    Encoding(#[from] EncodingError),
    /// The scan data do not match the echoed request.
    #[error("scan: {0}")]
    Scan(#[from] ScanError),
}

/// The typed body of a reply. The text replies are held by value (about
/// 1.2 KB for II): no allocation, one copy on the stack per reply.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum ReplyBody<'a> {
    /// No data lines (BM, QT, RS, TM0, TM2, SS, CR, HS, the `SCIP2.0` switch,
    /// the first answer to MD/MS/ME, and every error status).
    Empty,
    /// VV.
    Version(VersionInfo),
    /// PP.
    Params(SensorParams),
    /// II.
    Info(SensorInfo),
    /// TM1: the sensor clock (ms, 24 bits).
    Time(u32),
    /// GD/GS/GE, or one scan of an MD/MS/ME stream (status `99`).
    Scan(ScanData<'a>),
}

/// A decoded reply.
#[derive(Clone, Debug, PartialEq)]
pub struct Reply<'a> {
    /// The echoed command (for MD/MS/ME the count is the scans remaining).
    pub echo: TaggedCommand,
    /// The status.
    pub status: Status,
    /// The body.
    pub body: ReplyBody<'a>,
}

impl<'a> RawReply<'a> {
    /// Decodes the reply into typed values. Error statuses give an empty body
    /// (the status says why); a success with the wrong data is an error.
    pub fn decode(&self) -> Result<Reply<'a>, ReplyError> {
        let echo = match TaggedCommand::parse(self.echo) {
            Ok(c) => c,
            Err(CommandError::Undefined) => {
                return Err(ReplyError::UnknownEcho(Echo::from_bytes_lossy(self.echo)))
            }
            Err(e) => return Err(ReplyError::BadEcho(e)),
        };
        let kind = echo.command.kind();
        let success = match self.status {
            Status::Scip2(c) => c == StatusCode::OK || c == StatusCode::DATA,
            Status::Scip1(_) => false,
        };
        let expect_lines = |n: usize| {
            if self.line_count() == n {
                Ok(())
            } else {
                Err(ReplyError::LineCount {
                    kind,
                    got: self.line_count(),
                    expected: n,
                })
            }
        };
        if !success {
            // Error statuses carry no data. BM 02 / CR 03 are "success" to
            // the caller but still carry no data.
            expect_lines(0)?;
            return Ok(Reply {
                echo,
                status: self.status,
                body: ReplyBody::Empty,
            });
        }
        let body = match echo.command {
            Command::Vv => ReplyBody::Version(VersionInfo::parse(self.lines())?),
            Command::Pp => ReplyBody::Params(SensorParams::parse(self.lines())?),
            Command::Ii => ReplyBody::Info(SensorInfo::parse(self.lines())?),
            Command::Tm(TimeControl::Read) => {
                expect_lines(1)?;
                let field = self.line(0).unwrap_or(&[]);
                if field.len() != 4 {
                    return Err(EncodingError::BadLength(field.len()).into());
                }
                ReplyBody::Time(encoding::decode_value(field)?)
            }
            Command::Get(req) => ReplyBody::Scan(ScanData::from_reply(self, req, None)?),
            Command::Stream(s) if self.status == Status::Scip2(StatusCode::DATA) => {
                ReplyBody::Scan(ScanData::from_reply(self, s.scan, Some(s.count))?)
            }
            _ => {
                expect_lines(0)?;
                ReplyBody::Empty
            }
        };
        Ok(Reply {
            echo,
            status: self.status,
            body,
        })
    }
}

/// Writes data-line payload characters, cutting lines at 64 characters and
/// appending each line's checksum and LF. Values may straddle lines, as on
/// the real sensor. Call [`DataLineWriter::finish`] to flush the last line.
pub struct DataLineWriter<'s, S: ByteSink> {
    out: &'s mut S,
    line: [u8; DATA_LINE_CHARS + 2],
    len: usize,
}

impl<'s, S: ByteSink> DataLineWriter<'s, S> {
    /// A writer into `out`.
    pub fn new(out: &'s mut S) -> Self {
        DataLineWriter {
            out,
            line: [0; DATA_LINE_CHARS + 2],
            len: 0,
        }
    }

    /// Appends payload characters.
    pub fn put(&mut self, mut bytes: &[u8]) -> Result<(), EncodeError> {
        while !bytes.is_empty() {
            let n = (DATA_LINE_CHARS - self.len).min(bytes.len());
            self.line[self.len..self.len + n].copy_from_slice(&bytes[..n]);
            self.len += n;
            bytes = &bytes[n..];
            if self.len == DATA_LINE_CHARS {
                self.flush_line()?;
            }
        }
        Ok(())
    }

    /// Appends one encoded value.
    pub fn put_value(&mut self, value: u32, width: Width) -> Result<(), EncodeError> {
        let a = encoding::encode_array(value, width)?;
        self.put(&a[..width.chars()])
    }

    fn flush_line(&mut self) -> Result<(), EncodeError> {
        let sum = super::checksum::checksum(&self.line[..self.len]);
        self.line[self.len] = sum;
        self.line[self.len + 1] = b'\n';
        let n = self.len + 2;
        self.len = 0;
        self.out.put(&self.line[..n])
    }

    /// Flushes a partial last line (if any).
    pub fn finish(mut self) -> Result<(), EncodeError> {
        if self.len > 0 {
            self.flush_line()?;
        }
        Ok(())
    }
}

/// Writes the status line (`00P`, or a bare SCIP 1.1 character).
pub fn write_status(status: Status, out: &mut impl ByteSink) -> Result<(), EncodeError> {
    match status {
        Status::Scip2(StatusCode([a, b])) => {
            out.put(&[a, b, super::checksum::checksum(&[a, b]), b'\n'])
        }
        Status::Scip1(c) => out.put(&[c, b'\n']),
    }
}

/// Writes a whole reply that has no data lines: echo line, status, empty line.
/// `echo` is the received command line exactly as it arrived (tag included).
pub fn write_status_reply(
    echo: &[u8],
    status: Status,
    out: &mut impl ByteSink,
) -> Result<(), EncodeError> {
    out.put(echo)?;
    out.put(b"\n")?;
    write_status(status, out)?;
    out.put(b"\n")
}

/// Writes a whole reply as a URG-04LX does: the echo of `echo` (for streams,
/// put the remaining count in it first with [`super::StreamRequest::with_remaining`]),
/// the status, the body's data lines and the empty line.
pub fn encode_reply(
    echo: &TaggedCommand,
    status: Status,
    body: &ReplyBody<'_>,
    out: &mut impl ByteSink,
) -> Result<(), EncodeError> {
    echo.encode(out)?;
    write_status(status, out)?;
    match body {
        ReplyBody::Empty => {}
        ReplyBody::Version(v) => v.encode_lines(out)?,
        ReplyBody::Params(p) => p.encode_lines(out)?,
        ReplyBody::Info(i) => i.encode_lines(out)?,
        ReplyBody::Time(t) => {
            let mut w = DataLineWriter::new(out);
            w.put_value(*t & 0x00ff_ffff, Width::Four)?;
            w.finish()?;
        }
        ReplyBody::Scan(s) => s.encode_lines(out)?,
    }
    out.put(b"\n")
}
