//! The creator and the objects it makes: robots, boards, sensors, controllers and trajectories
//! (DESIGN.md section 1), their relations, their lifecycles, and the real-time loops of the
//! active controllers.
//!
//! - [`kinematics`]: the model a robot's loops compute with (float, or the FPGA board's).
//! - [`fpga_board`]: `board/fpga`, the FRHC's FPGA board: its latency model and what it accepts.
//! - [`config`]: a kind's configuration text parsed and described (keys, units, defaults).
//! - [`kinds`]: every kind and its TOML configuration (keys, units, defaults, ranges).
//! - [`clock`]: real time or the simulated clock, and the node's time as a recorder reads it;
//!   [`sim_world`]: the simulated clock's world, which steps the loops.
//! - [`runtime`]: what runs while a controller is active: the control task (SCHED_FIFO), the
//!   communication task (trajectory to reference cell), the sensor feed and the telemetry pump.
//! - [`teleop`]: the teleoperation channel, its ends, the operator's hand and the halves of
//!   the bilateral laws.
//! - [`recording`]: the node's ticks, events and links to an MCAP file, and read back.
//! - [`replay`]: `sensor/replay` and `sensor/operator-replay`, a recording played back in place
//!   of a force sensor or of the operator's hand.
//! - [`bridged`]: the channels whose master end a bridge feeds from outside the node, and the
//!   operator pose record they take.
//! - [`delay_line`]: the seeded delay (jitter, loss) a channel on one node injects between its
//!   ends when it has `faults`, as the data plane's fault layer does between nodes.
//! - `registry` (private): the objects, relations, lifecycles and methods.
//! - `service` (private): the creator served to a client session: calls checked against the
//!   session's role and dispatched, subscriptions' batches to its outbox as wire messages, the
//!   objects' errors turned into the wire's by the one conversion.
//!
//! # Relations are data
//! A controller names its robot, trajectory and (optional) sensor; a robot maps its joints onto
//! board axes (`MapJoints`, one call per board). Names are checked at `configure` and
//! `activate`. A robot's joints may be spread over several boards; a board may be mapped by
//! several robots, but an axis is driven by at most one running loop (a second activation is
//! refused with [`ObjectError::InUse`]).
//!
//! # Simulated boards
//! A `board/sim` is the electrical side; the mechanism behind it is the robot mapped onto it. The
//! robot's body (one rigid-body plant of its whole chain, since joints are dynamically coupled)
//! is built when the robot is configured, from the first simulated board's settings (DAC bits,
//! sub-step, friction, environment), at the robot's `start` pose; it persists across
//! activations (the loop takes it and gives it back) and is dropped at `cleanup`. A `board/fpga`
//! is the same simulated board with the FRHC's FPGA kinematics in front of it ([`fpga_board`]).
//!
//! # Lifecycle
//! ROS 2 words. Robots, boards, sensors and trajectories are configured by hand and show
//! `active` while a running controller uses them. Activating a controller builds an rt-core
//! `ControlLoop` and starts its threads; `ControlCommand::Activate` goes through the command ring
//! so commands start from the measured state. Deactivating sends `Deactivate` (amplifiers off),
//! joins the threads and gives the boards back.

pub mod bridged;
pub mod camera;
pub mod clock;
pub mod config;
pub mod delay_line;
pub mod error;
pub mod files;
pub mod fpga_board;
pub mod kinds;
pub mod kinematics;
pub mod lifecycle_feed;
pub mod link_source;
mod loops;
pub mod operator_hand;
pub mod recording;
pub mod reference;
mod registry;
pub mod replay;
pub mod roles;
pub mod runtime;
mod service;
pub mod sim_world;
pub mod stop_board;
pub mod teleop;
pub mod teleop_end;
pub mod teleop_laws;
pub mod teleop_passivity;
pub mod teleop_wave;
pub mod tick;

use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

use penelope_hal::{LifecycleState, Timestamp, Transition};

use crate::objects::error::ObjectError;
use clock::ClockMode;
use penelope_protocol::proto::{
    Class, ControllerMethod, KindInfo, Method, ObjectInfo, Reply, check_name,
};
use penelope_protocol::service::Remote;
use registry::{KindState, Registry};

/// The catalog of kinds: every kind a creator makes, one line each.
pub use registry::catalog;
/// `sensor/netft`, a kind that is one module: its configuration and its object.
pub use registry::netft;
use runtime::{CommTask, ControlTask, LinkPump, Subscriptions};
use sim_world::SimWorld;

/// Real-time settings of the control threads a creator starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RtPolicy {
    /// SCHED_FIFO priority of control threads (1-99; communication threads run 10 lower), or
    /// `None` for normal scheduling. When the process may not use SCHED_FIFO, threads run at
    /// normal priority and the controller's `describe` says so.
    pub priority: Option<u8>,
    /// Pin control threads to this CPU.
    pub cpu: Option<usize>,
    /// `mlockall` and hold `/dev/cpu_dma_latency` before the first tick.
    pub lock_memory: bool,
}

impl Default for RtPolicy {
    /// Priority 80, no pinning, memory not locked (the node turns it on for deployments).
    fn default() -> Self {
        RtPolicy {
            priority: Some(80),
            cpu: None,
            lock_memory: false,
        }
    }
}

/// How a creator is set up.
#[derive(Clone)]
pub struct CreatorConfig {
    /// The node's name.
    pub node: String,
    /// The most objects it holds.
    pub max_objects: u32,
    /// The most telemetry subscriptions, over all connections.
    pub max_subscriptions: u32,
    /// The most telemetry subscriptions of the connections from one IP address (so that one
    /// client cannot take the whole pool).
    pub max_subscriptions_per_peer: u32,
    /// Real-time settings of the loops.
    pub rt: RtPolicy,
    /// How controllers reach sensors on other nodes (set later with [`Creator::set_remote`]).
    pub remote: Option<Arc<dyn Remote>>,
    /// Real time, or a simulated clock moved by [`Creator::advance`].
    pub clock: ClockMode,
    /// The key that authenticates data-plane datagrams (from the system secret; set by the
    /// node), or `None` in a system without a secret.
    pub datagram_key: Option<crate::dataplane::frame::DatagramKey>,
    /// The system's common clock as this node estimates it (set by the node; a creator alone
    /// is its own), for its recordings' log times.
    pub common_clock: crate::common_clock::CommonClock,
    /// The directory `ctl record start` creates recordings in (a client names a plain file
    /// name in it), or `None`: recordings by a client refused. `penelope node` sets
    /// `--records`, the system file's `records`, or [`files::default_records_dir`].
    pub records: Option<std::path::PathBuf>,
    /// The directories a `robot/urdf`'s `file` is read from (none: every robot file refused).
    /// `penelope node` sets `--robot-files`, the system file's `robot_files`, or the system
    /// file's own directory.
    pub robot_files: Vec<std::path::PathBuf>,
}

impl std::fmt::Debug for CreatorConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CreatorConfig")
            .field("node", &self.node)
            .field("max_objects", &self.max_objects)
            .field("max_subscriptions", &self.max_subscriptions)
            .field(
                "max_subscriptions_per_peer",
                &self.max_subscriptions_per_peer,
            )
            .field("rt", &self.rt)
            .field("remote", &self.remote.is_some())
            .field("clock", &self.clock)
            .field("datagram_key", &self.datagram_key.is_some())
            .field("common_clock", self.common_clock.source())
            .field("records", &self.records)
            .field("robot_files", &self.robot_files)
            .finish()
    }
}

impl CreatorConfig {
    /// Node `node`: 256 objects, 64 subscriptions (16 per client address),
    /// [`RtPolicy::default`], no remote.
    pub fn new(node: impl Into<String>) -> Self {
        CreatorConfig {
            node: node.into(),
            max_objects: 256,
            max_subscriptions: 64,
            max_subscriptions_per_peer: 16,
            rt: RtPolicy::default(),
            remote: None,
            clock: ClockMode::RealTime,
            datagram_key: None,
            common_clock: crate::common_clock::CommonClock::own(),
            records: None,
            robot_files: Vec::new(),
        }
    }
}

/// Ticks a recorder's stream holds per controller before it loses them (over a minute at
/// 1 kHz).
const RECORDER_CAPACITY: usize = 1 << 16;

/// The creator of a node (the paper's `creatorImpl`): makes, lists and destroys objects and
/// serves their methods. `Send + Sync`; its mutex is taken by connection threads only, never by
/// a real-time thread.
pub struct Creator {
    config: CreatorConfig,
    registry: Mutex<Registry>,
    remote: Mutex<Option<Arc<dyn Remote>>>,
    subscriptions: Arc<Subscriptions>,
    /// Publishes link records on the real clock; started by the first link subscription.
    link_pump: Mutex<Option<LinkPump>>,
    fifo: OnceLock<bool>,
    /// The loops and the clock, on a simulated clock.
    sim: Option<Arc<Mutex<SimWorld>>>,
    /// The recording `ctl record start` began (its file and writer thread).
    recording: Mutex<Option<(String, crate::objects::recording::Recorder)>>,
    /// The transitions, for recorders.
    lifecycle: lifecycle_feed::LifecycleFeed,
    /// The stop latches of the running loops, reached by an e-stop without the registry lock.
    stops: stop_board::StopBoard,
}

impl std::fmt::Debug for Creator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Creator")
            .field("node", &self.config.node)
            .field("objects", &self.object_count())
            .finish_non_exhaustive()
    }
}

/// A controller's loop built by [`Creator::detach_loop`], with no thread: for tests and
/// benchmarks that step it on a simulated clock.
pub struct DetachedLoop {
    /// The control thread's per-tick body.
    pub control: ControlTask,
    /// The communication thread's per-tick body.
    pub comm: CommTask,
    /// The telemetry ring's consumer end.
    pub telemetry:
        penelope_rt_core::ring::ArcConsumer<tick::TickRecord, { runtime::TELEMETRY_CAPACITY }>,
    /// The newest sample for a sensor feed.
    pub probe:
        penelope_rt_core::cell::ArcLatestReader<penelope_rt_core::telemetry::TelemetrySample>,
    /// Where a sensor feed writes the wrench (when a sensor is bound).
    pub wrench: Option<
        penelope_rt_core::cell::ArcLatestWriter<
            penelope_rt_core::cell::Stamped<penelope_hal::Wrench>,
        >,
    >,
    /// New gains to the control task (what `set-gains` sends a running loop).
    pub gains:
        penelope_rt_core::ring::ArcProducer<runtime::RoutedGains, { runtime::GAINS_CAPACITY }>,
    /// Moves to the communication task (what GoTo, `move_jp` and `move_cp` push).
    pub goto: penelope_rt_core::ring::ArcProducer<runtime::GoToCommand, { runtime::GOTO_CAPACITY }>,
    /// Servo targets to the communication task, and its moves' status.
    pub motion: runtime::MotionControl,
}

impl Creator {
    /// A creator with no objects.
    pub fn new(config: CreatorConfig) -> Self {
        let subscriptions = Arc::new(Subscriptions::on_common_clock(
            config.common_clock.offset_cell(),
        ));
        Creator {
            sim: (config.clock == ClockMode::Simulated)
                .then(|| Arc::new(Mutex::new(SimWorld::default()))),
            remote: Mutex::new(config.remote.clone()),
            registry: Mutex::new(Registry {
                datagram_key: config.datagram_key.clone(),
                clock: config.clock,
                camera_env: Some(registry::camera::CameraEnv {
                    subscriptions: subscriptions.clone(),
                    clock: config.common_clock.clone(),
                    send_clock: match config.clock {
                        ClockMode::Simulated => camera::SendClock::Simulated,
                        _ => camera::SendClock::Real,
                    },
                }),
                ..Registry::default()
            }),
            config,
            subscriptions,
            link_pump: Mutex::new(None),
            fifo: OnceLock::new(),
            recording: Mutex::new(None),
            lifecycle: lifecycle_feed::LifecycleFeed::default(),
            stops: stop_board::StopBoard::default(),
        }
    }

    /// Latches the e-stop of every loop running on this node, without the registry lock or
    /// any command queue (a slow call holding them never delays it), and waits briefly
    /// ([`stop_board::STOP_ACK_WAIT`], real clock only) for the loops to act.
    pub fn estop_all(&self) -> penelope_protocol::proto::StopReport {
        self.stops.stop_all(&self.config.node, self.stop_wait())
    }

    /// Latches the e-stop of controller `name`'s running loop as [`Creator::estop_all`] does;
    /// `None` when no loop of that name runs (the caller then asks the registry, which knows
    /// why). `Some(acted)`: whether the loop latched it before the wait ended.
    pub fn estop_loop(&self, name: &str) -> Option<bool> {
        self.stops.stop(name, self.stop_wait())
    }

    /// How long an e-stop waits for its loops: none on a simulated clock (they latch on the
    /// next step).
    fn stop_wait(&self) -> std::time::Duration {
        match self.sim {
            Some(_) => std::time::Duration::ZERO,
            None => stop_board::STOP_ACK_WAIT,
        }
    }

    /// Holds the object registry's lock until `release` returns, as a slow call would (a
    /// `create` reading a file that never ends): for tests showing that an e-stop does not
    /// wait for it. `release` runs with the lock held.
    ///
    /// # Errors
    /// [`ObjectError::Internal`] when the registry is poisoned.
    #[cfg(feature = "fault-injection")]
    pub fn hold_registry_lock<T>(&self, release: impl FnOnce() -> T) -> Result<T, ObjectError> {
        let _registry = self.lock()?;
        Ok(release())
    }

    /// A reader of this creator's lifecycle transitions from now on (create, destroy and every
    /// transition that succeeded), holding up to `capacity` events not yet taken.
    pub fn lifecycle_events(
        &self,
        capacity: usize,
    ) -> std::sync::mpsc::Receiver<lifecycle_feed::LifecycleEvent> {
        self.lifecycle.subscribe(capacity)
    }

    /// The node's clock, ns: the simulated clock's on a simulated node.
    fn now_ns(&self) -> u64 {
        self.node_time().now_ns()
    }

    /// The node's clock, for a thread of its own to read.
    pub fn node_time(&self) -> clock::ClockReader {
        match &self.sim {
            Some(world) => clock::ClockReader::Simulated(world.clone()),
            None => clock::ClockReader::Real,
        }
    }

    /// Tells the lifecycle readers that `object` (of `kind`) went through `transition` and is
    /// now in `state`.
    fn note_lifecycle(&self, object: &str, kind: &str, transition: &str, state: &str) {
        self.lifecycle.publish(&lifecycle_feed::LifecycleEvent {
            time_ns: self.now_ns(),
            object: object.into(),
            kind: kind.into(),
            transition: transition.into(),
            state: state.into(),
        });
    }

    fn lock(&self) -> Result<MutexGuard<'_, Registry>, ObjectError> {
        self.registry
            .lock()
            .map_err(|_| ObjectError::Poisoned("object registry"))
    }

    /// The kinds it makes.
    pub fn kinds(&self) -> Vec<KindInfo> {
        registry::catalog::all_kinds()
    }

    /// Its objects, by name.
    pub fn list(&self) -> Vec<ObjectInfo> {
        self.reap_failed();
        self.lock()
            .map(|r| r.objects.values().map(|o| o.info(&r.bridged)).collect())
            .unwrap_or_default()
    }

    /// One object.
    pub fn info(&self, name: &str) -> Option<ObjectInfo> {
        self.reap_failed();
        let r = self.lock().ok()?;
        r.objects.get(name).map(|o| o.info(&r.bridged))
    }

    /// The channels whose master is an operator station behind the Zenoh bridge (shared: the
    /// bridge reads and feeds them).
    pub fn bridged_channels(&self) -> crate::objects::bridged::BridgedChannels {
        self.lock().map(|r| r.bridged.clone()).unwrap_or_default()
    }

    /// Where the counters and datagrams of channel `name`'s link to another node can be read
    /// (`None` for a channel with both ends on this node, or not configured yet).
    ///
    /// # Errors
    /// [`ObjectError::UnknownName`] for no such object.
    pub fn link_source(&self, name: &str) -> Result<Option<link_source::LinkSource>, ObjectError> {
        let registry = self.lock()?;
        Ok(match &registry.get(name)?.body {
            registry::KindState::Teleop(t) => t.link.as_ref().and_then(|l| l.stats_source()),
            _ => None,
        })
    }

    /// Starts recording `objects` (none: every controller, linked channel and camera) to the new
    /// MCAP file `name` in the node's recordings directory ([`CreatorConfig::records`]): see
    /// [`CreatorCall::RecordStart`](penelope_protocol::proto::CreatorCall::RecordStart). The recorder is a thread of normal priority fed by the
    /// telemetry pump through bounded streams; no loop waits for it.
    ///
    /// # Errors
    /// [`ObjectError::NotReady`] while recording; [`ObjectError::BadArgument`] for a name not
    /// ending `.mcap` or not a plain file name (`/`, `..`), an existing file or link of that
    /// name (created exclusively, links not followed: [`files::create_in`]), no recordings
    /// directory, an object neither a controller nor a channel; [`ObjectError::UnknownName`].
    pub fn record_start(&self, name: &str, objects: &[String]) -> Result<Reply, ObjectError> {
        self.record_start_with(name, objects, recording::DEFAULT_SCENE_HZ)
    }

    /// As [`record_start`](Self::record_start), drawing the robots of the recorded controllers
    /// in 3D at `scene_hz` of tick time ([`recording::scene`]; 0: their descriptions only).
    ///
    /// # Errors
    /// As [`record_start`](Self::record_start); [`ObjectError::BadArgument`] for a rate out of
    /// 0..=[`recording::scene::MAX_SCENE_HZ`].
    pub fn record_start_with(
        &self,
        name: &str,
        objects: &[String],
        scene_hz: f64,
    ) -> Result<Reply, ObjectError> {
        recording::scene::check_rate(scene_hz)
            .map_err(|e| ObjectError::BadArgument(e.to_string()))?;
        let mut recording = self
            .recording
            .lock()
            .map_err(|_| ObjectError::Poisoned("recording"))?;
        if let Some((current, _)) = recording.as_ref() {
            return Err(ObjectError::NotReady(format!(
                "already recording to {current}"
            )));
        }
        if !name.ends_with(".mcap") {
            return Err(ObjectError::BadArgument(format!(
                "a recording is an MCAP file named *.mcap, not `{}`",
                name.chars().take(200).collect::<String>()
            )));
        }
        let dir = self.config.records.as_deref().ok_or_else(|| {
            ObjectError::File(files::FileRefused::NoDirectory(
                "recordings",
                "--records DIR",
            ))
        })?;
        files::plain_name(name)?;
        let names: Vec<String> = if objects.is_empty() {
            self.list()
                .into_iter()
                .filter(|o| {
                    o.class == Class::Controller
                        || o.kind == kinds::Kind::TELEOP.as_str()
                        || o.kind == registry::camera::SIM_CAMERA.as_str()
                        || o.kind == registry::camera::CAMERA.as_str()
                })
                .map(|o| o.name)
                .collect()
        } else {
            objects.to_vec()
        };
        let mut streams = Vec::new();
        let mut links = Vec::new();
        let mut cameras = Vec::new();
        for name in &names {
            let info = self
                .info(name)
                .ok_or_else(|| ObjectError::UnknownName(name.clone()))?;
            if info.class == Class::Controller {
                streams.push((name.clone(), self.record_ticks(name, RECORDER_CAPACITY)?));
            } else if info.kind == registry::camera::SIM_CAMERA.as_str()
                || info.kind == registry::camera::CAMERA.as_str()
            {
                cameras.push(name.clone());
            } else if info.kind == kinds::Kind::TELEOP.as_str() {
                match self.link_source(name)? {
                    Some(source) => links.push((name.clone(), source)),
                    None if objects.is_empty() => {}
                    None => {
                        return Err(ObjectError::NoLink(name.clone()));
                    }
                }
            } else {
                return Err(ObjectError::BadArgument(format!(
                    "`{name}` is a {}: only controllers, channels and cameras are recorded",
                    info.kind
                )));
            }
        }
        let controllers: Vec<String> = streams.iter().map(|(n, _)| n.clone()).collect();
        let linked: Vec<String> = links.iter().map(|(n, _)| n.clone()).collect();
        let scene = self.scene_for(&controllers, scene_hz)?;
        // Created last, once everything else is checked: a refused call leaves no file.
        let (path, file) = files::create_in(dir, name)?;
        let path = path.display().to_string();
        let sources = recording::RecordingSources {
            node: &self.config.node,
            streams,
            links,
            lifecycle: Some(self.lifecycle_events(recording::LIFECYCLE_CAPACITY)),
            clock: &self.config.common_clock,
            node_time: self.node_time(),
            scene,
        };
        let taps = self.lock()?.camera_taps(&cameras);
        let recorder = recording::Recorder::start_with_cameras(
            recording::RecordProfile::Penelope,
            std::path::Path::new(&path),
            Some(file),
            sources,
            taps,
        )
        .map_err(|e| {
            let _ = std::fs::remove_file(&path);
            ObjectError::RecordingRefused(e.into())
        })?;
        *recording = Some((path.to_string(), recorder));
        Ok(Reply::Recording {
            path: path.to_string(),
            controllers,
            links: linked,
        })
    }

    /// A tap of every frame each running camera of this node releases from now on, by camera
    /// name: what a recording writes ([`recording::Recorder::start_with_cameras`]). A reader
    /// that falls behind loses frames (counted in the camera's `describe`), never the camera.
    pub fn camera_taps(
        &self,
    ) -> Vec<(
        String,
        std::sync::mpsc::Receiver<penelope_protocol::proto::CameraFrame>,
    )> {
        let Ok(reg) = self.lock() else {
            return Vec::new();
        };
        let names: Vec<String> = reg
            .objects
            .values()
            .filter(|o| registry::camera::is_camera(o.kind))
            .map(|o| o.name.clone())
            .collect();
        reg.camera_taps(&names)
    }

    /// As [`camera_taps`](Self::camera_taps), of the cameras named `names` only (those that
    /// run): for a reader that taps each camera once, as it finds them.
    pub fn camera_taps_of(
        &self,
        names: &[String],
    ) -> Vec<(
        String,
        std::sync::mpsc::Receiver<penelope_protocol::proto::CameraFrame>,
    )> {
        self.lock()
            .map(|reg| reg.camera_taps(names))
            .unwrap_or_default()
    }

    /// The 3D scene of a recording of `controllers` at `rate_hz` of tick time: the robot each
    /// drives (once per robot), side by side along world y in creation order, with the contact
    /// shapes of its simulated boards ([`recording::scene`]).
    ///
    /// # Errors
    /// [`ObjectError::BadArgument`] for a rate out of 0..=[`recording::scene::MAX_SCENE_HZ`];
    /// [`ObjectError::Poisoned`].
    pub fn scene_for(
        &self,
        controllers: &[String],
        rate_hz: f64,
    ) -> Result<recording::SceneConfig, ObjectError> {
        let rate_hz = recording::scene::check_rate(rate_hz)
            .map_err(|e| ObjectError::BadArgument(e.to_string()))?;
        Ok(recording::SceneConfig {
            robots: self.lock()?.scene_robots(controllers),
            rate_hz,
        })
    }

    /// Ends the recording [`record_start`](Self::record_start) began.
    ///
    /// # Errors
    /// [`ObjectError::NotReady`] when there is none; [`ObjectError::Device`] when its file could
    /// not be finished.
    pub fn record_stop(&self) -> Result<Reply, ObjectError> {
        let taken = self
            .recording
            .lock()
            .map_err(|_| ObjectError::Poisoned("recording"))?
            .take();
        let Some((path, recorder)) = taken else {
            return Err(ObjectError::NotReady("not recording".into()));
        };
        let ticks = recorder
            .finish()
            .map_err(|e| ObjectError::Recorder(e.into()))?;
        Ok(Reply::Recorded { path, ticks })
    }

    /// How many objects it holds.
    pub fn object_count(&self) -> u32 {
        self.lock().map_or(0, |r| r.objects.len() as u32)
    }

    /// Installs how controllers reach sensors on other nodes.
    pub fn set_remote(&self, remote: Arc<dyn Remote>) {
        if let Ok(mut r) = self.remote.lock() {
            *r = Some(remote);
        }
    }

    /// The system's common clock as this node estimates it.
    pub fn common_clock(&self) -> &crate::common_clock::CommonClock {
        &self.config.common_clock
    }

    /// Telemetry subscriptions open now.
    pub fn subscription_count(&self) -> usize {
        self.subscriptions.len()
    }

    /// Makes an object.
    ///
    /// # Errors
    /// A bad name ([`ObjectError::Wire`] of a `BadName`), [`ObjectError::UnknownKind`],
    /// [`ObjectError::NameTaken`], [`ObjectError::LimitReached`], [`ObjectError::BadConfig`];
    /// [`ObjectError::Unsupported`] for a real device (`board/galil`, `sensor/netft`) on a
    /// creator clocked by the simulated clock.
    pub fn create(&self, kind: &str, name: &str, config: &str) -> Result<ObjectInfo, ObjectError> {
        check_name(name)?;
        let entry = registry::catalog::entry_named(kind)
            .ok_or_else(|| ObjectError::UnknownKind(kind.chars().take(80).collect()))?;
        let k = entry.kind;
        // A real board or sensor moves with real time: a simulated clock cannot step it.
        if entry.real_device && self.sim.is_some() {
            return Err(ObjectError::Unsupported {
                kind: kind.into(),
                method: "a node on the simulated clock (a real device cannot be stepped by it: \
                         use board/sim, board/fpga or sensor/virtual, or start the node without \
                         --sim-clock)"
                    .into(),
            });
        }
        if config.len() > 64 * 1024 {
            return Err(ObjectError::BadConfig {
                kind: kind.into(),
                message: "configuration longer than 64 KiB".into(),
            });
        }
        // Built before the registry's lock is taken: a robot's file is read here (bounded,
        // regular files only), and no other call waits for it.
        let o = registry::make(k, name, config, &self.config.robot_files)?;
        let mut reg = self.lock()?;
        if reg.objects.contains_key(name) {
            return Err(ObjectError::NameTaken(name.into()));
        }
        if reg.objects.len() >= self.config.max_objects as usize {
            return Err(ObjectError::LimitReached {
                what: "objects".into(),
                limit: self.config.max_objects,
            });
        }
        let info = o.info(&reg.bridged);
        reg.objects.insert(name.to_string(), o);
        drop(reg);
        self.note_lifecycle(name, &info.kind, "create", info.state.as_str());
        Ok(info)
    }

    /// Removes an object; with `force`, stops the active controllers that use it first.
    ///
    /// # Errors
    /// [`ObjectError::UnknownName`], [`ObjectError::InUse`].
    pub fn destroy(&self, name: &str, force: bool) -> Result<(), ObjectError> {
        let dependents: Vec<String> = {
            let reg = self.lock()?;
            let o = reg.get(name)?;
            let mut d: Vec<String> = o.users.iter().cloned().collect();
            if o.kind.class() == Class::Controller && o.shown_state() == LifecycleState::Active {
                d.push(name.to_string());
            }
            d
        };
        if !dependents.is_empty() {
            if !force {
                return Err(ObjectError::InUse {
                    name: name.to_string(),
                    dependents,
                });
            }
            for c in &dependents {
                self.stop_controller(c, false)?;
            }
        }
        let mut reg = self.lock()?;
        let removed = reg.objects.remove(name);
        reg.bridged.remove(name);
        drop(reg);
        if let Some(mut o) = removed {
            if let KindState::Galil(g) = &mut o.body
                && let Some(mut b) = g.board.take()
            {
                use penelope_hal::Board;
                let _ = b.set_enabled(false);
            }
            self.note_lifecycle(name, o.kind.as_str(), "destroy", "destroyed");
        }
        self.subscriptions.links().end_stale(name, None);
        // A camera's subscriptions end with it.
        self.subscriptions.frames().end_camera(name);
        Ok(())
    }

    /// Runs a lifecycle transition on an object.
    ///
    /// # Errors
    /// [`ObjectError::InvalidTransition`], [`ObjectError::NotReady`], [`ObjectError::InUse`],
    /// [`ObjectError::Device`] and the configuration's errors.
    pub fn transition(&self, name: &str, t: Transition) -> Result<ObjectInfo, ObjectError> {
        let class = self.lock()?.get(name)?.kind.class();
        match (class, t) {
            (Class::Controller, Transition::Activate) => self.activate(name)?,
            (Class::Controller, Transition::Deactivate) => {
                let state = self.lock()?.get(name)?.shown_state();
                if state != LifecycleState::Active {
                    return Err(ObjectError::InvalidTransition {
                        name: name.into(),
                        state,
                        transition: t,
                    });
                }
                self.deactivate(name)?;
            }
            (Class::Controller, Transition::Shutdown) => {
                if self.lock()?.get(name)?.shown_state() == LifecycleState::Active {
                    self.deactivate(name)?;
                }
                self.lock()?.transition(name, t)?;
            }
            _ => self.lock()?.transition(name, t)?,
        }
        if class == Class::Trajectory {
            // A channel cleaned up or configured anew has lost the link its watchers read.
            let current = self.link_source(name)?;
            self.subscriptions.links().end_stale(name, current.as_ref());
        }
        let info = self
            .info(name)
            .ok_or_else(|| ObjectError::UnknownName(name.into()))?;
        self.note_lifecycle(name, &info.kind, t.as_str(), info.state.as_str());
        Ok(info)
    }

    fn object_call(&self, object: &str, method: Method) -> Result<Reply, ObjectError> {
        match method {
            Method::Controller(ControllerMethod::Rearm) => self.rearm(object),
            Method::Describe => self
                .info(object)
                .map(Reply::Object)
                .ok_or_else(|| ObjectError::UnknownName(object.into())),
            Method::Transition(t) => self.transition(object, t).map(Reply::Object),
            Method::Robot(m) => self.lock()?.robot_method(object, m),
            Method::Board(m) => self.lock()?.board_method(object, m),
            Method::Sensor(m) => self.lock()?.sensor_method(object, m),
            Method::Controller(m) => self.lock()?.controller_method(object, m),
            Method::Trajectory(m) => self.lock()?.trajectory_method(object, m),
        }
    }
}

impl Drop for Creator {
    fn drop(&mut self) {
        self.shutdown();
    }
}

#[allow(dead_code)]
fn _assert_send_sync() {
    fn is<T: Send + Sync>() {}
    is::<Creator>();
    let _ = Timestamp::ZERO;
}
