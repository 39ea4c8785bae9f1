//! The recorder: a thread of its own that writes what a node's streams, links and lifecycle
//! hold to a recording file, in one [`RecordProfile`] or the other.

use std::fs::File;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::mcap_log::{McapLog, McapTotals};
use super::ros2_log::Ros2Log;
use super::scene::{SceneConfig, SceneWriter};
use super::{RecordProfile, RecordingError};
use crate::common_clock::CommonClock;
use crate::objects::clock::ClockReader;
use crate::objects::lifecycle_feed::LifecycleEvent;
use crate::objects::link_source::{LinkSource, StreamDatagram};
use crate::objects::tick::{TickRecord, TickStream};
use penelope_protocol::proto::CameraFrame;

/// How often the recorder writes what its streams hold.
const DRAIN_EVERY: Duration = Duration::from_millis(50);
/// How often it writes each link's statistics.
const LINK_EVERY: Duration = Duration::from_millis(100);
/// How often it ends the MCAP chunk being written, so that a reader sees the ticks so far.
pub const FLUSH_EVERY: Duration = Duration::from_millis(200);

/// Lifecycle events a recorder's reader holds before it loses some (transitions are rare: a
/// system file of a hundred objects makes a few hundred).
pub const LIFECYCLE_CAPACITY: usize = 4096;

/// What a node's recording is made of: the node, what it records and the clocks it stamps
/// the records with.
pub struct RecordingSources<'a> {
    /// The node's name, written in the file.
    pub node: &'a str,
    /// Each recorded controller's name and the stream of its ticks.
    pub streams: Vec<(String, TickStream)>,
    /// Each channel's name and where its link's counters and datagrams are (samples from the
    /// start on).
    pub links: Vec<(String, LinkSource)>,
    /// The node's lifecycle transitions: a reader from [`Creator::lifecycle_events`], if any.
    ///
    /// [`Creator::lifecycle_events`]: crate::objects::Creator::lifecycle_events
    pub lifecycle: Option<Receiver<LifecycleEvent>>,
    /// The node's estimate of the common clock: written to `/clock` every 100 ms.
    pub clock: &'a CommonClock,
    /// The node's clock, which the link records and `/clock` are stamped with.
    pub node_time: ClockReader,
    /// The robots drawn in 3D from the streams' ticks ([`super::scene`],
    /// [`Creator::scene_for`]).
    ///
    /// [`Creator::scene_for`]: crate::objects::Creator::scene_for
    pub scene: SceneConfig,
}

/// What the recorder's thread writes to: a file in one profile or the other.
enum Sink {
    Penelope(McapLog, SceneWriter),
    Ros2(Ros2Log),
}

impl Sink {
    /// A `penelope` recording's file with its first clock record, its controllers' channels
    /// and its scene's description written.
    fn penelope(
        mut log: McapLog,
        sources: &RecordingSources<'_>,
        names: &[String],
    ) -> Result<Sink, RecordingError> {
        let start_ns = sources.node_time.now_ns();
        let clock = sources.clock;
        log.clock(start_ns, clock.source(), &clock.estimate())?;
        for name in names {
            log.add_controller(name)?;
        }
        let scene = SceneWriter::new(sources.scene.clone(), names);
        scene.describe(&mut log, start_ns)?;
        log.flush()?;
        Ok(Sink::Penelope(log, scene))
    }

    /// A `ros2` recording's file with the common clock's offset known so far.
    fn ros2(mut log: Ros2Log, clock: &CommonClock) -> Result<Sink, RecordingError> {
        if let Some(offset) = clock.estimate().offset_ns {
            log.set_clock_offset(offset);
        }
        log.flush()?;
        Ok(Sink::Ros2(log))
    }

    fn tick(&mut self, stream: usize, record: &TickRecord) -> Result<(), RecordingError> {
        match self {
            Sink::Penelope(log, scene) => {
                log.tick(stream, record)?;
                scene.tick(log, stream, record)
            }
            Sink::Ros2(log) => log.tick(stream, record),
        }
    }

    fn flush(&mut self) -> Result<(), RecordingError> {
        match self {
            Sink::Penelope(log, _) => log.flush(),
            Sink::Ros2(log) => log.flush(),
        }
    }

    fn finish(self, dropped: &[u64]) -> Result<McapTotals, RecordingError> {
        match self {
            Sink::Penelope(log, _) => log.finish(dropped),
            Sink::Ros2(log) => log.finish(dropped),
        }
    }
}

/// Writes a node's recorded controllers to a file from a thread of its own (normal priority:
/// the loops hand their ticks to the telemetry pump, which hands them to the recorder through
/// bounded streams; neither waits for it, a full stream loses ticks and counts them).
pub struct Recorder {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<u64, RecordingError>>>,
}

impl Recorder {
    /// Starts writing `sources` to the recording at `path`, in `profile`: `file` is the file
    /// at `path` already created (exclusively, links not followed: a client's recording,
    /// [`crate::objects::files::create_in`]), else `path` is created.
    ///
    /// A [`RecordProfile::Ros2`] file holds the ROS 2 topic set of the recorded controllers'
    /// robots and the links' `/diagnostics` ([`super::ros2_log`]; no lifecycle, streams or
    /// clock channels: the lifecycle is read and left out).
    ///
    /// # Errors
    /// [`RecordingError::Io`] when the file cannot be created or written.
    pub fn start(
        profile: RecordProfile,
        path: &Path,
        file: Option<File>,
        sources: RecordingSources<'_>,
    ) -> Result<Recorder, RecordingError> {
        Recorder::start_with_cameras(profile, path, file, sources, Vec::new())
    }

    /// As [`start`](Self::start), also writing `cameras`' frames (each camera's name and a tap
    /// of its frames): in a [`RecordProfile::Penelope`] file, `/<camera>/image` and
    /// `/<camera>/calibration` ([`McapLog::camera_frame`]); in a `ros2` file,
    /// `/<camera>/image_raw/compressed` and `/<camera>/camera_info` ([`Ros2Log::camera_frame`]).
    ///
    /// # Errors
    /// As [`start`](Self::start).
    pub fn start_with_cameras(
        profile: RecordProfile,
        path: &Path,
        file: Option<File>,
        sources: RecordingSources<'_>,
        cameras: Vec<(String, Receiver<CameraFrame>)>,
    ) -> Result<Recorder, RecordingError> {
        let names: Vec<String> = sources.streams.iter().map(|(n, _)| n.clone()).collect();
        let node = sources.node;
        let sink = match profile {
            RecordProfile::Penelope => {
                let log = match file {
                    Some(file) => McapLog::create_in(file, path, node)?,
                    None => McapLog::create(path, node)?,
                };
                Sink::penelope(log, &sources, &names)?
            }
            RecordProfile::Ros2 => {
                let scene = sources.scene.clone();
                let log = match file {
                    Some(file) => Ros2Log::create_in(file, path, node, scene, &names)?,
                    None => Ros2Log::create(path, node, scene, &names)?,
                };
                Sink::ros2(log, sources.clock)?
            }
        };
        let mut writer = RecorderThread::new(sink, sources);
        writer.cameras = cameras;
        Recorder::spawn(writer, path)
    }

    /// Starts the recorder's thread.
    fn spawn(writer: RecorderThread, path: &Path) -> Result<Recorder, RecordingError> {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::Builder::new()
            .name("recorder".into())
            .spawn(move || writer.run(&flag))
            .map_err(|source| RecordingError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        Ok(Recorder {
            stop,
            thread: Some(thread),
        })
    }

    /// Writes what is left and closes the file: the ticks written.
    ///
    /// # Errors
    /// [`RecordingError`] when a write failed.
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

/// What the recorder's thread owns: the file and what it takes the records from.
struct RecorderThread {
    sink: Sink,
    streams: Vec<(String, TickStream)>,
    /// Each link with the datagrams its ring had lost before the recording started.
    links: Vec<(String, LinkSource, u64)>,
    lifecycle: Option<Receiver<LifecycleEvent>>,
    clock: CommonClock,
    node_time: ClockReader,
    /// A buffer for the datagrams taken from a link's ring.
    drained: Vec<StreamDatagram>,
    /// Each camera's name and its frames.
    cameras: Vec<(String, Receiver<CameraFrame>)>,
}

impl RecorderThread {
    fn new(sink: Sink, sources: RecordingSources<'_>) -> RecorderThread {
        // What the links' rings held before (or lost while nobody read them) is not this
        // recording's: from here on every sample is written or counted.
        let links = sources
            .links
            .into_iter()
            .map(|(name, source)| {
                let before = source.skip_datagrams();
                (name, source, before)
            })
            .collect();
        RecorderThread {
            sink,
            streams: sources.streams,
            links,
            lifecycle: sources.lifecycle,
            clock: sources.clock.clone(),
            node_time: sources.node_time,
            drained: Vec::new(),
            cameras: Vec::new(),
        }
    }

    /// Writes until `stop` is set, then finishes the file: the ticks written.
    fn run(mut self, stop: &AtomicBool) -> Result<u64, RecordingError> {
        let mut links_at: Option<Instant> = None;
        let mut flushed = Instant::now();
        loop {
            let stopping = stop.load(Ordering::Relaxed);
            self.drain()?;
            if stopping || links_at.is_none_or(|t| t.elapsed() >= LINK_EVERY) {
                links_at = Some(Instant::now());
                self.write_links()?;
            }
            if stopping {
                let dropped: Vec<u64> = self
                    .streams
                    .iter()
                    .map(|(_, s)| s.dropped.load(Ordering::Relaxed))
                    .collect();
                return self.sink.finish(&dropped).map(|t| t.ticks);
            }
            if flushed.elapsed() >= FLUSH_EVERY {
                flushed = Instant::now();
                self.sink.flush()?;
            }
            // A batch writer: the streams hold a minute of ticks, so a twentieth of a
            // second between batches costs nothing and keeps the writes few.
            std::thread::sleep(DRAIN_EVERY);
        }
    }

    /// Writes the ticks, lifecycle events and stream samples waiting.
    fn drain(&mut self) -> Result<(), RecordingError> {
        for (i, (_, stream)) in self.streams.iter().enumerate() {
            while let Ok(record) = stream.ticks.try_recv() {
                self.sink.tick(i, &record)?;
            }
        }
        for (camera, frames) in &self.cameras {
            for frame in frames.try_iter() {
                match &mut self.sink {
                    Sink::Penelope(log, _) => log.camera_frame(camera, &frame)?,
                    Sink::Ros2(log) => log.camera_frame(camera, &frame)?,
                }
            }
        }
        for event in self.lifecycle.iter().flat_map(Receiver::try_iter) {
            if let Sink::Penelope(log, _) = &mut self.sink {
                log.lifecycle(&event)?;
            }
        }
        for (channel, source, _) in &self.links {
            source.drain_datagrams(|d| self.drained.push(d));
            for d in self.drained.drain(..) {
                if let Sink::Penelope(log, _) = &mut self.sink {
                    log.datagram(channel, &d)?;
                }
            }
        }
        Ok(())
    }

    /// Writes the clock, each link's statistics and what was lost so far.
    fn write_links(&mut self) -> Result<(), RecordingError> {
        let now = self.node_time.now_ns();
        let clock = &self.clock;
        match &mut self.sink {
            Sink::Penelope(log, _) => {
                log.clock(now, clock.source(), &clock.estimate())?;
                for (channel, source, before) in &self.links {
                    if let Some(stats) = source.latest() {
                        log.link(channel, &stats.record(now))?;
                    }
                    let lost = source.datagrams_dropped().wrapping_sub(*before);
                    log.datagrams_dropped(channel, lost)?;
                }
                // What the streams lost so far, when it grew.
                for (i, (_, stream)) in self.streams.iter().enumerate() {
                    log.dropped(i, stream.dropped.load(Ordering::Relaxed))?;
                }
            }
            Sink::Ros2(log) => {
                if let Some(offset) = clock.estimate().offset_ns {
                    log.set_clock_offset(offset);
                }
                for (channel, source, _) in &self.links {
                    if let Some(stats) = source.latest() {
                        log.link(channel, &stats.record(now))?;
                    }
                }
            }
        }
        Ok(())
    }
}
