//! The recording on disk: one file (`sim`'s `run.mcap`) or a rotating set
//! under a size cap (`sweepline run`), each file opening with the metadata
//! a replay needs, so that every file can be replayed alone.

use std::collections::{BTreeMap, VecDeque};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use foxglove::{Context, McapCompression, McapWriteOptions, McapWriter, McapWriterHandle};

use crate::recording::{Setup, CLOCK, SETUP};

/// Uncompressed bytes a chunk holds before it is written (about half a
/// second of scans): a killed daemon loses at most the open chunk, and the
/// file is flushed every second besides.
const CHUNK_SIZE: u64 = 128 * 1024;

/// Where the recording goes.
#[derive(Clone, Debug)]
pub enum RecordTo {
    /// One file, replaced if it exists.
    File(PathBuf),
    /// Files `run-<unix milliseconds>.mcap` in a folder: a new one when the
    /// current one reaches `file_bytes`, the oldest removed while all of
    /// them hold more than `total_bytes`.
    Rotating {
        /// The folder.
        dir: PathBuf,
        /// Size of one file (bytes).
        file_bytes: u64,
        /// Size of all of them (bytes).
        total_bytes: u64,
    },
}

/// Why a recording cannot go on.
#[derive(Debug, thiserror::Error)]
#[error("recording {path}: {why}")]
pub struct RecordError {
    /// The file.
    pub path: PathBuf,
    /// Why.
    pub why: String,
}

type Handle = McapWriterHandle<BufWriter<File>>;

/// The open recording.
pub(crate) struct Recorder {
    ctx: Arc<Context>,
    to: RecordTo,
    channels: Vec<String>,
    handle: Option<Handle>,
    path: PathBuf,
    /// Files of a rotating recording, oldest first.
    files: VecDeque<PathBuf>,
    /// The clock metadata (every file).
    clock: BTreeMap<String, String>,
    /// Bytes of the files closed so far.
    closed_bytes: u64,
    /// The millisecond in the newest file's name (0: none yet).
    last_ms: u64,
}

impl Recorder {
    /// Opens the first file; `channels` (empty: all) are the topics kept.
    pub(crate) fn open(
        ctx: &Arc<Context>,
        to: RecordTo,
        channels: Vec<String>,
        clock: BTreeMap<String, String>,
        setup: Option<&Setup>,
    ) -> Result<Recorder, RecordError> {
        let mut r = Recorder {
            ctx: ctx.clone(),
            to,
            channels,
            handle: None,
            path: PathBuf::new(),
            files: VecDeque::new(),
            clock,
            closed_bytes: 0,
            last_ms: 0,
        };
        if let RecordTo::Rotating { dir, .. } = &r.to {
            std::fs::create_dir_all(dir).map_err(|e| RecordError {
                path: dir.clone(),
                why: e.to_string(),
            })?;
            r.files = existing(dir);
        }
        r.next_file(setup)?;
        Ok(r)
    }

    /// The file being written.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    fn err(&self, why: impl ToString) -> RecordError {
        RecordError {
            path: self.path.clone(),
            why: why.to_string(),
        }
    }

    /// Opens the next file with the metadata a replay needs.
    fn next_file(&mut self, setup: Option<&Setup>) -> Result<(), RecordError> {
        self.path = match &self.to {
            RecordTo::File(p) => p.clone(),
            RecordTo::Rotating { dir, .. } => fresh_name(dir, &mut self.last_ms),
        };
        if let RecordTo::File(p) = &self.to {
            // The file is the run's: an older one goes.
            if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).map_err(|e| self.err(e))?;
            }
            if p.exists() {
                std::fs::remove_file(p).map_err(|e| self.err(e))?;
            }
        }
        // zstd level 1 on this thread: the default level 3 with a worker
        // thread per core cost 0.47 s of CPU per 120 s of the default room
        // against 0.32 s (the whole telemetry thread), for files 16 % larger.
        let options = McapWriteOptions::new()
            .compression(Some(McapCompression::Zstd))
            .compression_threads(0)
            .compression_level(1)
            .chunk_size(Some(CHUNK_SIZE));
        let keep = self.channels.clone();
        let handle = McapWriter::with_options(options)
            .context(&self.ctx)
            .channel_filter_fn(move |c| keep.is_empty() || keep.iter().any(|k| k == c.topic()))
            .create_new_buffered_file(&self.path)
            .map_err(|e| self.err(e))?;
        handle
            .write_metadata(CLOCK, self.clock.clone())
            .map_err(|e| self.err(e))?;
        if let Some(s) = setup {
            match s.to_metadata() {
                Ok(m) => handle.write_metadata(SETUP, m).map_err(|e| self.err(e))?,
                Err(e) => log::warn!("recording: the setup is left out: {e}"),
            }
        }
        self.handle = Some(handle);
        if matches!(self.to, RecordTo::Rotating { .. }) {
            self.files.push_back(self.path.clone());
        }
        Ok(())
    }

    /// Writes what is buffered; starts the next file when this one is
    /// full (`setup` then describes where the robot is now).
    pub(crate) fn tick(
        &mut self,
        setup: impl FnOnce() -> Option<Setup>,
    ) -> Result<(), RecordError> {
        let Some(h) = &self.handle else {
            return Ok(());
        };
        h.flush().map_err(|e| self.err(e))?;
        let RecordTo::Rotating {
            file_bytes,
            total_bytes,
            ..
        } = self.to
        else {
            return Ok(());
        };
        let size = std::fs::metadata(&self.path).map_or(0, |m| m.len());
        if size < file_bytes {
            return Ok(());
        }
        self.close(&[])?;
        self.prune(total_bytes);
        self.next_file(setup().as_ref())
    }

    /// Removes the oldest files while all of them hold more than `total`.
    fn prune(&mut self, total: u64) {
        let size = |p: &PathBuf| std::fs::metadata(p).map_or(0, |m| m.len());
        let mut all: u64 = self.files.iter().map(size).sum();
        while all > total && self.files.len() > 1 {
            let Some(old) = self.files.pop_front() else {
                break;
            };
            all = all.saturating_sub(size(&old));
            match std::fs::remove_file(&old) {
                Ok(()) => log::info!("recording: {} removed (size cap)", old.display()),
                Err(e) => log::warn!("recording: cannot remove {}: {e}", old.display()),
            }
        }
    }

    /// Writes `metadata` and closes the file; the bytes it holds.
    pub(crate) fn close(
        &mut self,
        metadata: &[(String, BTreeMap<String, String>)],
    ) -> Result<u64, RecordError> {
        let Some(h) = self.handle.take() else {
            return Ok(0);
        };
        for (name, m) in metadata {
            h.write_metadata(name, m.clone()).map_err(|e| self.err(e))?;
        }
        h.close().map_err(|e| self.err(e))?;
        let size = std::fs::metadata(&self.path).map_or(0, |m| m.len());
        self.closed_bytes += size;
        Ok(size)
    }

    /// Bytes written into the files closed so far.
    pub(crate) fn closed_bytes(&self) -> u64 {
        self.closed_bytes
    }
}

/// The recordings already in `dir`, oldest first.
fn existing(dir: &Path) -> VecDeque<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.file_name()
                        .and_then(|n| n.to_str())
                        .is_some_and(|n| n.starts_with("run-") && n.ends_with(".mcap"))
                })
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v.into()
}

/// `run-<unix milliseconds>.mcap` in `dir`, later than `last` (the
/// newest file's millisecond, updated) and not taken: the names sort as
/// the files were started, even when files are started within one
/// millisecond and the oldest have been removed.
fn fresh_name(dir: &Path, last: &mut u64) -> PathBuf {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64);
    let newest = existing(dir)
        .back()
        .and_then(|p| {
            p.file_stem()?
                .to_str()?
                .strip_prefix("run-")?
                .parse::<u64>()
                .ok()
        })
        .unwrap_or(0);
    let mut ms = now.max(*last + 1).max(newest + 1);
    loop {
        let p = dir.join(format!("run-{ms:014}.mcap"));
        if !p.exists() {
            *last = ms;
            return p;
        }
        ms += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use foxglove::ChannelBuilder;

    /// A rotating recording of 1 KiB files under a 3 KiB cap keeps the
    /// newest files only, each opening with its clock record.
    #[test]
    fn a_full_file_is_followed_by_a_new_one_and_the_oldest_go_beyond_the_cap() {
        let dir = std::env::temp_dir().join(format!("sweepline-rotate-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let ctx = Context::new();
        let ch = ChannelBuilder::new("/x")
            .context(&ctx)
            .message_encoding("json")
            .build_raw()
            .unwrap();
        let to = RecordTo::Rotating {
            dir: dir.clone(),
            file_bytes: 1024,
            total_bytes: 3 * 1024,
        };
        let clock: BTreeMap<String, String> = [("start".to_string(), "0".to_string())].into();
        let mut r = Recorder::open(&ctx, to, Vec::new(), clock, None).unwrap();
        // Bytes zstd cannot shrink much (a simple LCG).
        let mut x = 12345u32;
        let mut opened = 1;
        for _ in 0..40 {
            let payload: Vec<u8> = (0..600)
                .map(|_| {
                    x = x.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                    (x >> 24) as u8
                })
                .collect();
            ch.log(&payload);
            let before = r.path().to_path_buf();
            r.tick(|| None).unwrap();
            opened += usize::from(r.path() != before);
        }
        r.close(&[]).unwrap();
        let files = existing(&dir);
        assert!(opened >= 10, "{opened} files opened");
        assert!((2..=4).contains(&files.len()), "{files:?}");
        let total: u64 = files
            .iter()
            .map(|p| std::fs::metadata(p).unwrap().len())
            .sum();
        assert!(total <= 3 * 1024 + 2048, "{total} bytes kept");
        // Every file but the one opened by the last tick holds messages.
        for f in files.iter().take(files.len() - 1) {
            let bytes = std::fs::read(f).unwrap();
            let n = mcap::MessageStream::new(&bytes).unwrap().count();
            assert!(n >= 1, "{}: {n} messages", f.display());
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
