//! The replay kinds: a recording (MCAP, as `penelope demo`, `penelope node --record` and
//! `ctl record` write it) played back in place of a live device.
//!
//! - `sensor/replay`: a 6-axis force sensor whose readings are a recorded wrench stream, for
//!   example the slave's sensed contact force from a controller channel of a recording
//!   (`/controllers/follow`, field `wrench`).
//! - `sensor/operator-replay`: the operator's hand played back: the master's recorded motion
//!   (the plant's true state each tick, from a controller channel's `truth`) imposed on its
//!   simulated body, and the clutch as recorded
//!   ([`RecordedHand`](penelope_drivers::sim::recorded_hand)).
//!
//! Both read the whole channel at `configure`, never in a real-time thread; the control
//! thread only moves a cursor forward through memory loaded beforehand. The hand is a sensor
//! kind, as `sensor/operator-hand` is: a system file lists hands under `[sensors]`, and the
//! replay takes the scripted hand's place by changing one word.
//!
//! # Timing and the end of a recording
//! A tick is matched by time: the record at or just before the tick's time (the loop's time for
//! the sensor, the plant's for the hand; on the simulated clock both are the times the
//! recording holds). Past the last record:
//! - the sensor reports [`ReplaySensorError::Ended`]: the loop notes a sensor error and runs
//!   without a wrench, as with a live sensor that went silent (a slave holds no force, a master
//!   displays none). Holding the last contact force forever would push on the operator with a
//!   force nothing produces any more.
//! - the hand holds the handle still at its last recorded pose (as a resting hand does); the
//!   clutch keeps its last state.
//!
//! A recorded tick whose sample raised `sensor-error` replays as a sensor error, so that a
//! replay meets what the recording met.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use penelope_drivers::sim::recorded_hand::{RecordedHand, RecordedState};
use penelope_hal::{Error, ErrorKind, ForceSensor, Pose, Sensor, Timestamp, Wrench};
use penelope_rt_core::safety::SafetyEvent;
use serde::{Deserialize, Serialize};

use crate::objects::error::{ObjectError, ReplayError};
use crate::objects::recording::mcap_log::CONTROLLER_TOPIC;
use crate::objects::recording::read_recording;
use crate::objects::tick::TickRecord;

/// `sensor/replay`'s configuration: a force sensor that plays back a recorded wrench stream
/// (loaded at configure); past the recording's end it reports an error (the loop runs without
/// a wrench).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct ReplaySensorConfig {
    /// The recording (MCAP; required).
    pub file: String,
    /// A controller channel of the recording.
    pub topic: String,
    /// `wrench` (the sensed one), `commanded_wrench`, `truth.base_wrench` or
    /// `truth.tool_wrench` (the plant's true contact).
    pub field: String,
    /// The sensor frame's origin in the tool frame, m (for the force's mapping).
    pub mount_xyz: [f64; 3],
}

impl crate::objects::config::KindConfig for ReplaySensorConfig {
    fn example() -> Self {
        ReplaySensorConfig {
            file: "run.mcap".into(),
            ..Self::default()
        }
    }
}

impl Default for ReplaySensorConfig {
    fn default() -> Self {
        ReplaySensorConfig {
            file: String::new(),
            topic: format!("{CONTROLLER_TOPIC}follow"),
            field: "wrench".into(),
            mount_xyz: [0.0; 3],
        }
    }
}

/// `sensor/operator-replay`'s configuration: the operator's hand played back, the master
/// moving and the clutch held as recorded; past the recording's end the hand holds the handle
/// still at its last pose.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct OperatorReplayConfig {
    /// The master the hand holds (on a simulated board; required).
    pub robot: String,
    /// The recording (MCAP; required).
    pub file: String,
    /// The master controller's channel (its ticks carry the truth).
    pub topic: String,
}

impl crate::objects::config::KindConfig for OperatorReplayConfig {
    fn example() -> Self {
        OperatorReplayConfig {
            robot: "frhc".into(),
            file: "run.mcap".into(),
            ..Self::default()
        }
    }
}

impl Default for OperatorReplayConfig {
    fn default() -> Self {
        OperatorReplayConfig {
            robot: String::new(),
            file: String::new(),
            topic: format!("{CONTROLLER_TOPIC}display"),
        }
    }
}

/// The wrench fields a `sensor/replay` can play.
pub const WRENCH_FIELDS: [&str; 4] = [
    "wrench",
    "commanded_wrench",
    "truth.base_wrench",
    "truth.tool_wrench",
];

fn bad(kind: &str, message: impl Into<String>) -> ObjectError {
    ObjectError::BadConfig {
        kind: kind.to_string(),
        message: message.into(),
    }
}

fn check_file_and_topic(kind: &str, file: &str, topic: &str) -> Result<(), ObjectError> {
    if file.trim().is_empty() {
        return Err(bad(kind, "`file` (the recording) is required"));
    }
    if topic
        .strip_prefix(CONTROLLER_TOPIC)
        .is_none_or(str::is_empty)
    {
        return Err(bad(
            kind,
            format!("`topic` = {topic:?}: a controller channel, `{CONTROLLER_TOPIC}<name>`"),
        ));
    }
    Ok(())
}

impl ReplaySensorConfig {
    /// Checks what can be checked without the file.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<(), ObjectError> {
        check_file_and_topic(kind, &self.file, &self.topic)?;
        if !WRENCH_FIELDS.contains(&self.field.as_str()) {
            return Err(bad(
                kind,
                format!(
                    "`field` = {:?}: one of {}",
                    self.field,
                    WRENCH_FIELDS.join(", ")
                ),
            ));
        }
        if !self
            .mount_xyz
            .iter()
            .all(|x| x.is_finite() && x.abs() <= 10.0)
        {
            return Err(bad(kind, "`mount_xyz` must be finite, within 10 m"));
        }
        Ok(())
    }

    /// The mount pose in the tool frame.
    pub fn mount(&self) -> Pose {
        let [x, y, z] = self.mount_xyz;
        Pose::translation(x, y, z)
    }
}

impl OperatorReplayConfig {
    /// Checks what can be checked without the file.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<(), ObjectError> {
        if self.robot.is_empty() {
            return Err(bad(kind, "`robot` (the master the hand holds) is required"));
        }
        check_file_and_topic(kind, &self.file, &self.topic)
    }
}

/// Every tick of the controller channel `topic` of the recording at `path`.
///
/// # Errors
/// [`ReplayError`]: missing file, unreadable recording, no such channel, no ticks, ticks out of
/// time order.
pub fn load_ticks(path: &Path, topic: &str) -> Result<Vec<TickRecord>, ReplayError> {
    if !path.is_file() {
        return Err(ReplayError::MissingFile {
            path: path.to_path_buf(),
        });
    }
    let mut recording = read_recording(path)?;
    let name = topic.strip_prefix(CONTROLLER_TOPIC).unwrap_or(topic);
    let Some(ticks) = recording.controllers.remove(name) else {
        let available: Vec<String> = recording
            .controllers
            .keys()
            .map(|k| format!("{CONTROLLER_TOPIC}{k}"))
            .collect();
        return Err(ReplayError::MissingTopic {
            path: path.to_path_buf(),
            topic: topic.to_string(),
            available: available.join(", "),
        });
    };
    if ticks.is_empty() {
        return Err(ReplayError::Empty {
            path: path.to_path_buf(),
            topic: topic.to_string(),
        });
    }
    if let Some(w) = ticks
        .windows(2)
        .find(|w| w[1].sample.time < w[0].sample.time)
    {
        return Err(ReplayError::OutOfOrder {
            path: path.to_path_buf(),
            topic: topic.to_string(),
            seq: w[1].sample.seq,
        });
    }
    Ok(ticks)
}

/// One replayed reading: when, and the wrench (`None`: the recording met a sensor error).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplayedWrench {
    /// The tick's time (the loop's clock).
    pub time: Timestamp,
    /// The reading.
    pub wrench: Option<Wrench>,
}

/// The wrench stream of `field` in `ticks` (loaded by [`load_ticks`]).
///
/// # Errors
/// [`ReplayError::NonFinite`] for a NaN or infinite value; [`ReplayError::NoTruth`] for a
/// `truth.` field of a tick without truth.
pub fn wrench_stream(
    path: &Path,
    topic: &str,
    field: &str,
    ticks: &[TickRecord],
) -> Result<Vec<ReplayedWrench>, ReplayError> {
    ticks
        .iter()
        .map(|t| {
            let s = &t.sample;
            let truth = || {
                t.truth.ok_or_else(|| ReplayError::NoTruth {
                    path: path.to_path_buf(),
                    topic: topic.to_string(),
                    seq: s.seq,
                })
            };
            let w = match field {
                "commanded_wrench" => s.commanded_wrench,
                "truth.base_wrench" => truth()?.base_wrench,
                "truth.tool_wrench" => truth()?.tool_wrench,
                _ => s.wrench,
            };
            if !w.is_finite() {
                return Err(ReplayError::NonFinite {
                    path: path.to_path_buf(),
                    topic: topic.to_string(),
                    seq: s.seq,
                    field: field.to_string(),
                });
            }
            let failed = field == "wrench" && s.events.contains(SafetyEvent::SensorError);
            Ok(ReplayedWrench {
                time: s.time,
                wrench: (!failed).then_some(w),
            })
        })
        .collect()
}

/// The master's motion in `ticks` (with their plant truth), and the clutch: `clutch` per tick
/// (`false` where a tick did not record it).
///
/// # Errors
/// [`ReplayError::NoTruth`]; [`ReplayError::NonFinite`].
pub fn motion(
    path: &Path,
    topic: &str,
    ticks: &[TickRecord],
) -> Result<Vec<RecordedState>, ReplayError> {
    ticks
        .iter()
        .map(|t| {
            let seq = t.sample.seq;
            let truth = t.truth.ok_or_else(|| ReplayError::NoTruth {
                path: path.to_path_buf(),
                topic: topic.to_string(),
                seq,
            })?;
            let finite = truth.joints.position.iter().all(|x| x.is_finite())
                && truth.joints.velocity.iter().all(|x| x.is_finite())
                && truth.base_wrench.is_finite()
                && truth.kinetic_energy.is_finite()
                && truth.interaction_work.is_finite();
            if !finite {
                return Err(ReplayError::NonFinite {
                    path: path.to_path_buf(),
                    topic: topic.to_string(),
                    seq,
                    field: "truth".into(),
                });
            }
            Ok(RecordedState {
                time: truth.time,
                position: truth.joints.position,
                velocity: truth.joints.velocity,
                wrench: truth.base_wrench,
                kinetic_energy: truth.kinetic_energy,
                interaction_work: truth.interaction_work,
                clutch: t.clutch.unwrap_or(false),
            })
        })
        .collect()
}

/// A loaded `sensor/operator-replay`: its configuration, and once configured its motion.
pub struct OperatorReplayObj {
    /// Its configuration.
    pub config: OperatorReplayConfig,
    /// The motion, loaded at configure.
    pub motion: Option<Arc<[RecordedState]>>,
    /// The clutch button, read by the master's communication task.
    pub clutch: Arc<AtomicBool>,
}

impl OperatorReplayObj {
    /// Loads the recording (`configure`).
    ///
    /// # Errors
    /// [`ReplayError`].
    pub fn load(&mut self) -> Result<(), ReplayError> {
        let path = Path::new(&self.config.file);
        let ticks = load_ticks(path, &self.config.topic)?;
        self.motion = Some(motion(path, &self.config.topic, &ticks)?.into());
        Ok(())
    }

    /// A hand playing the loaded motion (`None` before `configure`).
    pub fn hand(&self) -> Option<RecordedHand> {
        Some(RecordedHand::new(self.motion.clone()?, self.clutch.clone()))
    }
}

/// A loaded `sensor/replay`: its configuration, and once configured its readings.
pub struct ReplaySensorObj {
    /// Its configuration.
    pub config: ReplaySensorConfig,
    /// The readings, loaded at configure.
    pub readings: Option<Arc<[ReplayedWrench]>>,
}

impl ReplaySensorObj {
    /// Loads the recording (`configure`).
    ///
    /// # Errors
    /// [`ReplayError`].
    pub fn load(&mut self) -> Result<(), ReplayError> {
        let path = Path::new(&self.config.file);
        let ticks = load_ticks(path, &self.config.topic)?;
        let stream = wrench_stream(path, &self.config.topic, &self.config.field, &ticks)?;
        self.readings = Some(stream.into());
        Ok(())
    }
}

/// Why a [`ReplaySensor`] has no reading for a tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReplaySensorError {
    /// The tick is before the recording's first.
    NotYet,
    /// The tick is past the recording's last.
    Ended,
    /// The recording met a sensor error at this tick.
    Recorded,
}

impl Error for ReplaySensorError {
    fn kind(&self) -> ErrorKind {
        match self {
            ReplaySensorError::NotYet | ReplaySensorError::Ended => ErrorKind::Timeout,
            ReplaySensorError::Recorded => ErrorKind::Other,
        }
    }
}

impl core::fmt::Display for ReplaySensorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ReplaySensorError::NotYet => "before the recording's first tick",
            ReplaySensorError::Ended => "past the recording's last tick",
            ReplaySensorError::Recorded => "the recording met a sensor error here",
        })
    }
}

/// The control loop's side of a `sensor/replay`: readings loaded at configure, a cursor.
pub struct ReplaySensor {
    readings: Arc<[ReplayedWrench]>,
    cursor: usize,
    mount: Pose,
    /// The recording's tick period (the last tick's reading holds for one period).
    period_ns: u64,
}

impl ReplaySensor {
    /// A sensor playing `readings` (in time order, at least one), mounted at `mount`.
    pub fn new(readings: Arc<[ReplayedWrench]>, mount: Pose) -> Self {
        let period_ns = match &readings[..] {
            [a, b, ..] => b.time.as_nanos().saturating_sub(a.time.as_nanos()),
            _ => 0,
        };
        ReplaySensor {
            readings,
            cursor: 0,
            mount,
            period_ns,
        }
    }
}

impl Sensor for ReplaySensor {
    type Error = ReplaySensorError;
    type Reading = Wrench;

    /// The recorded reading at or just before `now`.
    ///
    /// # Real-time
    /// No allocation; amortised constant time (the cursor moves forward only, one step per
    /// reading passed; time going back starts it over).
    fn read(&mut self, now: Timestamp) -> Result<Wrench, ReplaySensorError> {
        let r = &self.readings;
        let (Some(first), Some(last)) = (r.first(), r.last()) else {
            return Err(ReplaySensorError::Ended);
        };
        if now < first.time {
            return Err(ReplaySensorError::NotYet);
        }
        if now.as_nanos() >= last.time.as_nanos().saturating_add(self.period_ns.max(1)) {
            return Err(ReplaySensorError::Ended);
        }
        if r[self.cursor].time > now {
            self.cursor = 0;
        }
        // Bounded by the number of readings.
        while self.cursor + 1 < r.len() && r[self.cursor + 1].time <= now {
            self.cursor += 1;
        }
        r[self.cursor].wrench.ok_or(ReplaySensorError::Recorded)
    }
}

impl ForceSensor for ReplaySensor {
    fn mount(&self) -> Pose {
        self.mount
    }

    /// A recording is replayed as it was: taring changes nothing.
    fn tare(&mut self, _now: Timestamp) -> Result<(), ReplaySensorError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::objects::recording::RecordingError;
    use penelope_hal::Frame;

    fn reading(ms: u64, fx: f64) -> ReplayedWrench {
        let mut w = Wrench::zero(Frame::Base);
        w.force.x = fx;
        ReplayedWrench {
            time: Timestamp::from_nanos(ms * 1_000_000),
            wrench: Some(w),
        }
    }

    #[test]
    fn the_sensor_plays_each_tick_and_reports_the_end() {
        let mut readings = vec![reading(1, 1.0), reading(2, 2.0), reading(3, 3.0)];
        readings[1].wrench = None;
        let mut s = ReplaySensor::new(readings.into(), Pose::identity());
        let at = |us: u64| Timestamp::from_nanos(us * 1_000);
        assert_eq!(s.read(at(500)), Err(ReplaySensorError::NotYet));
        assert_eq!(s.read(at(1_000)).unwrap().force.x, 1.0);
        assert_eq!(s.read(at(1_500)).unwrap().force.x, 1.0);
        assert_eq!(s.read(at(2_000)), Err(ReplaySensorError::Recorded));
        assert_eq!(s.read(at(3_999)).unwrap().force.x, 3.0);
        assert_eq!(s.read(at(4_000)), Err(ReplaySensorError::Ended));
        assert_eq!(s.read(at(1_000)).unwrap().force.x, 1.0, "starts over");
    }

    #[test]
    fn configs_need_a_file_and_a_controller_channel() {
        let k = "sensor/replay";
        let c: ReplaySensorConfig = crate::objects::config::parse(k, "file = \"a.mcap\"").unwrap();
        assert!(c.check(k).is_ok());
        assert_eq!(c.topic, "/controllers/follow");
        for text in [
            "",
            "file = \"a.mcap\"\ntopic = \"/safety\"",
            "file = \"a.mcap\"\nfield = \"q\"",
            "file = \"a.mcap\"\nmount_xyz = [0, 0, nan]",
        ] {
            let c: ReplaySensorConfig = crate::objects::config::parse(k, text).unwrap();
            assert!(c.check(k).is_err(), "{text}");
        }
        let k = "sensor/operator-replay";
        let c: OperatorReplayConfig =
            crate::objects::config::parse(k, "file = \"a.mcap\"").unwrap();
        assert!(c.check(k).is_err(), "no robot");
        assert!(crate::objects::config::parse::<OperatorReplayConfig>(k, "seed = 1").is_err());
    }

    #[test]
    fn loading_a_missing_file_or_topic_is_a_typed_error() {
        let missing = Path::new("/nonexistent/penelope-replay.mcap");
        assert!(matches!(
            load_ticks(missing, "/controllers/follow"),
            Err(ReplayError::MissingFile { .. })
        ));
        let dir = std::env::temp_dir().join(format!("penelope-replay-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let write = |name: &str, nan: bool| {
            let path = dir.join(name);
            let mut log =
                crate::objects::recording::mcap_log::McapLog::create(&path, "lab").unwrap();
            let i = log.add_controller("follow").unwrap();
            let mut tick = TickRecord::default();
            for seq in 1..=3u64 {
                tick.sample.seq = seq;
                tick.sample.time = Timestamp::from_nanos(seq * 1_000_000);
                tick.sample.wrench.force.x = if nan && seq == 3 { f64::NAN } else { 1.0 };
                log.tick(i, &tick).unwrap();
            }
            log.finish(&[0]).unwrap();
            (path, tick)
        };
        let (clean, _) = write("clean.mcap", false);
        match load_ticks(&clean, "/controllers/display") {
            Err(ReplayError::MissingTopic { available, .. }) => {
                assert_eq!(available, "/controllers/follow")
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(load_ticks(&clean, "/controllers/follow").unwrap().len(), 3);
        let (path, tick) = write("nan.mcap", true);
        // JSON has no NaN (serde writes `null`): such a tick makes the file unreadable.
        assert!(matches!(
            load_ticks(&path, "/controllers/follow"),
            Err(ReplayError::Unreadable(_))
        ));
        let mut ticks = vec![tick; 2];
        ticks[0].sample.seq = 1;
        ticks[0].sample.time = Timestamp::from_nanos(1);
        ticks[0].sample.wrench.force.x = 1.0;
        match wrench_stream(&path, "/controllers/follow", "wrench", &ticks) {
            Err(ReplayError::NonFinite { seq: 3, .. }) => {}
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            motion(&path, "/controllers/follow", &ticks),
            Err(ReplayError::NoTruth { seq: 1, .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_crafted_recording_is_a_typed_error_of_the_replayed_sensor() {
        let path = std::env::temp_dir().join(format!(
            "penelope-replay-crafted-{}.mcap",
            std::process::id()
        ));
        std::fs::write(
            &path,
            crate::objects::recording::crafted_mcap_with_a_huge_record(),
        )
        .unwrap();
        let k = "sensor/replay";
        let config = format!("file = {:?}", path.to_str().unwrap());
        let c: ReplaySensorConfig = crate::objects::config::parse(k, &config).unwrap();
        c.check(k).unwrap();
        let mut sensor = ReplaySensorObj {
            config: c,
            readings: None,
        };
        // `configure` reads the recording: refused with a typed error, the object unloaded.
        let e = sensor.load().unwrap_err();
        assert!(
            matches!(
                &e,
                ReplayError::Unreadable(RecordingError::Mcap {
                    source: mcap::McapError::RecordTooLarge { .. },
                    ..
                })
            ),
            "{e}"
        );
        assert!(sensor.readings.is_none());
        match penelope_protocol::proto::WireError::from(e.for_kind(k)) {
            penelope_protocol::proto::WireError::Call(
                penelope_protocol::proto::CallError::BadConfig { kind, message },
            ) => {
                assert_eq!(kind, k);
                assert!(message.contains("exceeds limit"), "{message}");
            }
            other => panic!("{other:?}"),
        }
        let _ = std::fs::remove_file(path);
    }
}
