//! Recordings: every control tick of a node's controllers, written to a file while the node runs
//! (`penelope node --record FILE`), so that a task run by several processes, on several hosts,
//! can be reported on as [`run`](super::run) reports on one process ([`from_recordings`]).
//!
//! The file is a sequence of frames, each a little-endian `u32` length and a postcard
//! [`Entry`]: first the node's name, then each recorded controller's name with its index, then
//! ticks tagged with that index. A reader takes every whole frame and stops at a cut-off last
//! one, so a recording can be read while its node is still writing it.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use penelope_hal::Transition;
use serde::{Deserialize, Serialize};

use super::{RECORD_CAPACITY, RunError, RunOptions, RunOutput, find_task};
use crate::node::Node;
use crate::objects::runtime::{TickRecord, TickStream};
use crate::objects::teleop_end::LinkStatsSource;
use crate::proto::{Call, LinkRecord, Method};
use crate::system::SystemFile;
use penelope_rt_core::clock::MonotonicClock;

/// The format's version, in the first frame.
pub const RECORDING_VERSION: u32 = 1;

/// How often the recorder writes what its streams hold.
const DRAIN_EVERY: Duration = Duration::from_millis(50);
/// How often it writes each link's statistics.
const LINK_EVERY: Duration = Duration::from_millis(100);

/// The largest frame a reader accepts (a tick is a few hundred bytes).
const MAX_FRAME: usize = 64 * 1024;

/// One frame of a recording.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub enum Entry {
    /// The first frame: the format's version and the recording node.
    Header {
        /// [`RECORDING_VERSION`].
        version: u32,
        /// The node's name.
        node: String,
    },
    /// A recorded controller and the index its ticks carry.
    Controller {
        /// The index.
        index: u16,
        /// The controller's name on the node.
        name: String,
    },
    /// One control tick of controller `index`.
    Tick {
        /// The controller's index.
        index: u16,
        /// The tick (boxed: a tick is far larger than the other entries).
        record: Box<TickRecord>,
    },
    /// The state and statistics of channel `channel`'s link to another node, now and then
    /// (every tenth of a second, and at the end).
    Link {
        /// The channel's name on the node.
        channel: String,
        /// What its link counted (boxed, as a tick is).
        record: Box<LinkRecord>,
    },
    /// Ticks of controller `index` its stream lost (the recorder fell behind), at the end.
    Dropped {
        /// The controller's index.
        index: u16,
        /// Ticks lost.
        count: u64,
    },
}

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
    /// The file is not a recording of this version, or a frame is malformed.
    #[error("{path}: not a recording: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// A recording read back.
#[derive(Clone, Debug, Default)]
pub struct Recording {
    /// The node that wrote it.
    pub node: String,
    /// Every recorded controller's ticks, in order, by name.
    pub controllers: BTreeMap<String, Vec<TickRecord>>,
    /// Ticks lost by the recorder, by controller (written when the recording ends).
    pub dropped: BTreeMap<String, u64>,
    /// The records of each channel's link to another node, in order, by channel.
    pub links: BTreeMap<String, Vec<LinkRecord>>,
}

/// Reads the whole frames of the recording at `path` (a cut-off last frame, being written, is
/// left out).
///
/// # Errors
/// [`RecordingError`] for a file that cannot be read, or is not a recording.
pub fn read_recording(path: &Path) -> Result<Recording, RecordingError> {
    let mut bytes = Vec::new();
    File::open(path)
        .and_then(|mut f| f.read_to_end(&mut bytes))
        .map_err(|source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    let bad = |message: String| RecordingError::Format {
        path: path.to_path_buf(),
        message,
    };
    let mut recording = Recording::default();
    let mut names: BTreeMap<u16, String> = BTreeMap::new();
    let mut rest = bytes.as_slice();
    let mut first = true;
    while rest.len() >= 4 {
        let len = u32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]]) as usize;
        if len > MAX_FRAME {
            return Err(bad(format!("a frame of {len} bytes")));
        }
        let Some(frame) = rest.get(4..4 + len) else {
            break; // being written
        };
        rest = &rest[4 + len..];
        let entry: Entry =
            postcard::from_bytes(frame).map_err(|e| bad(format!("a malformed frame: {e}")))?;
        match (first, entry) {
            (true, Entry::Header { version, node }) if version == RECORDING_VERSION => {
                recording.node = node;
            }
            (true, Entry::Header { version, .. }) => {
                return Err(bad(format!(
                    "version {version}, this program reads {RECORDING_VERSION}"
                )));
            }
            (true, _) => return Err(bad("no header".into())),
            (false, Entry::Header { .. }) => return Err(bad("a second header".into())),
            (false, Entry::Controller { index, name }) => {
                recording.controllers.entry(name.clone()).or_default();
                names.insert(index, name);
            }
            (false, Entry::Tick { index, record }) => {
                let name = names
                    .get(&index)
                    .ok_or_else(|| bad(format!("a tick of unknown controller {index}")))?;
                recording
                    .controllers
                    .entry(name.clone())
                    .or_default()
                    .push(*record);
            }
            (false, Entry::Link { channel, record }) => {
                recording.links.entry(channel).or_default().push(*record);
            }
            (false, Entry::Dropped { index, count }) => {
                let name = names
                    .get(&index)
                    .ok_or_else(|| bad(format!("a count of unknown controller {index}")))?;
                recording.dropped.insert(name.clone(), count);
            }
        }
        first = false;
    }
    if first {
        return Err(bad("empty".into()));
    }
    Ok(recording)
}

/// Writes a node's recorded controllers to a file from a thread of its own (normal priority:
/// the loops hand their ticks over through bounded streams and never wait for it).
pub struct Recorder {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<u64, RecordingError>>>,
}

impl Recorder {
    /// Starts writing `streams` (controller name, ticks) of node `node` to `path`, with the
    /// statistics of `links` (channel name, where its link's counters are).
    ///
    /// # Errors
    /// [`RecordingError::Io`] when the file cannot be created.
    pub fn start(
        path: &Path,
        node: &str,
        streams: Vec<(String, TickStream)>,
        links: Vec<(String, LinkStatsSource)>,
    ) -> Result<Recorder, RecordingError> {
        let io = |source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut out = BufWriter::new(File::create(path).map_err(io)?);
        let write = move |out: &mut BufWriter<File>, e: &Entry| -> std::io::Result<()> {
            let bytes = postcard::to_allocvec(e).map_err(std::io::Error::other)?;
            out.write_all(&(bytes.len() as u32).to_le_bytes())?;
            out.write_all(&bytes)
        };
        write(
            &mut out,
            &Entry::Header {
                version: RECORDING_VERSION,
                node: node.to_string(),
            },
        )
        .map_err(io)?;
        for (i, (name, _)) in streams.iter().enumerate() {
            let entry = Entry::Controller {
                index: i as u16,
                name: name.clone(),
            };
            write(&mut out, &entry).map_err(io)?;
        }
        out.flush().map_err(io)?;
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let file = path.to_path_buf();
        let thread = std::thread::Builder::new()
            .name("recorder".into())
            .spawn(move || {
                let io = |source| RecordingError::Io {
                    path: file.clone(),
                    source,
                };
                let mut written = 0u64;
                let mut links_at: Option<Instant> = None;
                loop {
                    let stopping = flag.load(Ordering::Relaxed);
                    for (i, (_, stream)) in streams.iter().enumerate() {
                        while let Ok(record) = stream.ticks.try_recv() {
                            let entry = Entry::Tick {
                                index: i as u16,
                                record: Box::new(record),
                            };
                            write(&mut out, &entry).map_err(io)?;
                            written += 1;
                        }
                    }
                    if stopping || links_at.is_none_or(|t| t.elapsed() >= LINK_EVERY) {
                        links_at = Some(Instant::now());
                        let now = MonotonicClock::read().as_nanos();
                        for (channel, source) in &links {
                            if let Some(stats) = source.latest() {
                                let entry = Entry::Link {
                                    channel: channel.clone(),
                                    record: Box::new(stats.record(now)),
                                };
                                write(&mut out, &entry).map_err(io)?;
                            }
                        }
                    }
                    if stopping {
                        for (i, (_, stream)) in streams.iter().enumerate() {
                            let count = stream.dropped.load(Ordering::Relaxed);
                            let entry = Entry::Dropped {
                                index: i as u16,
                                count,
                            };
                            write(&mut out, &entry).map_err(io)?;
                        }
                        out.flush().map_err(io)?;
                        return Ok(written);
                    }
                    out.flush().map_err(io)?;
                    // A batch writer: the streams hold a minute of ticks, so a twentieth of a
                    // second between batches costs nothing and keeps the writes few.
                    std::thread::sleep(DRAIN_EVERY);
                }
            })
            .map_err(io)?;
        Ok(Recorder {
            stop,
            thread: Some(thread),
        })
    }

    /// Writes what is left and closes the file: the ticks written.
    ///
    /// # Errors
    /// [`RecordingError::Io`] when a write failed.
    pub fn finish(mut self) -> Result<u64, RecordingError> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(_)) | None => Ok(0),
        }
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Applies `file` to `node` as [`SystemFile::apply`] does, but starts recording each
/// controller the file activates on this node (to `path`) before activating it, so the
/// recording holds every tick from the first.
///
/// # Errors
/// [`RunError`] when the file is refused, a controller cannot be recorded or activated, or the
/// file cannot be created.
pub fn apply_recorded(
    node: &Node,
    file: &SystemFile,
    path: &Path,
) -> Result<(Vec<crate::proto::ObjectInfo>, Recorder), RunError> {
    let mut deferred = file.clone();
    let mut to_activate = Vec::new();
    for o in &mut deferred.objects {
        if o.active && (o.node.is_empty() || o.node == node.name()) {
            to_activate.push(o.name.clone());
        }
        o.active = false;
    }
    let created = deferred.apply(node)?;
    let node_error = |what: String| move |error| RunError::Node { what, error };
    let mut streams = Vec::new();
    for name in &to_activate {
        let stream = node
            .creator()
            .record_ticks(name, RECORD_CAPACITY)
            .map_err(node_error(format!("recording `{name}`")))?;
        streams.push((name.clone(), stream));
    }
    // The links of this node's channels to other nodes.
    let mut links = Vec::new();
    for o in deferred.objects_on(node.name()) {
        if o.kind == "trajectory/teleop"
            && let Ok(Some(source)) = node.creator().link_stats_source(&o.name)
        {
            links.push((o.name.clone(), source));
        }
    }
    let recorder = Recorder::start(path, node.name(), streams, links)
        .map_err(|e| RunError::Task(e.to_string()))?;
    for name in &to_activate {
        node.call(Call::Object {
            object: name.clone(),
            method: Method::Transition(Transition::Activate),
        })
        .map_err(node_error(format!("activating `{name}`")))?;
    }
    Ok((created, recorder))
}

/// The report's input from recordings of a task run by separate processes: the master's and
/// the slave's ticks from the recordings that hold them, from the master's first tick (the
/// task's start: its hand begins there) for the task's duration (`options.duration`, else the
/// operator's script); `None` when a recording does not reach that far yet.
///
/// # Errors
/// [`RunError::Task`] when the file has no task or no recording holds its controllers.
pub fn from_recordings(
    file: &SystemFile,
    options: &RunOptions,
    recordings: &[Recording],
) -> Result<Option<RunOutput>, RunError> {
    let task = find_task(file, options)?;
    let mut info = task.info;
    let find = |node: &str, controller: &str| {
        recordings
            .iter()
            .filter(|r| node.is_empty() || r.node == node)
            .find_map(|r| r.controllers.get(controller))
            .ok_or_else(|| {
                RunError::Task(format!(
                    "no recording holds controller `{controller}` of node `{node}`"
                ))
            })
    };
    let master = find(&task.node_of.0, &info.controllers.0)?;
    let slave = find(&task.node_of.1, &info.controllers.1)?;
    let dropped_of = |node: &str, controller: &str| {
        recordings
            .iter()
            .filter(|r| node.is_empty() || r.node == node)
            .find_map(|r| r.dropped.get(controller).copied())
            .unwrap_or(0)
    };
    let dropped = (
        dropped_of(&task.node_of.0, &info.controllers.0),
        dropped_of(&task.node_of.1, &info.controllers.1),
    );
    let Some(first) = master.first() else {
        return Ok(None);
    };
    let start = first.sample.time;
    let end = start + task.duration;
    let reached = |ticks: &[TickRecord]| ticks.last().is_some_and(|t| t.sample.time >= end);
    if !reached(master) || !reached(slave) {
        return Ok(None);
    }
    info.start = start;
    let within = |ticks: &[TickRecord]| -> Vec<TickRecord> {
        ticks
            .iter()
            .filter(|t| t.sample.time >= start && t.sample.time < end)
            .copied()
            .collect()
    };
    Ok(Some(RunOutput {
        master: within(master),
        slave: within(slave),
        info,
        dropped,
    }))
}
