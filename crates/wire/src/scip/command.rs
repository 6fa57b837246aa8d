//! Host → sensor commands: typed, encoded to the exact bytes a URG expects,
//! and parsed back sensor-side (the emulator), with the status code a real
//! sensor answers to a malformed command.
//!
//! The echo of an MD/MS/ME reply has the scan count replaced by the number of
//! scans remaining; it parses as the same [`StreamRequest`] with `count`
//! holding that remaining number.

use super::sink::{ByteSink, EncodeError};
use super::status::StatusCode;

/// Longest tag a command may carry (status `0G` beyond).
pub const MAX_TAG: usize = 16;

/// The command mnemonic, without parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CommandKind {
    /// `SCIP2.0`: switch a SCIP 1.1 sensor to SCIP 2.0.
    Scip20,
    /// `VV`: version information.
    Vv,
    /// `PP`: sensor parameters.
    Pp,
    /// `II`: sensor state.
    Ii,
    /// `BM`: laser on.
    Bm,
    /// `QT`: stop streaming, laser off.
    Qt,
    /// `RS`: reset (stop, laser off, clock and speeds reset).
    Rs,
    /// `TM0`/`TM1`/`TM2`: time-adjust mode.
    Tm,
    /// `SS`: serial bit rate.
    Ss,
    /// `CR`: motor speed.
    Cr,
    /// `HS`: high-sensitivity mode.
    Hs,
    /// `GD`: one scan, 3-character distances.
    Gd,
    /// `GS`: one scan, 2-character distances.
    Gs,
    /// `GE`: one scan, distance and intensity (time-of-flight models).
    Ge,
    /// `MD`: stream, 3-character distances.
    Md,
    /// `MS`: stream, 2-character distances.
    Ms,
    /// `ME`: stream, distance and intensity (time-of-flight models).
    Me,
}

impl CommandKind {
    /// The mnemonic as sent on the wire.
    pub fn mnemonic(&self) -> &'static str {
        match self {
            CommandKind::Scip20 => "SCIP2.0",
            CommandKind::Vv => "VV",
            CommandKind::Pp => "PP",
            CommandKind::Ii => "II",
            CommandKind::Bm => "BM",
            CommandKind::Qt => "QT",
            CommandKind::Rs => "RS",
            CommandKind::Tm => "TM",
            CommandKind::Ss => "SS",
            CommandKind::Cr => "CR",
            CommandKind::Hs => "HS",
            CommandKind::Gd => "GD",
            CommandKind::Gs => "GS",
            CommandKind::Ge => "GE",
            CommandKind::Md => "MD",
            CommandKind::Ms => "MS",
            CommandKind::Me => "ME",
        }
    }

    /// The kind whose two-letter mnemonic is `m`.
    pub fn from_mnemonic(m: [u8; 2]) -> Option<Self> {
        Some(match &m {
            b"VV" => CommandKind::Vv,
            b"PP" => CommandKind::Pp,
            b"II" => CommandKind::Ii,
            b"BM" => CommandKind::Bm,
            b"QT" => CommandKind::Qt,
            b"RS" => CommandKind::Rs,
            b"TM" => CommandKind::Tm,
            b"SS" => CommandKind::Ss,
            b"CR" => CommandKind::Cr,
            b"HS" => CommandKind::Hs,
            b"GD" => CommandKind::Gd,
            b"GS" => CommandKind::Gs,
            b"GE" => CommandKind::Ge,
            b"MD" => CommandKind::Md,
            b"MS" => CommandKind::Ms,
            b"ME" => CommandKind::Me,
            _ => return None,
        })
    }

    /// True for VV/PP/II, whose data lines are `KEY:value;X`.
    pub fn has_kv_lines(&self) -> bool {
        matches!(self, CommandKind::Vv | CommandKind::Pp | CommandKind::Ii)
    }

    /// True for MD/MS/ME.
    pub fn is_stream(&self) -> bool {
        matches!(self, CommandKind::Md | CommandKind::Ms | CommandKind::Me)
    }
}

/// TM sub-command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TimeControl {
    /// `TM0`: enter time-adjust mode.
    Enter,
    /// `TM1`: read the sensor clock.
    Read,
    /// `TM2`: leave time-adjust mode.
    Leave,
}

/// What a scan command returns per step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DataKind {
    /// `GD`/`MD`: 3-character distances (18 bits).
    Distance,
    /// `GS`/`MS`: 2-character distances (12 bits, up to 4095 mm).
    ShortDistance,
    /// `GE`/`ME`: 3-character distance then 3-character intensity.
    DistanceIntensity,
}

/// Cluster field of a scan command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cluster {
    /// `00`..`99`: the sensor merges this many neighbouring steps into one value
    /// (0 and 1 both mean no merging).
    Steps(u8),
    /// `FF` (URG-04LX family only; **experimental**, undocumented): the value
    /// stream alternates distance and intensity for consecutive step pairs.
    UrgIntensity,
}

impl Cluster {
    /// Steps per value (1 for `00`, `01` and `FF`).
    pub fn group(&self) -> u16 {
        match self {
            Cluster::Steps(n) => u16::from(*n).max(1),
            Cluster::UrgIntensity => 1,
        }
    }
}

/// Start/end/cluster of a GD/GS/GE (and the scan part of MD/MS/ME).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ScanRequest {
    /// What each value carries.
    pub kind: DataKind,
    /// First step (0..=9999).
    pub start: u16,
    /// Last step (0..=9999, ≥ start).
    pub end: u16,
    /// Step merging.
    pub cluster: Cluster,
}

impl ScanRequest {
    /// Number of values the reply must carry (per value: one field for
    /// distance kinds, two for [`DataKind::DistanceIntensity`]).
    pub fn value_count(&self) -> usize {
        if self.end < self.start {
            return 0;
        }
        let steps = usize::from(self.end - self.start) + 1;
        steps.div_ceil(usize::from(self.cluster.group()))
    }

    /// Characters of encoded data the reply must carry.
    pub fn payload_chars(&self) -> usize {
        let per = match self.kind {
            DataKind::Distance => 3,
            DataKind::ShortDistance => 2,
            DataKind::DistanceIntensity => 6,
        };
        self.value_count() * per
    }

    /// Sensor-side check of the range against the sensor's AMIN/AMAX: the
    /// status a URG answers when it is out of range.
    pub fn check_range(&self, amin: u16, amax: u16) -> Result<(), StatusCode> {
        if self.end < self.start {
            return Err(StatusCode(*b"05"));
        }
        if self.end > amax || self.start < amin {
            return Err(StatusCode(*b"04"));
        }
        Ok(())
    }
}

/// MD/MS/ME parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct StreamRequest {
    /// Range, cluster and data kind.
    pub scan: ScanRequest,
    /// Scans skipped between two sent scans (0..=9).
    pub skip: u8,
    /// Number of scans (0 = until QT; 1..=99). In an echo: scans remaining.
    pub count: u8,
}

impl StreamRequest {
    /// The same request with the count field replaced by `remaining`, as the
    /// sensor echoes it before each scan.
    pub fn with_remaining(&self, remaining: u8) -> Self {
        StreamRequest {
            count: remaining,
            ..*self
        }
    }
}

/// A command without its tag.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// `SCIP2.0`.
    Scip20,
    /// `VV`.
    Vv,
    /// `PP`.
    Pp,
    /// `II`.
    Ii,
    /// `BM`.
    Bm,
    /// `QT`.
    Qt,
    /// `RS`.
    Rs,
    /// `TM0`/`TM1`/`TM2`.
    Tm(TimeControl),
    /// `SSbbbbbb`: bit rate in bit/s (6 digits).
    Ss(u32),
    /// `CRnn`: motor speed level (2 digits; 00 default, 99 reset).
    Cr(u8),
    /// `HS0`/`HS1`: high-sensitivity mode off/on.
    Hs(bool),
    /// `GD`/`GS`/`GE`.
    Get(ScanRequest),
    /// `MD`/`MS`/`ME`.
    Stream(StreamRequest),
}

impl Command {
    /// The mnemonic kind.
    pub fn kind(&self) -> CommandKind {
        match self {
            Command::Scip20 => CommandKind::Scip20,
            Command::Vv => CommandKind::Vv,
            Command::Pp => CommandKind::Pp,
            Command::Ii => CommandKind::Ii,
            Command::Bm => CommandKind::Bm,
            Command::Qt => CommandKind::Qt,
            Command::Rs => CommandKind::Rs,
            Command::Tm(_) => CommandKind::Tm,
            Command::Ss(_) => CommandKind::Ss,
            Command::Cr(_) => CommandKind::Cr,
            Command::Hs(_) => CommandKind::Hs,
            Command::Get(r) => match r.kind {
                DataKind::Distance => CommandKind::Gd,
                DataKind::ShortDistance => CommandKind::Gs,
                DataKind::DistanceIntensity => CommandKind::Ge,
            },
            Command::Stream(s) => match s.scan.kind {
                DataKind::Distance => CommandKind::Md,
                DataKind::ShortDistance => CommandKind::Ms,
                DataKind::DistanceIntensity => CommandKind::Me,
            },
        }
    }

    /// The scan range, for GD/GS/GE and MD/MS/ME.
    pub fn scan_request(&self) -> Option<&ScanRequest> {
        match self {
            Command::Get(r) => Some(r),
            Command::Stream(s) => Some(&s.scan),
            _ => None,
        }
    }
}

/// An optional command tag (`;` + up to 16 printable characters), echoed by
/// the sensor so late replies can be told from new ones. Empty = no tag.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct Tag(heapless::Vec<u8, MAX_TAG>);

impl Tag {
    /// No tag.
    pub fn none() -> Self {
        Tag(heapless::Vec::new())
    }

    /// A tag from its text; fails like the sensor would (`0G` too long, `0H`
    /// bad characters).
    pub fn new(text: &[u8]) -> Result<Self, CommandError> {
        if text.len() > MAX_TAG {
            return Err(CommandError::TagTooLong(text.len()));
        }
        if let Some(&b) = text.iter().find(|&&b| !is_tag_byte(b)) {
            return Err(CommandError::TagInvalid(b));
        }
        let mut v = heapless::Vec::new();
        // Length checked above, so this cannot fail.
        let _ = v.extend_from_slice(text);
        Ok(Tag(v))
    }

    /// The tag text (empty when none).
    pub fn as_bytes(&self) -> &[u8] {
        &self.0
    }

    /// True when there is no tag.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

fn is_tag_byte(b: u8) -> bool {
    (0x21..=0x7e).contains(&b) && b != b';'
}

/// A command with its (possibly empty) tag: what travels on one line.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct TaggedCommand {
    /// The command.
    pub command: Command,
    /// Its tag (empty when none).
    pub tag: Tag,
}

/// Why a command line could not be parsed, with the status a URG answers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// Not a known command.
    #[error("undefined command")]
    Undefined,
    /// Parameters missing or the wrong length.
    #[error("missing or malformed parameters")]
    MissingParameters,
    /// Extra characters after a command that takes none, or a line too long.
    #[error("command line too long")]
    TooLong,
    /// Tag longer than 16 characters.
    #[error("tag of {0} characters is longer than 16")]
    TagTooLong(usize),
    /// Tag with a byte that is not printable or is a `;`.
    #[error("tag holds invalid byte 0x{0:02x}")]
    TagInvalid(u8),
    /// Scan start step not numeric.
    #[error("start step is not numeric")]
    BadStart,
    /// Scan end step not numeric.
    #[error("end step is not numeric")]
    BadEnd,
    /// Cluster count not numeric (nor `FF`).
    #[error("cluster count is not numeric")]
    BadCluster,
    /// End step before start step.
    #[error("end step is smaller than start step")]
    EndBeforeStart,
    /// Skip count not numeric.
    #[error("skip count is not numeric")]
    BadSkip,
    /// Scan count not numeric.
    #[error("scan count is not numeric")]
    BadCount,
    /// A TM/SS/CR/HS parameter is not valid.
    #[error("invalid control parameter")]
    BadControl,
}

impl CommandError {
    /// The status code a URG answers to this error.
    pub fn status(&self) -> StatusCode {
        StatusCode(*match self {
            CommandError::Undefined => b"0E",
            CommandError::MissingParameters => b"0C",
            CommandError::TooLong => b"0D",
            CommandError::TagTooLong(_) => b"0G",
            CommandError::TagInvalid(_) => b"0H",
            CommandError::BadStart => b"01",
            CommandError::BadEnd => b"02",
            CommandError::BadCluster => b"03",
            CommandError::EndBeforeStart => b"05",
            CommandError::BadSkip => b"06",
            CommandError::BadCount => b"07",
            CommandError::BadControl => b"01",
        })
    }
}

fn digits(field: &[u8]) -> Option<u32> {
    if field.is_empty() || !field.iter().all(u8::is_ascii_digit) {
        return None;
    }
    Some(
        field
            .iter()
            .fold(0u32, |v, &d| v * 10 + u32::from(d - b'0')),
    )
}

fn parse_scan(kind: DataKind, p: &[u8]) -> Result<ScanRequest, CommandError> {
    let start = digits(&p[0..4]).ok_or(CommandError::BadStart)? as u16;
    let end = digits(&p[4..8]).ok_or(CommandError::BadEnd)? as u16;
    let cluster = match &p[8..10] {
        b"FF" if kind != DataKind::DistanceIntensity => Cluster::UrgIntensity,
        c => Cluster::Steps(digits(c).ok_or(CommandError::BadCluster)? as u8),
    };
    if end < start {
        return Err(CommandError::EndBeforeStart);
    }
    Ok(ScanRequest {
        kind,
        start,
        end,
        cluster,
    })
}

impl TaggedCommand {
    /// A command without tag.
    pub fn new(command: Command) -> Self {
        TaggedCommand {
            command,
            tag: Tag::none(),
        }
    }

    /// A command with a tag.
    pub fn with_tag(command: Command, tag: Tag) -> Self {
        TaggedCommand { command, tag }
    }

    /// Parses one received command line (without its line end), the way a
    /// URG does; the error carries the status it would answer.
    pub fn parse(line: &[u8]) -> Result<Self, CommandError> {
        let (body, tag) = match line.iter().position(|&b| b == b';') {
            Some(i) => (&line[..i], Tag::new(&line[i + 1..])?),
            None => (line, Tag::none()),
        };
        let command = Self::parse_body(body)?;
        Ok(TaggedCommand { command, tag })
    }

    fn parse_body(body: &[u8]) -> Result<Command, CommandError> {
        if body == b"SCIP2.0" {
            return Ok(Command::Scip20);
        }
        if body.len() < 2 {
            return Err(CommandError::Undefined);
        }
        let kind = CommandKind::from_mnemonic([body[0], body[1]]).ok_or(CommandError::Undefined)?;
        let p = &body[2..];
        let bare = |c: Command| {
            if p.is_empty() {
                Ok(c)
            } else {
                Err(CommandError::TooLong)
            }
        };
        let exact = |n: usize| match p.len().cmp(&n) {
            core::cmp::Ordering::Less => Err(CommandError::MissingParameters),
            core::cmp::Ordering::Greater => Err(CommandError::TooLong),
            core::cmp::Ordering::Equal => Ok(()),
        };
        match kind {
            CommandKind::Vv => bare(Command::Vv),
            CommandKind::Pp => bare(Command::Pp),
            CommandKind::Ii => bare(Command::Ii),
            CommandKind::Bm => bare(Command::Bm),
            CommandKind::Qt => bare(Command::Qt),
            CommandKind::Rs => bare(Command::Rs),
            CommandKind::Scip20 => Err(CommandError::Undefined),
            CommandKind::Tm => {
                exact(1)?;
                match p[0] {
                    b'0' => Ok(Command::Tm(TimeControl::Enter)),
                    b'1' => Ok(Command::Tm(TimeControl::Read)),
                    b'2' => Ok(Command::Tm(TimeControl::Leave)),
                    _ => Err(CommandError::BadControl),
                }
            }
            CommandKind::Ss => {
                exact(6)?;
                digits(p).map(Command::Ss).ok_or(CommandError::BadControl)
            }
            CommandKind::Cr => {
                exact(2)?;
                digits(p)
                    .map(|v| Command::Cr(v as u8))
                    .ok_or(CommandError::BadControl)
            }
            CommandKind::Hs => {
                exact(1)?;
                match p[0] {
                    b'0' => Ok(Command::Hs(false)),
                    b'1' => Ok(Command::Hs(true)),
                    _ => Err(CommandError::BadControl),
                }
            }
            CommandKind::Gd | CommandKind::Gs | CommandKind::Ge => {
                exact(10)?;
                parse_scan(data_kind(kind), p).map(Command::Get)
            }
            CommandKind::Md | CommandKind::Ms | CommandKind::Me => {
                exact(13)?;
                let scan = parse_scan(data_kind(kind), &p[..10])?;
                let skip = digits(&p[10..11]).ok_or(CommandError::BadSkip)? as u8;
                let count = digits(&p[11..13]).ok_or(CommandError::BadCount)? as u8;
                Ok(Command::Stream(StreamRequest { scan, skip, count }))
            }
        }
    }

    /// Writes the command line without its line end (also the echo text).
    pub fn encode_line(&self, out: &mut impl ByteSink) -> Result<(), EncodeError> {
        let c = &self.command;
        out.put(c.kind().mnemonic().as_bytes())?;
        match c {
            Command::Tm(t) => out.put(match t {
                TimeControl::Enter => b"0",
                TimeControl::Read => b"1",
                TimeControl::Leave => b"2",
            })?,
            Command::Ss(rate) => put_digits(u64::from(*rate), 6, out)?,
            Command::Cr(level) => put_digits(u64::from(*level), 2, out)?,
            Command::Hs(on) => out.put(if *on { b"1" } else { b"0" })?,
            Command::Get(r) => put_scan(r, out)?,
            Command::Stream(s) => {
                put_scan(&s.scan, out)?;
                put_digits(u64::from(s.skip), 1, out)?;
                put_digits(u64::from(s.count), 2, out)?;
            }
            _ => {}
        }
        if !self.tag.is_empty() {
            out.put(b";")?;
            out.put(self.tag.as_bytes())?;
        }
        Ok(())
    }

    /// Writes the command as sent by the host: the line plus one LF.
    pub fn encode(&self, out: &mut impl ByteSink) -> Result<(), EncodeError> {
        self.encode_line(out)?;
        out.put(b"\n")
    }
}

fn data_kind(kind: CommandKind) -> DataKind {
    match kind {
        CommandKind::Gs | CommandKind::Ms => DataKind::ShortDistance,
        CommandKind::Ge | CommandKind::Me => DataKind::DistanceIntensity,
        _ => DataKind::Distance,
    }
}

fn put_digits(value: u64, width: usize, out: &mut impl ByteSink) -> Result<(), EncodeError> {
    let mut buf = [0u8; 8];
    if width > buf.len() || value >= 10u64.pow(width as u32) {
        return Err(EncodeError::ValueTooLarge { value, width });
    }
    let mut v = value;
    for slot in buf[..width].iter_mut().rev() {
        *slot = b'0' + (v % 10) as u8;
        v /= 10;
    }
    out.put(&buf[..width])
}

fn put_scan(r: &ScanRequest, out: &mut impl ByteSink) -> Result<(), EncodeError> {
    put_digits(u64::from(r.start), 4, out)?;
    put_digits(u64::from(r.end), 4, out)?;
    match r.cluster {
        Cluster::Steps(n) => put_digits(u64::from(n), 2, out),
        Cluster::UrgIntensity => out.put(b"FF"),
    }
}
