//! Crash-safe checkpoints: a versioned, checksummed container of named,
//! typed sections (pose, explored grid, run progress, the tracker's
//! keyframes, the planner's records: each a serde state type of its
//! algorithm crate, made a [`Section`] here in the pipeline layer), written
//! atomically (tmp file + fsync + rename + fsync of the folder) so that after
//! a crash or `kill -9` the daemon resumes from the last good checkpoint.
//!
//! File layout (little-endian):
//!
//! ```text
//! "SWPLCKPT"            8 bytes magic
//! format version        u16   (this build: 2)
//! flags                 u16   (0)
//! section count         u32   (<= 256)
//! per section:
//!   name length         u8    (1..=48), name: ASCII [a-z0-9_.-]
//!   section version     u16
//!   payload length      u64
//!   payload             the section's value in postcard 1.x (serde)
//!   payload CRC-32      u32
//! file CRC-32           u32   of every byte before it
//! ```
//!
//! Payloads are [postcard](https://postcard.jamesmunns.com/wire-format):
//! a documented, stable, compact serde format (varint integers, IEEE floats,
//! length-prefixed sequences), readable from any language with its spec.
//! Format version 1 (until 2026-12-02) had hand-written payloads; this build
//! refuses it with a clear message rather than misread it.
//!
//! The reader checks the whole-file CRC first, then every length against the
//! bytes actually present, so a truncated, corrupted or hostile file is a clear
//! [`CheckpointError`], never a panic or a huge allocation (serde allocates a
//! sequence by what the payload holds, never by what its length prefix
//! claims). Each section then checks what serde cannot (finite numbers,
//! lengths that agree with a grid, limits) in [`Section::restored`]. A
//! corrupted checkpoint never replaces a good one: [`CheckpointStore::save`]
//! verifies what it wrote before the rename and keeps the previous good file
//! as `<name>.prev`, which [`CheckpointStore::load`] falls back to.

mod checks;
pub mod contacts;
mod home;
pub mod keyframes;
mod lattice;
pub mod mount;
mod reach;
pub(crate) mod resume_log;
mod sections;
mod swept;
mod tries;

use std::fs::{self, File, OpenOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::Serialize;

use checks::Bytes;
pub use contacts::{ContactArc, ContactArcs, TriedPlaces};
pub use mount::MountRecord;
pub use resume_log::{ProgressMark, ResumeEntry, ResumeLog, ResumeLogError, RESUME_FILE};
pub use sections::{RunFinished, RunProgress, WrittenAt};

/// File magic.
pub const MAGIC: &[u8; 8] = b"SWPLCKPT";
/// Container format version written and read by this build.
pub const FORMAT_VERSION: u16 = 2;
/// Largest section payload the reader decodes (bytes): a 8192 × 8192 grid
/// and a full keyframe window fit many times over.
pub const MAX_PAYLOAD: usize = 256 << 20;
/// Most sections a checkpoint may hold.
pub(crate) const MAX_SECTIONS: u32 = 256;
/// Longest section name.
pub(crate) const MAX_NAME: usize = 48;
/// Largest checkpoint file the reader accepts (bytes).
pub(crate) const MAX_FILE_BYTES: u64 = 512 << 20;
/// Size of the fixed header.
const HEADER: usize = 16;

/// Why a checkpoint could not be written, read or decoded.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// File system error.
    #[error("checkpoint {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// OS error.
        source: std::io::Error,
    },
    /// Not a checkpoint at all.
    #[error("not a sweepline checkpoint (bad magic bytes)")]
    BadMagic,
    /// Written by another format version.
    #[error("checkpoint format version {0} is not supported (this build reads version {FORMAT_VERSION}){hint}", hint = old_format_hint(*.0))]
    UnsupportedVersion(u16),
    /// The file ends before its structure does.
    #[error("checkpoint is truncated: {0}")]
    Truncated(String),
    /// A checksum does not match: the file was corrupted.
    #[error("checkpoint is corrupted: {0}")]
    Corrupted(String),
    /// The container structure is invalid (bad name, too many sections...).
    #[error("checkpoint is malformed: {0}")]
    Malformed(String),
    /// A section's payload is not what its type expects.
    #[error("checkpoint section `{name}` is malformed: {message}")]
    BadSection {
        /// Section name.
        name: String,
        /// What is wrong.
        message: String,
    },
    /// A section the caller requires is absent.
    #[error("checkpoint has no `{0}` section")]
    Missing(String),
    /// A section of a version this build cannot read.
    #[error(
        "checkpoint section `{name}` has version {found}; this build reads version {supported}"
    )]
    SectionVersion {
        /// Section name.
        name: String,
        /// Version in the file.
        found: u16,
        /// Version this build reads.
        supported: u16,
    },
    /// The file is larger than `MAX_FILE_BYTES`.
    #[error("checkpoint is {0} bytes, more than the {MAX_FILE_BYTES} bytes accepted")]
    TooLarge(u64),
    /// Neither the checkpoint nor its previous copy is usable.
    #[error("no usable checkpoint: {current}; previous copy: {previous}")]
    NoneUsable {
        /// Why the current file was rejected.
        current: String,
        /// Why the previous copy was rejected.
        previous: String,
    },
}

/// A typed section of a checkpoint: a serde state type with a name and a
/// version. Its payload is the value in postcard.
pub trait Section: Serialize + DeserializeOwned {
    /// Section name (ASCII lower-case, digits, `_ . -`; at most 48 bytes).
    const NAME: &'static str;
    /// Version of this section's layout; bump it when the type's fields
    /// change.
    const VERSION: u16;
    /// The value as read back: checks what serde cannot (finite numbers,
    /// lengths that agree with a grid, limits) and rebuilds what is not
    /// stored. The error says which value is bad.
    fn restored(self) -> Result<Self, String> {
        Ok(self)
    }
}

/// CRC-32 (IEEE 802.3, the zlib/PNG/gzip checksum) of `bytes`, as the
/// container stores it. `crc32(b"123456789") == 0xCBF43926`.
pub fn crc32(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

/// What to say beside an unsupported format version.
fn old_format_hint(version: u16) -> &'static str {
    if version < FORMAT_VERSION {
        "; it was written by a sweepline from before 2026-12-02: finish that \
         run with the build that wrote it, or start a new run with `--fresh`"
    } else {
        "; it was written by a newer sweepline"
    }
}

/// Encodes `value` as its section payload.
fn encode<S: Section>(value: &S) -> Result<Vec<u8>, CheckpointError> {
    postcard::to_allocvec(value).map_err(|e| CheckpointError::BadSection {
        name: S::NAME.to_string(),
        message: format!("cannot be encoded: {e}"),
    })
}

/// Decodes and checks a payload of section `S`: all of it, no more.
fn decode<S: Section>(payload: &[u8]) -> Result<S, CheckpointError> {
    let bad = |message: String| CheckpointError::BadSection {
        name: S::NAME.to_string(),
        message,
    };
    if payload.len() > MAX_PAYLOAD {
        return Err(bad(format!(
            "{} bytes, more than the {MAX_PAYLOAD} accepted",
            payload.len()
        )));
    }
    let (value, rest) = postcard::take_from_bytes::<S>(payload).map_err(|e| bad(e.to_string()))?;
    if !rest.is_empty() {
        return Err(bad(format!(
            "{} trailing bytes after the value",
            rest.len()
        )));
    }
    value.restored().map_err(bad)
}

/// Payload-level helpers for the sections' own tests.
#[cfg(test)]
pub(crate) mod testing {
    use super::{decode, CheckpointError, Section};

    /// The payload of `value` as written, without the checks `put` makes
    /// (so a test can write a value the reader must refuse).
    pub(crate) fn payload<S: Section>(value: &S) -> Vec<u8> {
        postcard::to_allocvec(value).expect("encodes")
    }

    /// Reads a payload as [`super::Checkpoint::get`] does.
    pub(crate) fn read<S: Section>(bytes: &[u8]) -> Result<S, CheckpointError> {
        decode(bytes)
    }

    /// The reader's message for `value`, which it must refuse.
    pub(crate) fn refusal<S: Section + std::fmt::Debug>(value: &S) -> String {
        read::<S>(&payload(value))
            .expect_err("the reader must refuse it")
            .to_string()
    }

    /// `value` reads back equal, and every shorter prefix of its payload
    /// and its payload with a byte more are refused.
    pub(crate) fn round_trips<S: Section + PartialEq + std::fmt::Debug>(value: &S) {
        let bytes = payload(value);
        assert_eq!(&read::<S>(&bytes).expect("reads back"), value);
        for cut in 0..bytes.len() {
            assert!(read::<S>(&bytes[..cut]).is_err(), "cut at {cut} accepted");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        let e = read::<S>(&longer).expect_err("a trailing byte").to_string();
        assert!(e.contains("trailing"), "{e}");
    }
}

#[derive(Clone, Debug, PartialEq)]
struct RawSection {
    name: String,
    version: u16,
    payload: Vec<u8>,
}

/// A checkpoint in memory: an ordered set of named sections.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Checkpoint {
    sections: Vec<RawSection>,
}

fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_NAME
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b"_.-".contains(&b))
}

impl Checkpoint {
    /// An empty checkpoint.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds (or replaces) section `S`. The value is encoded and decoded back
    /// at once, so a value its own reader would reject (a NaN pose, say) is
    /// refused here and never reaches a file.
    pub fn put<S: Section>(&mut self, value: &S) -> Result<(), CheckpointError> {
        if !valid_name(S::NAME) {
            return Err(CheckpointError::Malformed(format!(
                "section name `{}` is not 1..={MAX_NAME} bytes of [a-z0-9_.-]",
                S::NAME
            )));
        }
        let payload = encode(value)?;
        decode::<S>(&payload)?;
        let raw = RawSection {
            name: S::NAME.to_string(),
            version: S::VERSION,
            payload,
        };
        match self.sections.iter_mut().find(|s| s.name == S::NAME) {
            Some(s) => *s = raw,
            None => {
                if self.sections.len() >= MAX_SECTIONS as usize {
                    return Err(CheckpointError::Malformed(format!(
                        "more than {MAX_SECTIONS} sections"
                    )));
                }
                self.sections.push(raw);
            }
        }
        Ok(())
    }

    /// Section `S`, if present.
    pub fn get<S: Section>(&self) -> Result<Option<S>, CheckpointError> {
        let Some(raw) = self.sections.iter().find(|s| s.name == S::NAME) else {
            return Ok(None);
        };
        if raw.version != S::VERSION {
            return Err(CheckpointError::SectionVersion {
                name: raw.name.clone(),
                found: raw.version,
                supported: S::VERSION,
            });
        }
        decode::<S>(&raw.payload).map(Some)
    }

    /// Section `S`, which must be present.
    pub fn require<S: Section>(&self) -> Result<S, CheckpointError> {
        self.get::<S>()?
            .ok_or_else(|| CheckpointError::Missing(S::NAME.to_string()))
    }

    /// Names of the sections, in order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.sections.iter().map(|s| s.name.as_str())
    }

    /// The file image.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(
            HEADER
                + 4
                + self
                    .sections
                    .iter()
                    .map(|s| s.payload.len() + 70)
                    .sum::<usize>(),
        );
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&0u16.to_le_bytes());
        out.extend_from_slice(&(self.sections.len() as u32).to_le_bytes());
        for s in &self.sections {
            out.push(s.name.len() as u8);
            out.extend_from_slice(s.name.as_bytes());
            out.extend_from_slice(&s.version.to_le_bytes());
            out.extend_from_slice(&(s.payload.len() as u64).to_le_bytes());
            out.extend_from_slice(&s.payload);
            out.extend_from_slice(&crc32(&s.payload).to_le_bytes());
        }
        let crc = crc32(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Parses a file image; rejects anything but an intact checkpoint of this
    /// format version. Never panics, allocates at most the sections present.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, CheckpointError> {
        if bytes.len() as u64 > MAX_FILE_BYTES {
            return Err(CheckpointError::TooLarge(bytes.len() as u64));
        }
        if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
            return Err(if MAGIC.starts_with(bytes) {
                CheckpointError::Truncated(format!("only {} bytes", bytes.len()))
            } else {
                CheckpointError::BadMagic
            });
        }
        if bytes.len() < HEADER + 4 {
            return Err(CheckpointError::Truncated(format!(
                "{} bytes, shorter than the {}-byte header and checksum",
                bytes.len(),
                HEADER + 4
            )));
        }
        let version = u16::from_le_bytes([bytes[8], bytes[9]]);
        if version != FORMAT_VERSION {
            return Err(CheckpointError::UnsupportedVersion(version));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 4);
        let stored = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
        if crc32(body) != stored {
            return Err(CheckpointError::Corrupted(
                "file checksum mismatch (truncated or damaged file)".into(),
            ));
        }
        let flags = u16::from_le_bytes([body[10], body[11]]);
        if flags != 0 {
            return Err(CheckpointError::Malformed(format!(
                "unknown flags {flags:#06x}"
            )));
        }
        let count = u32::from_le_bytes([body[12], body[13], body[14], body[15]]);
        if count > MAX_SECTIONS {
            return Err(CheckpointError::Malformed(format!(
                "{count} sections, more than the {MAX_SECTIONS} allowed"
            )));
        }
        let mut r = Bytes::new(&body[HEADER..]);
        let trunc = |what: &str, i: u32| {
            CheckpointError::Truncated(format!("ends inside the {what} of section #{i}"))
        };
        let mut sections: Vec<RawSection> = Vec::with_capacity(count as usize);
        for i in 0..count {
            let n = r.u8().ok_or_else(|| trunc("name length", i))? as usize;
            if n == 0 || n > MAX_NAME || n > r.remaining() {
                return Err(CheckpointError::Malformed(format!(
                    "section #{i} has a name length of {n}"
                )));
            }
            let raw_name = r.raw(n).ok_or_else(|| trunc("name", i))?;
            let name = match std::str::from_utf8(raw_name) {
                Ok(s) if valid_name(s) => s.to_string(),
                _ => {
                    return Err(CheckpointError::Malformed(format!(
                        "section #{i} has an invalid name {:?}",
                        String::from_utf8_lossy(raw_name)
                    )))
                }
            };
            if sections.iter().any(|s| s.name == name) {
                return Err(CheckpointError::Malformed(format!(
                    "section `{name}` appears twice"
                )));
            }
            let sv = r.u16().ok_or_else(|| trunc("version", i))?;
            let len = r.u64().ok_or_else(|| trunc("length", i))?;
            let len = usize::try_from(len)
                .ok()
                .filter(|&l| l.checked_add(4).is_some_and(|t| t <= r.remaining()))
                .ok_or_else(|| {
                    CheckpointError::Truncated(format!(
                        "section `{name}` claims {len} bytes but only {} remain",
                        r.remaining()
                    ))
                })?;
            let payload = r.raw(len).ok_or_else(|| trunc("payload", i))?.to_vec();
            let crc = r.u32().ok_or_else(|| trunc("checksum", i))?;
            if crc32(&payload) != crc {
                return Err(CheckpointError::Corrupted(format!(
                    "section `{name}` checksum mismatch"
                )));
            }
            sections.push(RawSection {
                name,
                version: sv,
                payload,
            });
        }
        if r.remaining() != 0 {
            return Err(CheckpointError::Malformed(format!(
                "{} unexpected bytes after the last section",
                r.remaining()
            )));
        }
        Ok(Self { sections })
    }

    /// Reads and parses a checkpoint file.
    pub fn read(path: &Path) -> Result<Self, CheckpointError> {
        let io = |source| CheckpointError::Io {
            path: path.display().to_string(),
            source,
        };
        let mut f = File::open(path).map_err(io)?;
        let len = f.metadata().map_err(io)?.len();
        if len > MAX_FILE_BYTES {
            return Err(CheckpointError::TooLarge(len));
        }
        let mut bytes = Vec::with_capacity(len as usize);
        Read::by_ref(&mut f)
            .take(MAX_FILE_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(io)?;
        Self::from_bytes(&bytes)
    }
}

/// A checkpoint loaded by [`CheckpointStore::load`].
#[derive(Debug)]
pub struct Loaded {
    /// The checkpoint.
    pub checkpoint: Checkpoint,
    /// Set when the current file was unusable and the previous copy was
    /// used instead: why the current one was rejected.
    pub fell_back: Option<String>,
}

/// Where a daemon keeps its checkpoint: `<dir>/<name>`, the previous good one
/// as `<name>.prev`, the one being written as `<name>.tmp`, and a rejected
/// corrupt one as `<name>.bad` (kept for a post-mortem).
#[derive(Debug, Clone)]
pub struct CheckpointStore {
    dir: PathBuf,
    name: String,
}

impl CheckpointStore {
    /// The default file name inside the state folder.
    pub(crate) const DEFAULT_NAME: &'static str = "checkpoint.swc";

    /// A store for `dir/checkpoint.swc`.
    pub fn new(dir: &Path) -> Self {
        Self::with_name(dir, Self::DEFAULT_NAME)
    }

    /// A store for `dir/name`.
    pub(crate) fn with_name(dir: &Path, name: &str) -> Self {
        Self {
            dir: dir.to_path_buf(),
            name: name.to_string(),
        }
    }

    /// The current checkpoint's path.
    pub fn path(&self) -> PathBuf {
        self.dir.join(&self.name)
    }

    /// The previous good checkpoint's path.
    pub fn prev_path(&self) -> PathBuf {
        self.dir.join(format!("{}.prev", self.name))
    }

    fn tmp_path(&self) -> PathBuf {
        self.dir.join(format!("{}.tmp", self.name))
    }

    fn bad_path(&self) -> PathBuf {
        self.dir.join(format!("{}.bad", self.name))
    }

    /// Writes `cp` atomically: to `<name>.tmp`, fsync, read back and verify,
    /// then the current file (if intact) becomes `<name>.prev`, the new one is
    /// renamed into place and the folder is fsynced. A current file that does
    /// not verify is moved to `<name>.bad` instead, so it never displaces the
    /// good previous copy. On any error the files in place are untouched.
    pub fn save(&self, cp: &Checkpoint) -> Result<(), CheckpointError> {
        let bytes = cp.to_bytes();
        let tmp = self.tmp_path();
        let io = |p: &Path| {
            let p = p.display().to_string();
            move |source| CheckpointError::Io { path: p, source }
        };
        fs::create_dir_all(&self.dir).map_err(io(&self.dir))?;
        {
            let mut f = OpenOptions::new()
                .write(true)
                .create(true)
                .truncate(true)
                .open(&tmp)
                .map_err(io(&tmp))?;
            f.write_all(&bytes).map_err(io(&tmp))?;
            f.sync_all().map_err(io(&tmp))?;
        }
        if let Err(e) = Checkpoint::read(&tmp).and_then(|back| {
            if back == *cp {
                Ok(())
            } else {
                Err(CheckpointError::Corrupted(
                    "the file read back differs from what was written".into(),
                ))
            }
        }) {
            let _ = fs::remove_file(&tmp);
            return Err(e);
        }
        let cur = self.path();
        if cur.exists() {
            let keep_as = match Checkpoint::read(&cur) {
                Ok(_) => self.prev_path(),
                Err(e) => {
                    log::warn!(
                        "checkpoint {} is unusable ({e}); keeping the previous copy",
                        cur.display()
                    );
                    self.bad_path()
                }
            };
            fs::rename(&cur, &keep_as).map_err(io(&cur))?;
        }
        fs::rename(&tmp, &cur).map_err(io(&cur))?;
        File::open(&self.dir)
            .and_then(|d| d.sync_all())
            .map_err(io(&self.dir))?;
        Ok(())
    }

    /// Writes `cp` to `<name>` by a temporary file and a rename, without
    /// fsync, verification or a previous copy: for the frequent, expendable
    /// heartbeat, where a crash of the process (not of the machine) must
    /// leave either the old or the new file, never a torn one.
    pub(crate) fn save_unsynced(&self, cp: &Checkpoint) -> Result<(), CheckpointError> {
        let tmp = self.tmp_path();
        let cur = self.path();
        let io = |p: &Path| {
            let p = p.display().to_string();
            move |source| CheckpointError::Io { path: p, source }
        };
        fs::create_dir_all(&self.dir).map_err(io(&self.dir))?;
        fs::write(&tmp, cp.to_bytes()).map_err(io(&tmp))?;
        fs::rename(&tmp, &cur).map_err(io(&cur))
    }

    /// Reads the current file only (no fallback): `Ok(None)` when it does
    /// not exist.
    pub(crate) fn read_current(&self) -> Result<Option<Checkpoint>, CheckpointError> {
        match Checkpoint::read(&self.path()) {
            Ok(cp) => Ok(Some(cp)),
            Err(CheckpointError::Io { source, .. })
                if source.kind() == std::io::ErrorKind::NotFound =>
            {
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    /// Loads the current checkpoint, or the previous copy when the current one
    /// is missing or unusable. `Ok(None)` when there is no checkpoint at all
    /// (a fresh start).
    pub fn load(&self) -> Result<Option<Loaded>, CheckpointError> {
        let cur = self.path();
        let prev = self.prev_path();
        let current_err = match Checkpoint::read(&cur) {
            Ok(checkpoint) => {
                return Ok(Some(Loaded {
                    checkpoint,
                    fell_back: None,
                }))
            }
            Err(CheckpointError::Io { source, .. })
                if source.kind() == std::io::ErrorKind::NotFound =>
            {
                "missing".to_string()
            }
            Err(e) => e.to_string(),
        };
        match Checkpoint::read(&prev) {
            Ok(checkpoint) => Ok(Some(Loaded {
                checkpoint,
                fell_back: Some(current_err),
            })),
            Err(CheckpointError::Io { source, .. })
                if source.kind() == std::io::ErrorKind::NotFound && current_err == "missing" =>
            {
                Ok(None)
            }
            Err(e) => Err(CheckpointError::NoneUsable {
                current: current_err,
                previous: e.to_string(),
            }),
        }
    }
}
