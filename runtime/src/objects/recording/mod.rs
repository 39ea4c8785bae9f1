//! Recordings: every control tick of a node's controllers, their safety events and the
//! statistics of its channels' links, written to an MCAP file while the node runs (`penelope
//! node --record FILE`, or the creator's `record` call), and read back: the supervisor's task
//! runs report on a task run by several processes, on several hosts, from them.
//!
//! The file's channels and messages are [`mcap_log`]'s. The [`Recorder`]
//! finishes a chunk every [`FLUSH_EVERY`], and [`read_recording`] takes every message up to a
//! cut-off last record, so a recording can be read while its node is still writing it.

use std::path::{Path, PathBuf};

pub mod mcap_log;
mod profile;
mod reader;
mod recorder;
pub mod ros2_log;
pub mod ros2_topics;
pub mod scene;

pub use profile::RecordProfile;
pub(crate) use reader::check_record_lengths;
#[cfg(test)]
pub(crate) use reader::crafted_mcap_with_a_huge_record;
pub use reader::{Recording, read_recording};
pub use recorder::{FLUSH_EVERY, LIFECYCLE_CAPACITY, Recorder, RecordingSources};
pub use scene::{DEFAULT_SCENE_HZ, SceneConfig, SceneRobot};

/// Why a recording could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be opened, written or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// The MCAP library refused to write or read the file.
    #[error("{path}: {source}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// The error.
        source: mcap::McapError,
    },
    /// The file is not a recording, or a message is malformed.
    #[error("{path}: not a recording: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

impl RecordingError {
    /// Maps the MCAP library's errors on file `path` to [`RecordingError::Mcap`].
    pub(crate) fn mcap(path: &Path) -> impl Fn(mcap::McapError) -> RecordingError + Copy + '_ {
        move |source| RecordingError::Mcap {
            path: path.to_path_buf(),
            source,
        }
    }
}
