//! The creator and the objects it makes: robots, boards, sensors, controllers and trajectories
//! (DESIGN.md section 1), their relations, their lifecycles, and the real-time loops of the
//! active controllers.
//!
//! - [`kinematics`]: the model a robot's loops compute with (float, or the FPGA board's).
//! - [`kinds`]: every kind and its TOML configuration (keys, units, defaults, ranges).
//! - [`runtime`]: what runs while a controller is active: the control task (SCHED_FIFO), the
//!   communication task (trajectory to reference cell), the sensor feed and the telemetry pump.
//! - [`teleop`]: the teleoperation channel, its ends, the operator's hand and the halves of
//!   the bilateral laws.
//! - `registry` (private): the objects, relations, lifecycles and methods.
//!
//! # Relations are data
//! A controller names its robot, trajectory and (optional) sensor; a robot maps its joints onto
//! board axes (`MapJoints`, one call per board). Names are checked at `configure` and
//! `activate`. A robot's joints may be spread over several boards; a board may be mapped by
//! several robots, but an axis is driven by at most one running loop (a second activation is
//! refused with [`WireError::InUse`]).
//!
//! # Simulated boards
//! A `board/sim` is the electrical side; the mechanism behind it is the robot mapped onto it. The
//! robot's body (one rigid-body plant of its whole chain, since joints are dynamically coupled)
//! is built when the robot is configured, from the first simulated board's settings (DAC bits,
//! sub-step, friction, environment), at the robot's `start` pose; it persists across
//! activations (the loop takes it and gives it back) and is dropped at `cleanup`.
//!
//! # Lifecycle
//! ROS 2 words. Robots, boards, sensors and trajectories are configured by hand and show
//! `active` while a running controller uses them. Activating a controller builds an rt-core
//! `ControlLoop` and starts its threads; `ControlCommand::Activate` goes through the command ring
//! so commands start from the measured state. Deactivating sends `Deactivate` (amplifiers off),
//! joins the threads and gives the boards back.

pub mod kinds;
pub mod kinematics;
mod registry;
pub mod runtime;
pub mod teleop;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::sync_channel;
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

use penelope_hal::{LifecycleState, Timestamp, Transition};
use penelope_rt_core::exec::{self, PeriodicConfig, Setting};

use crate::proto::{
    Call, Class, ControllerMethod, CreatorCall, KindInfo, Method, NodeInfo, ObjectInfo, Reply,
    WireError, check_name,
};
use crate::service::{Remote, Service, Session};
use penelope_rt_core::control::ControlCommand;
use registry::{Body, Launch, Registry};
use runtime::{CommTask, ControlTask, LoopFault, LoopShared, Running, Subscriptions};

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
    /// Real-time settings of the loops.
    pub rt: RtPolicy,
    /// How controllers reach sensors on other nodes (set later with [`Creator::set_remote`]).
    pub remote: Option<Arc<dyn Remote>>,
}

impl std::fmt::Debug for CreatorConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CreatorConfig")
            .field("node", &self.node)
            .field("max_objects", &self.max_objects)
            .field("max_subscriptions", &self.max_subscriptions)
            .field("rt", &self.rt)
            .field("remote", &self.remote.is_some())
            .finish()
    }
}

impl CreatorConfig {
    /// Node `node`: 256 objects, 64 subscriptions, [`RtPolicy::default`], no remote.
    pub fn new(node: impl Into<String>) -> Self {
        CreatorConfig {
            node: node.into(),
            max_objects: 256,
            max_subscriptions: 64,
            rt: RtPolicy::default(),
            remote: None,
        }
    }
}

/// The creator of a node (the paper's `creatorImpl`): makes, lists and destroys objects and
/// serves their methods. `Send + Sync`; its mutex is taken by connection threads only, never by
/// a real-time thread.
pub struct Creator {
    config: CreatorConfig,
    registry: Mutex<Registry>,
    remote: Mutex<Option<Arc<dyn Remote>>>,
    subscriptions: Arc<Subscriptions>,
    fifo: OnceLock<bool>,
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
    pub telemetry: penelope_rt_core::ring::ArcConsumer<
        penelope_rt_core::telemetry::TelemetrySample,
        { runtime::TELEMETRY_CAPACITY },
    >,
    /// The newest sample for a sensor feed.
    pub probe:
        penelope_rt_core::cell::ArcLatestReader<penelope_rt_core::telemetry::TelemetrySample>,
    /// Where a sensor feed writes the wrench (when a sensor is bound).
    pub wrench: Option<
        penelope_rt_core::cell::ArcLatestWriter<
            penelope_rt_core::cell::Stamped<penelope_hal::Wrench>,
        >,
    >,
}

impl Creator {
    /// A creator with no objects.
    pub fn new(config: CreatorConfig) -> Self {
        Creator {
            remote: Mutex::new(config.remote.clone()),
            config,
            registry: Mutex::new(Registry::default()),
            subscriptions: Arc::new(Subscriptions::default()),
            fifo: OnceLock::new(),
        }
    }

    fn lock(&self) -> Result<MutexGuard<'_, Registry>, WireError> {
        self.registry
            .lock()
            .map_err(|_| WireError::Internal("object registry poisoned".into()))
    }

    /// The kinds it makes.
    pub fn kinds(&self) -> Vec<KindInfo> {
        kinds::all_kinds()
    }

    /// Its objects, by name.
    pub fn list(&self) -> Vec<ObjectInfo> {
        self.reap_failed();
        self.lock()
            .map(|r| r.objects.values().map(|o| o.info()).collect())
            .unwrap_or_default()
    }

    /// One object.
    pub fn info(&self, name: &str) -> Option<ObjectInfo> {
        self.reap_failed();
        self.lock().ok()?.objects.get(name).map(|o| o.info())
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

    /// Telemetry subscriptions open now.
    pub fn subscription_count(&self) -> usize {
        self.subscriptions.len()
    }

    /// Makes an object.
    ///
    /// # Errors
    /// [`WireError::BadName`], [`WireError::UnknownKind`], [`WireError::NameTaken`],
    /// [`WireError::LimitReached`], [`WireError::BadConfig`].
    pub fn create(&self, kind: &str, name: &str, config: &str) -> Result<ObjectInfo, WireError> {
        check_name(name)?;
        let k = kinds::Kind::parse(kind)
            .ok_or_else(|| WireError::UnknownKind(kind.chars().take(80).collect()))?;
        if config.len() > 64 * 1024 {
            return Err(WireError::BadConfig {
                kind: kind.into(),
                message: "configuration longer than 64 KiB".into(),
            });
        }
        let mut reg = self.lock()?;
        if reg.objects.contains_key(name) {
            return Err(WireError::NameTaken(name.into()));
        }
        if reg.objects.len() >= self.config.max_objects as usize {
            return Err(WireError::LimitReached {
                what: "objects".into(),
                limit: self.config.max_objects,
            });
        }
        let o = registry::make(k, name, config)?;
        let info = o.info();
        reg.objects.insert(name.to_string(), o);
        Ok(info)
    }

    /// Removes an object; with `force`, stops the active controllers that use it first.
    ///
    /// # Errors
    /// [`WireError::UnknownName`], [`WireError::InUse`].
    pub fn destroy(&self, name: &str, force: bool) -> Result<(), WireError> {
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
                return Err(WireError::InUse {
                    name: name.to_string(),
                    dependents,
                });
            }
            for c in &dependents {
                self.deactivate(c)?;
            }
        }
        let mut reg = self.lock()?;
        if let Some(mut o) = reg.objects.remove(name)
            && let Body::Galil(g) = &mut o.body
            && let Some(mut b) = g.board.take()
        {
            use penelope_hal::Board;
            let _ = b.set_enabled(false);
        }
        Ok(())
    }

    /// Runs a lifecycle transition on an object.
    ///
    /// # Errors
    /// [`WireError::InvalidTransition`], [`WireError::NotReady`], [`WireError::InUse`],
    /// [`WireError::Device`] and the configuration's errors.
    pub fn transition(&self, name: &str, t: Transition) -> Result<ObjectInfo, WireError> {
        let class = self.lock()?.get(name)?.kind.class();
        match (class, t) {
            (Class::Controller, Transition::Activate) => self.activate(name)?,
            (Class::Controller, Transition::Deactivate) => {
                let state = self.lock()?.get(name)?.shown_state();
                if state != LifecycleState::Active {
                    return Err(WireError::InvalidTransition {
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
        self.info(name)
            .ok_or_else(|| WireError::UnknownName(name.into()))
    }

    fn fifo_allowed(&self) -> bool {
        let Some(p) = self.config.rt.priority else {
            return false;
        };
        *self.fifo.get_or_init(|| {
            std::thread::spawn(move || exec::set_fifo(p) == Setting::Applied)
                .join()
                .unwrap_or(false)
        })
    }

    fn activate(&self, name: &str) -> Result<(), WireError> {
        let fifo = self.fifo_allowed();
        let remote = self.remote.lock().ok().and_then(|r| r.clone());
        let launch = Launch {
            rt: &self.config.rt,
            remote,
        };
        let mut reg = self.lock()?;
        let built = reg.build_loop(name, &launch)?;
        let rt = launch.rt;
        let thread_name =
            |prefix: &str| -> String { format!("{prefix}{name}").chars().take(15).collect() };
        let mut control_cfg = PeriodicConfig::new(thread_name("ctl-"), built.timing.period);
        control_cfg.lock_memory = rt.lock_memory;
        control_cfg.hold_dma_latency = rt.lock_memory;
        control_cfg.cpu = rt.cpu;
        control_cfg.priority = if fifo { rt.priority } else { None };
        let mut comm_cfg = PeriodicConfig::new(thread_name("com-"), built.timing.comm_period);
        comm_cfg.lock_memory = false;
        comm_cfg.hold_dma_latency = false;
        comm_cfg.prefault_stack = 64 * 1024;
        comm_cfg.stack_size = 512 * 1024;
        comm_cfg.cpu = rt.cpu;
        comm_cfg.priority = if fifo {
            rt.priority.map(|p| p.saturating_sub(10).max(1))
        } else {
            None
        };
        let scheduling = match (fifo, rt.priority) {
            (true, Some(p)) => format!("SCHED_FIFO {p}"),
            (false, Some(p)) => {
                log::warn!(
                    "controller `{name}`: SCHED_FIFO {p} is not permitted to this process; its loop runs at normal priority"
                );
                "normal (SCHED_FIFO refused)".to_string()
            }
            (_, None) => "normal".to_string(),
        };

        let control_stop = Arc::new(AtomicBool::new(false));
        let comm_stop = Arc::new(AtomicBool::new(false));
        let fault = Arc::new(LoopFault::default());
        let (back_tx, back_rx) = sync_channel(1);
        let (comm_back_tx, comm_back_rx) = sync_channel(1);
        let registry::Built {
            control,
            comm,
            telemetry,
            commands,
            goto,
            gains,
            mut probe,
            wrench,
            source,
            model,
            joints,
            timing,
        } = built;
        // A thread that cannot be spawned is an error, never a silently missing part.
        let spawned_control = exec::spawn(
            control_cfg,
            runtime::control_body(control, control_stop.clone(), back_tx, fault.clone()),
        );
        let control_thread = match spawned_control {
            Ok(t) => t,
            Err(e) => {
                // The task (with the board) went down with the closure: configure again.
                let comm = Some(comm);
                reg.take_back(
                    runtime::StoppedLoop {
                        control: None,
                        comm,
                    },
                    name,
                    false,
                );
                return Err(WireError::Internal(format!(
                    "cannot start the control thread: {e}"
                )));
            }
        };
        let spawned_comm = exec::spawn(
            comm_cfg,
            runtime::comm_body(comm, fault.clone(), comm_stop.clone(), comm_back_tx),
        );
        let comm_thread = match spawned_comm {
            Ok(t) => t,
            Err(e) => {
                control_stop.store(true, Ordering::Release);
                let control = back_rx.recv_timeout(std::time::Duration::from_secs(2)).ok();
                let _ = control_thread.join();
                reg.take_back(
                    runtime::StoppedLoop {
                        control,
                        comm: None,
                    },
                    name,
                    false,
                );
                return Err(WireError::Internal(format!(
                    "cannot start the communication thread: {e}"
                )));
            }
        };
        let aux_stop = Arc::new(AtomicBool::new(false));
        let shared = Arc::new(LoopShared::default());
        let feed_stats = Arc::new(runtime::FeedStats::default());
        let pump = {
            let (shared, subs, stop) =
                (shared.clone(), self.subscriptions.clone(), aux_stop.clone());
            let controller = name.to_string();
            let mut telemetry = telemetry;
            let period = timing.telemetry_period;
            std::thread::Builder::new()
                .name(thread_name("tel-"))
                .spawn(move || {
                    runtime::run_pump(
                        &mut telemetry,
                        &shared,
                        &subs,
                        &controller,
                        joints,
                        period,
                        &stop,
                    );
                })
        };
        let feed = match (source, wrench) {
            (Some(source), Some(mut out)) => {
                let (stop, stats) = (aux_stop.clone(), feed_stats.clone());
                let controller = name.to_string();
                let period = timing.sensor_period;
                Some(
                    std::thread::Builder::new()
                        .name(thread_name("sen-"))
                        .spawn(move || {
                            runtime::run_sensor_feed(
                                &source,
                                &model,
                                &mut probe,
                                &mut out,
                                period,
                                &stop,
                                &stats,
                                &controller,
                            );
                        }),
                )
            }
            _ => None,
        };
        let spawn_error = match (&pump, &feed) {
            (Err(e), _) => Some(format!("cannot start the telemetry thread: {e}")),
            (_, Some(Err(e))) => Some(format!("cannot start the sensor feed thread: {e}")),
            _ => None,
        };
        let running = Running {
            control: Some(control_thread),
            control_stop,
            control_back: back_rx,
            comm: Some(comm_thread),
            comm_stop,
            comm_back: comm_back_rx,
            commands,
            goto,
            gains,
            pump: pump.ok(),
            aux_stop,
            feed: feed.and_then(Result::ok),
            feed_stats,
            shared,
            fifo,
            period: timing.period,
            fault,
        };
        if let Some(why) = spawn_error {
            // Stop what did start, give the board back, and say why.
            let stopped = running.stop();
            reg.take_back(stopped, name, false);
            return Err(WireError::Internal(why));
        }
        let o = reg.get_mut(name)?;
        o.state = LifecycleState::Active;
        if let Body::Controller(c) = &mut o.body {
            c.running = Some(running);
            c.scheduling = Some(scheduling);
            c.fault = None;
        }
        Ok(())
    }

    /// Takes every loop whose threads failed out of service: the control thread already
    /// brought its robot to the safe state (amplifiers off, or the board's servo holding); here
    /// the threads are joined, the board goes back to its objects as it is, and the controller
    /// shows `error` with the cause until it is re-armed. Runs before every call, so what a
    /// client sees is never a dead loop shown `active`.
    fn reap_failed(&self) {
        let failed: Vec<(String, String, Running)> = {
            let Ok(mut reg) = self.lock() else { return };
            let names: Vec<String> = reg
                .objects
                .values()
                .filter(|o| {
                    matches!(&o.body, Body::Controller(c)
                        if c.running.as_ref().is_some_and(|r| r.failure().is_some()))
                })
                .map(|o| o.name.clone())
                .collect();
            names
                .into_iter()
                .filter_map(|name| {
                    let o = reg.objects.get_mut(&name)?;
                    let Body::Controller(c) = &mut o.body else {
                        return None;
                    };
                    let robot = c.robot.clone().unwrap_or_default();
                    Some((name, robot, c.running.take()?))
                })
                .collect()
        };
        for (name, robot, running) in failed {
            let cause = running
                .failure()
                .unwrap_or_else(|| "a thread failed".into());
            let last = running.shared.newest().map(|n| n.sample);
            let stopped = running.stop_failed();
            let Ok(mut reg) = self.lock() else { return };
            let stopped = reg.take_back(stopped, &name, true);
            log::error!(
                "node {}: controller `{name}` failed ({cause}); robot `{robot}` stopped: {stopped}",
                self.config.node
            );
            if let Ok(o) = reg.get_mut(&name) {
                o.state = LifecycleState::Error;
                if let Body::Controller(c) = &mut o.body {
                    c.fault = Some(cause);
                    c.last = last.or(c.last);
                    c.scheduling = None;
                }
            }
        }
    }

    /// Calls `method` on object `object` (as a connection's `Call::Object` would, for calls made
    /// inside the process).
    ///
    /// # Errors
    /// The object's typed error.
    pub fn call_object(&self, object: &str, method: Method) -> Result<Reply, WireError> {
        self.reap_failed();
        self.object_call(object, method)
    }

    /// Makes a thread of controller `name`'s running loop panic in its next tick, as a bug
    /// would (fault-injection tests of the failure path).
    ///
    /// # Errors
    /// [`WireError::UnknownName`], or [`WireError::NotReady`] when it is not running.
    #[cfg(feature = "fault-injection")]
    pub fn inject_thread_panic(
        &self,
        name: &str,
        thread: runtime::LoopThread,
    ) -> Result<(), WireError> {
        let reg = self.lock()?;
        match &reg.get(name)?.body {
            Body::Controller(c) => match &c.running {
                Some(r) => {
                    r.fault.inject_panic(thread);
                    Ok(())
                }
                None => Err(WireError::NotReady(format!("`{name}` is not running"))),
            },
            _ => Err(WireError::NotReady(format!("`{name}` is not a controller"))),
        }
    }

    /// Re-arms controller `name`: a running loop clears its latched fault or e-stop (and its
    /// boards' own latches) and activates again from the measured state; a loop whose threads
    /// failed (`error`) is built and started anew, from the measured state.
    fn rearm(&self, name: &str) -> Result<Reply, WireError> {
        let failed = {
            let mut reg = self.lock()?;
            let o = reg.get_mut(name)?;
            if o.kind.class() != Class::Controller {
                return Err(WireError::WrongClass {
                    name: name.into(),
                    expected: Class::Controller,
                    found: o.kind.class(),
                });
            }
            let failed = o.state == LifecycleState::Error;
            if failed {
                o.state = LifecycleState::Inactive;
                if let Body::Controller(c) = &mut o.body {
                    c.fault = None;
                }
            }
            failed
        };
        if failed {
            self.activate(name)?;
            return Ok(Reply::Unit);
        }
        let mut reg = self.lock()?;
        let Body::Controller(c) = &mut reg.get_mut(name)?.body else {
            return Err(WireError::Internal("controller body".into()));
        };
        let run = c
            .running
            .as_mut()
            .ok_or_else(|| WireError::NotReady(format!("controller `{name}` is not running")))?;
        for cmd in [ControlCommand::Rearm, ControlCommand::Activate] {
            run.commands
                .push(cmd)
                .map_err(|_| WireError::NotReady("command queue full; retry".into()))?;
        }
        Ok(Reply::Unit)
    }

    /// Stops controller `name`'s loop (amplifiers off), joins its threads and gives its boards
    /// back. The registry lock is not held while threads are joined (a sensor feed may be calling
    /// back into this node).
    fn deactivate(&self, name: &str) -> Result<(), WireError> {
        let running = {
            let mut reg = self.lock()?;
            let o = reg.get_mut(name)?;
            match &mut o.body {
                Body::Controller(c) => c.running.take(),
                _ => return Err(WireError::Internal("not a controller".into())),
            }
        };
        let mut last = None;
        let stopped = running.map(|r| {
            let shared = r.shared.clone();
            let stopped = r.stop();
            last = shared.newest().map(|n| n.sample);
            stopped
        });
        let mut reg = self.lock()?;
        if let Some(stopped) = stopped {
            reg.take_back(stopped, name, false);
        }
        reg.release_users(name);
        let o = reg.get_mut(name)?;
        o.state = LifecycleState::Inactive;
        if let Body::Controller(c) = &mut o.body {
            c.last = last.or(c.last);
            c.scheduling = None;
        }
        Ok(())
    }

    /// Builds controller `name`'s loop without starting any thread (for tests and benchmarks
    /// that step it on a simulated clock). The controller stays `inactive`, but the objects it
    /// uses show it as their user and the robot's board is inside the returned loop, so they
    /// cannot run elsewhere until the creator is dropped.
    ///
    /// # Errors
    /// As activating the controller.
    pub fn detach_loop(&self, name: &str) -> Result<DetachedLoop, WireError> {
        let launch = Launch {
            rt: &self.config.rt,
            remote: self.remote.lock().ok().and_then(|r| r.clone()),
        };
        let built = self.lock()?.build_loop(name, &launch)?;
        Ok(DetachedLoop {
            control: built.control,
            comm: built.comm,
            telemetry: built.telemetry,
            probe: built.probe,
            wrench: built.wrench,
        })
    }

    /// Stops every running loop safely (amplifiers off, threads joined).
    pub fn shutdown(&self) {
        let active: Vec<String> = self
            .lock()
            .map(|r| {
                r.objects
                    .values()
                    .filter(|o| matches!(&o.body, Body::Controller(c) if c.running.is_some()))
                    .map(|o| o.name.clone())
                    .collect()
            })
            .unwrap_or_default();
        for c in active {
            if let Err(e) = self.deactivate(&c) {
                log::warn!("shutdown: controller `{c}`: {e}");
            }
        }
    }

    fn subscribe(
        &self,
        session: &Session,
        object: &str,
        decimation: u32,
    ) -> Result<Reply, WireError> {
        let controller = {
            let reg = self.lock()?;
            let o = reg.get(object)?;
            match o.kind.class() {
                Class::Controller => object.to_string(),
                Class::Robot => reg.driver_of(object).ok_or_else(|| {
                    WireError::NotReady(format!(
                        "robot `{object}` is not driven by an active controller; subscribe to a controller"
                    ))
                })?,
                found => {
                    return Err(WireError::WrongClass {
                        name: object.into(),
                        expected: Class::Controller,
                        found,
                    });
                }
            }
        };
        let id = self.subscriptions.add(
            session.id,
            &controller,
            decimation,
            session.outbox.clone(),
            self.config.max_subscriptions,
        )?;
        Ok(Reply::Subscribed { subscription: id })
    }

    fn object_call(&self, object: &str, method: Method) -> Result<Reply, WireError> {
        match method {
            Method::Controller(ControllerMethod::Rearm) => self.rearm(object),
            Method::Describe => self
                .info(object)
                .map(Reply::Object)
                .ok_or_else(|| WireError::UnknownName(object.into())),
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

impl Service for Creator {
    fn call(&self, session: &Session, call: Call) -> Result<Reply, WireError> {
        self.reap_failed();
        match call {
            Call::Ping { payload } => Ok(Reply::Pong(payload)),
            Call::NodeInfo => Ok(Reply::Node(NodeInfo {
                node: self.config.node.clone(),
                software: env!("CARGO_PKG_VERSION").to_string(),
                hosts_naming: false,
                objects: self.object_count(),
            })),
            Call::Creator(CreatorCall::Kinds) => Ok(Reply::Kinds(self.kinds())),
            Call::Creator(CreatorCall::List) => Ok(Reply::Objects(self.list())),
            Call::Creator(CreatorCall::Create { kind, name, config }) => {
                self.create(&kind, &name, &config).map(Reply::Object)
            }
            Call::Creator(CreatorCall::Destroy { name, force }) => {
                self.destroy(&name, force).map(|()| Reply::Unit)
            }
            Call::Object { object, method } => self.object_call(&object, method),
            Call::Naming(_) => Err(WireError::NoNamingService),
            Call::Subscribe { object, decimation } => self.subscribe(session, &object, decimation),
            Call::Unsubscribe { subscription } => {
                if self.subscriptions.remove(session.id, subscription) {
                    Ok(Reply::Unit)
                } else {
                    Err(WireError::UnknownName(format!(
                        "subscription {subscription}"
                    )))
                }
            }
        }
    }

    fn closed(&self, session: &Session) {
        self.subscriptions.remove_session(session.id);
    }
}

#[allow(dead_code)]
fn _assert_send_sync() {
    fn is<T: Send + Sync>() {}
    is::<Creator>();
    let _ = Timestamp::ZERO;
    let _ = Ordering::Relaxed;
}
