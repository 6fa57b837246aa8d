//! The record of a run's restarts: for each resume, which checkpoint it
//! started from and what the daemon before it had done after that checkpoint
//! (from its heartbeat), i.e. how much progress the crash lost. Kept as
//! `resume.toml` in the run folder, where the report reads it.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::RunProgress;

/// File name of the resume record in a run folder.
pub const RESUME_FILE: &str = "resume.toml";

/// Why the resume record could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ResumeLogError {
    /// File system error.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// OS error.
        source: std::io::Error,
    },
    /// The file is not a resume record.
    #[error("{path} is not a valid resume record: {message}")]
    Parse {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
}

/// How far a run had got at one moment (a checkpoint or a heartbeat).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProgressMark {
    /// Sequence number of the checkpoint (for a heartbeat: of the last
    /// checkpoint before it).
    pub sequence: u64,
    /// Wall-clock UNIX time (s) it was written, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unix: Option<f64>,
    /// Run time (s) on the run's own clock.
    pub elapsed: f64,
    /// Coverage by the daemon's record, 0..=1.
    pub coverage: f64,
    /// Scans processed.
    pub scans: u64,
    /// Path driven (m).
    pub path_length: f64,
}

impl ProgressMark {
    /// The mark of `p`, written at UNIX time `unix` if known.
    pub fn new(p: &RunProgress, unix: Option<f64>) -> Self {
        Self {
            sequence: p.sequence,
            unix,
            elapsed: p.elapsed,
            coverage: p.coverage,
            scans: p.scans,
            path_length: p.path_length,
        }
    }
}

/// One resume of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResumeEntry {
    /// Which restart of the run this is (1 = the first resume).
    pub restart: u32,
    /// Wall-clock UNIX time (s) the resumed daemon started.
    pub(crate) resumed_unix: f64,
    /// The checkpoint resumed from.
    pub checkpoint: ProgressMark,
    /// The previous daemon's last heartbeat after that checkpoint (its last
    /// sign of life before the crash), when there is one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_alive: Option<ProgressMark>,
    /// Set when the current checkpoint was unusable and its previous copy
    /// was resumed from: why.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fell_back: Option<String>,
}

impl ResumeEntry {
    /// Age of the checkpoint at the previous daemon's last sign of life, on
    /// the run's clock (s).
    pub fn checkpoint_age(&self) -> Option<f64> {
        self.last_alive
            .map(|a| (a.elapsed - self.checkpoint.elapsed).max(0.0))
    }

    /// The same on the wall clock (s), when both times are known.
    pub(crate) fn checkpoint_age_wall(&self) -> Option<f64> {
        let a = self.last_alive?.unix?;
        Some((a - self.checkpoint.unix?).max(0.0))
    }

    /// Coverage (0..=1, daemon's record) reached after the checkpoint and
    /// lost by the crash.
    pub fn coverage_lost(&self) -> Option<f64> {
        self.last_alive
            .map(|a| (a.coverage - self.checkpoint.coverage).max(0.0))
    }

    /// Wall time (s) from the last sign of life (else the checkpoint) to the
    /// resume.
    pub(crate) fn downtime(&self) -> Option<f64> {
        let last = self
            .last_alive
            .and_then(|a| a.unix)
            .or(self.checkpoint.unix)?;
        Some((self.resumed_unix - last).max(0.0))
    }
}

/// Every resume of a run, oldest first.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResumeLog {
    /// The resumes.
    #[serde(default)]
    pub resume: Vec<ResumeEntry>,
}

impl ResumeLog {
    /// Reads `dir/resume.toml`; `Ok(None)` when there is none (a run that
    /// was never resumed).
    pub fn read(dir: &Path) -> Result<Option<Self>, ResumeLogError> {
        let path = dir.join(RESUME_FILE);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => {
                return Err(ResumeLogError::Io {
                    path: path.display().to_string(),
                    source,
                })
            }
        };
        toml::from_str(&text)
            .map(Some)
            .map_err(|e| ResumeLogError::Parse {
                path: path.display().to_string(),
                message: e.to_string(),
            })
    }

    /// Writes `dir/resume.toml` (creating `dir`).
    pub fn write(&self, dir: &Path) -> Result<(), ResumeLogError> {
        let path = dir.join(RESUME_FILE);
        let io = |source| ResumeLogError::Io {
            path: path.display().to_string(),
            source,
        };
        let text = toml::to_string(self).map_err(|e| ResumeLogError::Parse {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        std::fs::create_dir_all(dir).map_err(io)?;
        std::fs::write(&path, text).map_err(io)
    }

    /// Records a new resume in `dir`: the entries of earlier restarts of the
    /// same run are kept (an unreadable record is replaced), and `entry`
    /// is appended.
    pub(crate) fn append(dir: &Path, entry: ResumeEntry) -> Result<Self, ResumeLogError> {
        let mut log = Self::read(dir).ok().flatten().unwrap_or_default();
        log.resume.retain(|e| e.restart < entry.restart);
        log.resume.push(entry);
        log.write(dir)?;
        Ok(log)
    }

    /// Removes `dir/resume.toml` (a fresh start: no resume to report).
    pub fn clear(dir: &Path) -> Result<(), ResumeLogError> {
        let path = dir.join(RESUME_FILE);
        match std::fs::remove_file(&path) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(source) => Err(ResumeLogError::Io {
                path: path.display().to_string(),
                source,
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mark(seq: u64, unix: f64, elapsed: f64, coverage: f64) -> ProgressMark {
        ProgressMark {
            sequence: seq,
            unix: Some(unix),
            elapsed,
            coverage,
            scans: 10 * seq,
            path_length: elapsed / 10.0,
        }
    }

    #[test]
    fn derived_figures_and_file_round_trip() {
        let dir = std::env::temp_dir().join(format!("sweepline-resume-log-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(ResumeLog::read(&dir).unwrap(), None);
        let e1 = ResumeEntry {
            restart: 1,
            resumed_unix: 1000.5,
            checkpoint: mark(12, 998.0, 109.0, 0.307),
            last_alive: Some(mark(12, 998.4, 113.0, 0.315)),
            fell_back: None,
        };
        assert!((e1.checkpoint_age().unwrap() - 4.0).abs() < 1e-9);
        assert!((e1.checkpoint_age_wall().unwrap() - 0.4).abs() < 1e-9);
        assert!((e1.coverage_lost().unwrap() - 0.008).abs() < 1e-9);
        assert!((e1.downtime().unwrap() - 2.1).abs() < 1e-9);
        let e2 = ResumeEntry {
            restart: 2,
            last_alive: None,
            fell_back: Some("file checksum mismatch".into()),
            ..e1.clone()
        };
        assert_eq!(e2.coverage_lost(), None);
        assert!((e2.downtime().unwrap() - 2.5).abs() < 1e-9);

        ResumeLog::append(&dir, e1.clone()).unwrap();
        let log = ResumeLog::append(&dir, e2.clone()).unwrap();
        assert_eq!(log.resume, vec![e1.clone(), e2]);
        assert_eq!(ResumeLog::read(&dir).unwrap().unwrap(), log);
        // A new first restart (a new run in the same folder) starts over.
        let log = ResumeLog::append(&dir, e1.clone()).unwrap();
        assert_eq!(log.resume, vec![e1]);
        ResumeLog::clear(&dir).unwrap();
        assert_eq!(ResumeLog::read(&dir).unwrap(), None);
        ResumeLog::clear(&dir).unwrap();

        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(RESUME_FILE), "[[resume]]\nrestart = \"x\"\n").unwrap();
        let err = ResumeLog::read(&dir).unwrap_err().to_string();
        assert!(err.contains("not a valid resume record"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
