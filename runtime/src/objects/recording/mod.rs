//! Recordings: every control tick of a node's controllers, their safety events and the
//! statistics of its channels' links, written to an MCAP file while the node runs (`penelope
//! node --record FILE`, or the creator's `record` call), and read back: the supervisor's task
//! runs report on a task run by several processes, on several hosts, from them.
//!
//! The file's channels and messages are [`mcap_log`]'s. The [`Recorder`]
//! finishes a chunk every [`FLUSH_EVERY`], and [`read_recording`] takes every message up to a
//! cut-off last record, so a recording can be read while its node is still writing it.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

pub mod mcap_log;
mod reader;
pub mod ros2_log;
pub mod ros2_topics;
pub mod scene;

use crate::common_clock::CommonClock;
use crate::objects::clock::ClockReader;
use crate::objects::lifecycle_feed::LifecycleEvent;
use crate::objects::link_source::LinkSource;
use crate::objects::tick::TickStream;
use mcap_log::{McapLog, McapTotals};
pub(crate) use reader::check_record_lengths;
#[cfg(test)]
pub(crate) use reader::crafted_mcap_with_a_huge_record;
pub use reader::{Recording, read_recording};
use ros2_log::Ros2Log;
pub use scene::{DEFAULT_SCENE_HZ, SceneConfig, SceneRobot};

/// How often the recorder writes what its streams hold.
const DRAIN_EVERY: Duration = Duration::from_millis(50);
/// How often it writes each link's statistics.
const LINK_EVERY: Duration = Duration::from_millis(100);
/// How often it ends the MCAP chunk being written, so that a reader sees the ticks so far.
pub const FLUSH_EVERY: Duration = Duration::from_millis(200);

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

/// Which messages a recording holds: `penelope` (every tick in full, safety events, links,
/// streams, lifecycle, clock and the 3D scene: [`mcap_log`]; what Penelope's readers, replay
/// and task reports need) or `ros2` (the ROS 2 topic set as CDR: [`ros2_log`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RecordProfile {
    /// Penelope's own channels (JSON): the default.
    #[default]
    Penelope,
    /// The ROS 2 topic set (CDR, `ros2msg` schemas).
    Ros2,
}

impl RecordProfile {
    /// Every profile, by name.
    pub const ALL: [RecordProfile; 2] = [RecordProfile::Penelope, RecordProfile::Ros2];

    /// `penelope` or `ros2`.
    pub const fn as_str(self) -> &'static str {
        match self {
            RecordProfile::Penelope => "penelope",
            RecordProfile::Ros2 => "ros2",
        }
    }

    /// The profile named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.as_str() == name)
    }
}

impl std::fmt::Display for RecordProfile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for RecordProfile {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::from_name(s)
            .ok_or_else(|| format!("unknown recording profile `{s}` (penelope or ros2)"))
    }
}

/// What the recorder's thread writes to: a file in one profile or the other.
enum Sink {
    Penelope(McapLog, scene::SceneWriter),
    Ros2(Ros2Log),
}

impl Sink {
    fn tick(
        &mut self,
        stream: usize,
        record: &crate::objects::tick::TickRecord,
    ) -> Result<(), RecordingError> {
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

/// Lifecycle events a recorder's reader holds before it loses some (transitions are rare: a
/// system file of a hundred objects makes a few hundred).
pub const LIFECYCLE_CAPACITY: usize = 4096;

/// Writes a node's recorded controllers to a file from a thread of its own (normal priority:
/// the loops hand their ticks to the telemetry pump, which hands them to the recorder through
/// bounded streams; neither waits for it, a full stream loses ticks and counts them).
pub struct Recorder {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<u64, RecordingError>>>,
}

impl Recorder {
    /// Starts writing `streams` (controller name, ticks) of node `node` to `path`, with the
    /// statistics and stream samples of `links` (channel name, where its link's counters and
    /// datagrams are; samples from now on) and the node's `lifecycle` transitions (a reader
    /// from [`Creator::lifecycle_events`], if any), log times on `clock` (the node's estimate
    /// of the common clock: written to `/clock` every 100 ms); `node_time` is the node's
    /// clock, which the link records and `/clock` are stamped with; `scene`: the robots drawn
    /// in 3D from the streams' ticks ([`scene`], [`Creator::scene_for`]).
    ///
    /// [`Creator::lifecycle_events`]: crate::objects::Creator::lifecycle_events
    /// [`Creator::scene_for`]: crate::objects::Creator::scene_for
    ///
    /// # Errors
    /// [`RecordingError::Io`] when the file cannot be created.
    #[allow(clippy::too_many_arguments)]
    pub fn start(
        path: &Path,
        node: &str,
        streams: Vec<(String, TickStream)>,
        links: Vec<(String, LinkSource)>,
        lifecycle: Option<Receiver<LifecycleEvent>>,
        clock: &CommonClock,
        node_time: ClockReader,
        scene: SceneConfig,
    ) -> Result<Recorder, RecordingError> {
        let log = McapLog::create(path, node)?;
        Recorder::start_with(
            log, path, streams, links, lifecycle, clock, node_time, scene,
        )
    }

    /// As [`start`](Self::start), writing to `file`, already created (exclusively, links not
    /// followed: a client's recording, [`crate::objects::files::create_in`]) at `path`.
    ///
    /// # Errors
    /// [`RecordingError::Io`] when the file cannot be written.
    #[allow(clippy::too_many_arguments)]
    pub fn start_in(
        file: std::fs::File,
        path: &Path,
        node: &str,
        streams: Vec<(String, TickStream)>,
        links: Vec<(String, LinkSource)>,
        lifecycle: Option<Receiver<LifecycleEvent>>,
        clock: &CommonClock,
        node_time: ClockReader,
        scene: SceneConfig,
    ) -> Result<Recorder, RecordingError> {
        let log = McapLog::create_in(file, path, node)?;
        Recorder::start_with(
            log, path, streams, links, lifecycle, clock, node_time, scene,
        )
    }

    /// As [`start`](Self::start) in recording profile `profile`: a [`RecordProfile::Ros2`]
    /// file holds the ROS 2 topic set of the recorded controllers' robots and the links'
    /// `/diagnostics` ([`ros2_log`]; no lifecycle, streams or clock channels: `lifecycle` is
    /// read and left out); `file`: already created (as [`start_in`](Self::start_in)), else
    /// `path` is created.
    ///
    /// # Errors
    /// [`RecordingError::Io`] when the file cannot be created or written.
    #[allow(clippy::too_many_arguments)]
    pub fn start_as(
        profile: RecordProfile,
        file: Option<std::fs::File>,
        path: &Path,
        node: &str,
        streams: Vec<(String, TickStream)>,
        links: Vec<(String, LinkSource)>,
        lifecycle: Option<Receiver<LifecycleEvent>>,
        clock: &CommonClock,
        node_time: ClockReader,
        scene: SceneConfig,
    ) -> Result<Recorder, RecordingError> {
        match (profile, file) {
            (RecordProfile::Penelope, None) => Recorder::start(
                path, node, streams, links, lifecycle, clock, node_time, scene,
            ),
            (RecordProfile::Penelope, Some(file)) => Recorder::start_in(
                file, path, node, streams, links, lifecycle, clock, node_time, scene,
            ),
            (RecordProfile::Ros2, file) => {
                let names: Vec<String> = streams.iter().map(|(n, _)| n.clone()).collect();
                let mut log = match file {
                    Some(file) => Ros2Log::create_in(file, path, node, scene, &names)?,
                    None => Ros2Log::create(path, node, scene, &names)?,
                };
                if let Some(offset) = clock.estimate().offset_ns {
                    log.set_clock_offset(offset);
                }
                log.flush()?;
                Recorder::spawn(
                    Sink::Ros2(log),
                    path,
                    streams,
                    links,
                    lifecycle,
                    clock,
                    node_time,
                )
            }
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn start_with(
        mut log: McapLog,
        path: &Path,
        streams: Vec<(String, TickStream)>,
        links: Vec<(String, LinkSource)>,
        lifecycle: Option<Receiver<LifecycleEvent>>,
        clock: &CommonClock,
        node_time: ClockReader,
        scene: SceneConfig,
    ) -> Result<Recorder, RecordingError> {
        let start_ns = node_time.now_ns();
        log.clock(start_ns, clock.source(), &clock.estimate())?;
        for (name, _) in &streams {
            log.add_controller(name)?;
        }
        let names: Vec<String> = streams.iter().map(|(n, _)| n.clone()).collect();
        let scene = scene::SceneWriter::new(scene, &names);
        scene.describe(&mut log, start_ns)?;
        log.flush()?;
        Recorder::spawn(
            Sink::Penelope(log, scene),
            path,
            streams,
            links,
            lifecycle,
            clock,
            node_time,
        )
    }

    /// Starts the recorder's thread writing to `sink`.
    fn spawn(
        mut sink: Sink,
        path: &Path,
        streams: Vec<(String, TickStream)>,
        links: Vec<(String, LinkSource)>,
        lifecycle: Option<Receiver<LifecycleEvent>>,
        clock: &CommonClock,
        node_time: ClockReader,
    ) -> Result<Recorder, RecordingError> {
        let clock = clock.clone();
        // What the links' rings held before (or lost while nobody read them) is not this
        // recording's: from here on every sample is written or counted.
        let links: Vec<(String, LinkSource, u64)> = links
            .into_iter()
            .map(|(name, source)| {
                let before = source.skip_datagrams();
                (name, source, before)
            })
            .collect();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::Builder::new()
            .name("recorder".into())
            .spawn(move || {
                let mut links_at: Option<Instant> = None;
                let mut drained = Vec::new();
                let mut flushed = Instant::now();
                loop {
                    let stopping = flag.load(Ordering::Relaxed);
                    for (i, (_, stream)) in streams.iter().enumerate() {
                        while let Ok(record) = stream.ticks.try_recv() {
                            sink.tick(i, &record)?;
                        }
                    }
                    for event in lifecycle.iter().flat_map(Receiver::try_iter) {
                        if let Sink::Penelope(log, _) = &mut sink {
                            log.lifecycle(&event)?;
                        }
                    }
                    for (channel, source, _) in &links {
                        source.drain_datagrams(|d| drained.push(d));
                        for d in drained.drain(..) {
                            if let Sink::Penelope(log, _) = &mut sink {
                                log.datagram(channel, &d)?;
                            }
                        }
                    }
                    if stopping || links_at.is_none_or(|t| t.elapsed() >= LINK_EVERY) {
                        links_at = Some(Instant::now());
                        let now = node_time.now_ns();
                        match &mut sink {
                            Sink::Penelope(log, _) => {
                                log.clock(now, clock.source(), &clock.estimate())?;
                                for (channel, source, before) in &links {
                                    if let Some(stats) = source.latest() {
                                        log.link(channel, &stats.record(now))?;
                                    }
                                    let lost = source.datagrams_dropped().wrapping_sub(*before);
                                    log.datagrams_dropped(channel, lost)?;
                                }
                                // What the streams lost so far, when it grew.
                                for (i, (_, stream)) in streams.iter().enumerate() {
                                    log.dropped(i, stream.dropped.load(Ordering::Relaxed))?;
                                }
                            }
                            Sink::Ros2(log) => {
                                if let Some(offset) = clock.estimate().offset_ns {
                                    log.set_clock_offset(offset);
                                }
                                for (channel, source, _) in &links {
                                    if let Some(stats) = source.latest() {
                                        log.link(channel, &stats.record(now))?;
                                    }
                                }
                            }
                        }
                    }
                    if stopping {
                        let dropped: Vec<u64> = streams
                            .iter()
                            .map(|(_, s)| s.dropped.load(Ordering::Relaxed))
                            .collect();
                        return sink.finish(&dropped).map(|t| t.ticks);
                    }
                    if flushed.elapsed() >= FLUSH_EVERY {
                        flushed = Instant::now();
                        sink.flush()?;
                    }
                    // A batch writer: the streams hold a minute of ticks, so a twentieth of a
                    // second between batches costs nothing and keeps the writes few.
                    std::thread::sleep(DRAIN_EVERY);
                }
            })
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

#[cfg(test)]
mod tests {
    use super::mcap_log::McapLog;
    use super::*;
    use crate::objects::link_source::StreamDatagram;
    use crate::objects::tick::TickRecord;
    use penelope_drivers::sim::tap::TapSample;
    use penelope_hal::{JointVector, Timestamp};
    use penelope_protocol::proto::LinkRecord;
    use penelope_rt_core::safety::{EventSet, FaultCause, SafetyEvent, SafetyState};
    use penelope_rt_core::telemetry::TelemetrySample;

    fn scratch(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("penelope-recording-{}-{name}", std::process::id()))
    }

    /// Ticks whose values need every bit of an f64 (thirds, tiny and huge numbers).
    fn ticks(n: u64) -> Vec<TickRecord> {
        (1..=n)
            .map(|i| {
                let x = i as f64 / 3.0;
                let mut events = EventSet::EMPTY;
                if i == 7 {
                    events.insert(SafetyEvent::LinkLost);
                }
                TickRecord {
                    sample: TelemetrySample {
                        time: Timestamp::from_nanos(1_000_000 * i + 17),
                        seq: i,
                        q: JointVector::from_fn(|j, _| x * (j as f64 + 0.1) + 1e-300),
                        qd: JointVector::from_fn(|j, _| -x / (j as f64 + 7.0)),
                        effort: JointVector::from_fn(|j, _| 1e300 / (x + j as f64)),
                        state: if i > 5 {
                            SafetyState::Fault
                        } else {
                            SafetyState::Running
                        },
                        fault: (i > 5).then_some(FaultCause::VelocityLimit { joint: 3 }),
                        events,
                        port_energy: (i % 2 == 0).then_some(-x),
                        ..TelemetrySample::default()
                    },
                    truth: Some(TapSample {
                        kinetic_energy: x.sqrt(),
                        interaction_work: -x * 1e-9,
                        ..TapSample::default()
                    }),
                    clutch: (i % 3 == 0).then_some(i % 2 == 0),
                }
            })
            .collect()
    }

    fn link(time_ns: u64) -> LinkRecord {
        LinkRecord {
            time_ns,
            down: false,
            losses: 1,
            restorations: 1,
            samples_taken: 99,
            samples_dropped: 2,
            samples_missed: 3,
            refused: 0,
            clock_offset_ns: Some(-12_345),
            round_trip_ns: Some(250_000),
            one_way_delay_ns: Some(125_000),
            jitter_ns: None,
            last_heard_ns: Some(1_000),
            heartbeat_loss: 0.1 + 0.2,
            trips: 40,
            trip_p50_ns: Some(120_000),
            trip_p99_ns: Some(300_000),
            trip_max_ns: None,
        }
    }

    #[test]
    fn a_recording_reads_back_bit_for_bit_with_its_links_and_losses() {
        let path = scratch("roundtrip.mcap");
        let (a, b) = (ticks(40), ticks(25));
        let mut log = McapLog::create(&path, "lab").unwrap();
        log.add_controller("display").unwrap();
        log.add_controller("follow").unwrap();
        for t in &a {
            log.tick(0, t).unwrap();
        }
        for t in &b {
            log.tick(1, t).unwrap();
        }
        log.link("link", &link(5)).unwrap();
        log.link("link", &link(9)).unwrap();
        let datagrams = stream_samples();
        for d in &datagrams {
            log.datagram("link", d).unwrap();
        }
        assert!(log.datagrams_dropped("link", 3).unwrap());
        assert!(
            !log.datagrams_dropped("link", 3).unwrap(),
            "written when it grows"
        );
        let totals = log.finish(&[0, 4]).unwrap();
        assert_eq!(totals.ticks, 65);
        let r = read_recording(&path).unwrap();
        assert_eq!(r.node, "lab");
        assert_eq!(r.controllers["display"], a, "every bit of every tick");
        assert_eq!(r.controllers["follow"], b);
        assert_eq!(r.links["link"], vec![link(5), link(9)]);
        assert_eq!(r.dropped["display"], 0);
        assert_eq!(r.dropped["follow"], 4);
        assert_eq!(
            r.datagrams["link"], datagrams,
            "every bit of every stream sample"
        );
        assert_eq!(r.datagrams_dropped["link"], 3);
        let topics: Vec<String> = super::mcap_log::summarize(&path)
            .unwrap()
            .channels
            .into_iter()
            .map(|c| c.topic)
            .filter(|t| t.starts_with("/streams/"))
            .collect();
        assert_eq!(
            topics,
            [
                "/streams/link/master-to-slave",
                "/streams/link/slave-to-master"
            ]
        );
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn the_tick_schema_names_every_event_bit() {
        let schema: serde_json::Value =
            serde_json::from_str(&super::mcap_log::tick_schema()).unwrap();
        let events = schema["properties"]["sample"]["properties"]["events"]["description"]
            .as_str()
            .unwrap()
            .to_string();
        for e in penelope_rt_core::safety::SafetyEvent::ALL {
            assert!(
                events.contains(&format!("{} {}", e as u8, e.as_str())),
                "{events}"
            );
        }
        assert!(events.contains("14 sensor-error"), "{events}");
    }

    /// A sample sent each way and one taken, with every optional part.
    fn stream_samples() -> Vec<StreamDatagram> {
        use crate::objects::link_source::StreamName;
        use penelope_hal::{CartesianReference, Reference};
        use penelope_rt_core::teleop::{PortEnergy, WaveSample};
        let pose = |x: f64| {
            Reference::Cartesian(CartesianReference {
                pose: penelope_hal::Pose::translation(x, 0.1 + 0.2, -1.0 / 3.0),
                ..CartesianReference::default()
            })
        };
        let d = |stream, k: u64, arrived: Option<i64>| StreamDatagram {
            stream,
            time_ns: k * 2_000_000,
            sequence: k,
            sent_ns: (k * 2_000_000) as i64 - 7,
            arrived_ns: arrived,
            one_way_ns: arrived.map(|a| a - (k * 2_000_000) as i64),
            clutch: k.is_multiple_of(2),
            reference: pose(k as f64 * 1e-3 + 1e-17),
            wave: (k == 2).then(|| WaveSample {
                wave: nalgebra::Vector3::new(0.5, -1.25, 3.0),
                integral: nalgebra::Vector3::new(1e-3, 2e-3, -3e-3),
                energy: nalgebra::Vector3::new(0.125, 0.0, 7.5),
            }),
            energy: (k == 3).then_some(PortEnergy { input: 0.375 }),
        };
        vec![
            d(StreamName::MasterToSlave, 1, None),
            d(StreamName::SlaveToMaster, 2, Some(4_000_123)),
            d(StreamName::MasterToSlave, 3, None),
        ]
    }

    #[test]
    fn a_recording_cut_off_anywhere_reads_as_a_prefix_of_its_ticks() {
        let path = scratch("cut.mcap");
        let all = ticks(60);
        let mut log = McapLog::create(&path, "lab").unwrap();
        log.add_controller("display").unwrap();
        for chunk in all.chunks(10) {
            for t in chunk {
                log.tick(0, t).unwrap();
            }
            log.flush().unwrap(); // what the recorder does every FLUSH_EVERY
        }
        log.finish(&[0]).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let cut = scratch("cut-part.mcap");
        let mut seen = 0;
        for len in (16..bytes.len()).step_by(97) {
            std::fs::write(&cut, &bytes[..len]).unwrap();
            let r = read_recording(&cut).unwrap();
            let got = r
                .controllers
                .get("display")
                .map_or(&[][..], |v| v.as_slice());
            assert_eq!(got, &all[..got.len()], "cut at {len}: a prefix");
            assert!(got.len() >= seen, "more of the file, no fewer ticks");
            seen = got.len();
        }
        assert!(
            seen >= 50,
            "flushed chunks are read before the file ends: {seen}"
        );
        let _ = std::fs::remove_file(path);
        let _ = std::fs::remove_file(cut);
    }

    #[test]
    fn losses_are_written_as_they_grow_so_a_file_cut_off_still_has_them() {
        let path = scratch("losses.mcap");
        let mut log = McapLog::create(&path, "lab").unwrap();
        log.add_controller("display").unwrap();
        log.tick(0, &ticks(1)[0]).unwrap();
        assert!(!log.dropped(0, 0).unwrap(), "nothing lost, nothing written");
        assert!(log.dropped(0, 5).unwrap());
        assert!(!log.dropped(0, 5).unwrap(), "written once");
        assert!(!log.dropped(3, 5).unwrap(), "no such controller");
        log.flush().unwrap();
        // The node dies here: no summary, no final counts.
        std::mem::forget(log);
        let r = read_recording(&path).unwrap();
        assert_eq!(r.dropped["display"], 5);
        assert_eq!(r.controllers["display"].len(), 1);
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn an_unwritable_path_or_a_foreign_file_is_a_typed_error() {
        let nowhere = Path::new("/nonexistent-dir/run.mcap");
        assert!(matches!(
            McapLog::create(nowhere, "lab"),
            Err(RecordingError::Io { .. })
        ));
        assert!(matches!(
            Recorder::start(
                nowhere,
                "lab",
                Vec::new(),
                Vec::new(),
                None,
                &crate::common_clock::CommonClock::own(),
                ClockReader::Real,
                SceneConfig::default(),
            ),
            Err(RecordingError::Io { .. })
        ));
        let foreign = scratch("foreign.mcap");
        std::fs::write(&foreign, b"time_s,q\n0,1\n").unwrap();
        assert!(matches!(
            read_recording(&foreign),
            Err(RecordingError::Format { .. })
        ));
        let _ = std::fs::remove_file(foreign);
    }

    #[test]
    fn a_scene_message_needs_a_schema_the_scene_crate_carries() {
        let path = scratch("scene-schema.mcap");
        let mut log = McapLog::create(&path, "lab").unwrap();
        let tf = penelope_scene::FrameTransforms::default();
        log.scene("/tf", penelope_scene::FRAME_TRANSFORMS, 5, &tf)
            .unwrap();
        log.scene("/tf", penelope_scene::FRAME_TRANSFORMS, 6, &tf)
            .unwrap();
        assert!(matches!(
            log.scene("/x", "foxglove.NoSuchSchema", 7, &tf),
            Err(RecordingError::Format { .. })
        ));
        log.finish(&[]).unwrap();
        let summary = super::mcap_log::summarize(&path).unwrap();
        let tf_channel = summary
            .channels
            .iter()
            .find(|c| c.topic == "/tf")
            .expect("a /tf channel");
        assert_eq!(tf_channel.messages, 2, "one channel, two messages");
        assert!(summary.channels.iter().all(|c| c.topic != "/x"));
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn a_crafted_record_length_is_an_error_not_an_abort() {
        let path = scratch("crafted.mcap");
        std::fs::write(&path, crafted_mcap_with_a_huge_record()).unwrap();
        for e in [
            read_recording(&path).unwrap_err(),
            super::mcap_log::summarize(&path).unwrap_err(),
        ] {
            assert!(
                matches!(
                    &e,
                    RecordingError::Mcap {
                        source: mcap::McapError::RecordTooLarge {
                            len: 0x4141_4141_4141_4141,
                            ..
                        },
                        ..
                    }
                ),
                "{e}"
            );
        }
        let _ = std::fs::remove_file(path);
    }

    /// A real recording, compressed and flushed in several chunks (written once).
    fn a_recording() -> Vec<u8> {
        static BYTES: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
        BYTES.get_or_init(write_a_recording).clone()
    }

    fn write_a_recording() -> Vec<u8> {
        let path = scratch("prop-base.mcap");
        let mut log = McapLog::create(&path, "lab").unwrap();
        log.add_controller("display").unwrap();
        for (i, t) in ticks(30).iter().enumerate() {
            log.tick(0, t).unwrap();
            if i % 10 == 9 {
                log.flush().unwrap();
            }
        }
        log.link("link", &link(5)).unwrap();
        log.finish(&[0]).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let _ = std::fs::remove_file(path);
        bytes
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]
        /// Mutated recordings (bytes overwritten, u64 fields set huge, cut off) are read or
        /// refused with a typed error: never a panic or an abort.
        #[test]
        fn mutated_recordings_never_panic_or_abort(
            edits in proptest::collection::vec((0usize..4096, 0u8..=255, 0u8..4), 1..6),
            cut in 0usize..4096,
            which in 0usize..2,
        ) {
            let mut bytes = if which == 0 {
                a_recording()
            } else {
                crafted_mcap_with_a_huge_record()
            };
            for (at, byte, how) in edits {
                let at = at % bytes.len();
                match how {
                    0 => bytes[at] = byte,
                    // A length field (little-endian u64) set large at a random place.
                    1 => {
                        let end = (at + 8).min(bytes.len());
                        for b in &mut bytes[at..end] {
                            *b = 0x41;
                        }
                    }
                    2 => {
                        let end = (at + 8).min(bytes.len());
                        bytes[at..end].fill(0xff);
                    }
                    _ => bytes[at] ^= 1 << (byte % 8),
                }
            }
            if cut % 3 == 0 {
                bytes.truncate(cut.max(8) % (bytes.len() + 1));
            }
            let path = scratch(&format!("prop-{}-{}.mcap", std::process::id(), cut));
            std::fs::write(&path, &bytes).unwrap();
            let _ = read_recording(&path);
            let _ = super::mcap_log::summarize(&path);
            let _ = std::fs::remove_file(path);
        }
    }
}
