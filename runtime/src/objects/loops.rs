//! The loops of active controllers: starting them (threads, or steps on the simulated clock),
//! stopping them safely, taking failed ones out of service, and the simulated clock's controls.

use std::sync::atomic::AtomicBool;
use std::sync::mpsc::sync_channel;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use penelope_hal::{LifecycleState, Timestamp};
use penelope_rt_core::control::ControlCommand;
use penelope_rt_core::exec::{self, PeriodicConfig, Setting};
use penelope_rt_core::safety::TeleopRole;

use super::registry::{self, KindState, Launch};
use super::runtime::{self, LoopFault, LoopShared, Running, StopMode, StoppedLoop};
use super::sim_world::{SimWorld, SteppedLoop, TickBody};
use super::tick::TickStream;
use super::{Creator, DetachedLoop, RtPolicy};
use crate::objects::error::ObjectError;
use penelope_protocol::proto::{CallError, Class, Method, Reply, WireError};

impl Creator {
    pub(super) fn fifo_allowed(&self) -> bool {
        let Some(p) = self.config.rt.priority else {
            return false;
        };
        *self.fifo.get_or_init(|| {
            std::thread::spawn(move || exec::set_fifo(p) == Setting::Applied)
                .join()
                .unwrap_or(false)
        })
    }

    /// What activating controller `name` needs from outside the registry: the remote link,
    /// and, for a sensor on another node, where that sensor is published on the data plane
    /// (asked of the sensor once, here, without the registry's lock: the only TCP call a
    /// remote sensor costs).
    fn launch(&self, name: &str) -> Result<Launch<'_>, ObjectError> {
        let remote = self.remote.lock().ok().and_then(|r| r.clone());
        let path = match &self.lock()?.get(name)?.body {
            KindState::Controller(c) => c.sensor.clone().filter(|s| s.starts_with('/')),
            _ => None,
        };
        // A published sensor measures on its own node's time, not in step with a simulated
        // clock: the wrench would be stale to the stepped loop, tick after tick.
        if let (Some(path), Some(_)) = (&path, &self.sim) {
            return Err(ObjectError::NotReady(format!(
                "sensor `{path}` is on another node, read over the data plane in real time; on a \
                 simulated clock put the sensor on this node (or run the nodes in real time)"
            )));
        }
        let sensor_stream = match (&path, &remote) {
            (Some(path), Some(remote)) => Some(sensor_stream(remote.as_ref(), path)?),
            _ => None,
        };
        Ok(Launch {
            rt: &self.config.rt,
            remote,
            sensor_stream,
        })
    }

    pub(super) fn activate(&self, name: &str) -> Result<(), ObjectError> {
        let fifo = self.fifo_allowed();
        let launch = self.launch(name)?;
        let mut reg = self.lock()?;
        let built = reg.build_loop(name, &launch)?;
        // A camera watching this controller's robot takes its ticks from now on.
        if let KindState::Controller(c) = &reg.get(name)?.body
            && let Some(robot) = &c.robot
        {
            self.subscriptions.set_driver(name, robot);
        }
        let rt = launch.rt;
        let scheduling = scheduling(name, fifo, rt.priority);
        let (mut running, bodies) = self.wire_loop(name, built, fifo);
        let stop = running.stop.clone();
        let scheduling = if let Some(world) = &self.sim {
            step_on_simulated_clock(world, name, bodies)?;
            "simulated clock".to_string()
        } else {
            if let Err(why) = start_threads(name, &mut running, bodies, rt, fifo) {
                // Stop what did start, give the board back, and say why.
                let stopped = running.stop(StopMode::Deactivate);
                reg.take_back(stopped, name, false);
                return Err(why);
            }
            scheduling
        };
        let o = reg.get_mut(name)?;
        o.state = LifecycleState::Active;
        if let KindState::Controller(c) = &mut o.body {
            c.running = Some(running);
            c.scheduling = Some(scheduling);
            c.fault = None;
        }
        self.stops.insert(name, stop);
        Ok(())
    }

    /// Wires the loop the registry built for controller `name`: the stop flags, fault record
    /// and hand-back channels its bodies share with the [`Running`] that stops them, and the
    /// bodies themselves, not started yet.
    fn wire_loop(&self, name: &str, built: registry::Built, fifo: bool) -> (Running, LoopBodies) {
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
            stop,
            goto,
            motion,
            gains,
            probe,
            wrench,
            source,
            model,
            joints,
            timing,
        } = built;
        let aux_stop = Arc::new(AtomicBool::new(false));
        let shared = Arc::new(LoopShared::default());
        let feed_stats = Arc::new(runtime::FeedStats::default());
        let pump = runtime::Pump::new(
            telemetry,
            shared.clone(),
            self.subscriptions.clone(),
            name,
            joints,
        );
        let feed = match (source, wrench) {
            (Some(source), Some(out)) => Some(runtime::SensorFeed {
                source,
                model,
                state: probe,
                out,
                stats: feed_stats.clone(),
                controller: name.to_string(),
            }),
            _ => None,
        };
        // A teleoperation end's thread also wakes on its doorbell and socket (urgent samples);
        // without them (no descriptor left) it still ticks, as every other loop's does.
        let event_driven = comm.is_event_driven();
        // A teleoperation end's control loop ticks at its side's phase on the common clock:
        // the master's and the slave's half a period apart, whatever hosts they run on.
        let tick_phase = comm.teleop_side().map(|side| {
            exec::TickPhase::new(
                side.tick_phase(timing.period),
                self.config.common_clock.offset_cell(),
            )
        });
        let comm_wake = comm.wake_on().unwrap_or_else(|e| {
            log::warn!("controller `{name}`: urgent samples wait for the period ({e})");
            None
        });
        let mut control = control;
        if self.sim.is_none() {
            // On the real clock the simulated world goes on when the control thread does not.
            control.keep_plant_moving();
        }
        let control_body =
            runtime::control_body(control, control_stop.clone(), back_tx, fault.clone());
        let comm_body = runtime::comm_body(comm, fault.clone(), comm_stop.clone(), comm_back_tx);
        let running = Running {
            control: None,
            control_stop,
            control_back: back_rx,
            comm: None,
            comm_stop,
            comm_back: comm_back_rx,
            commands,
            stop,
            goto,
            motion,
            gains,
            pump: None,
            aux_stop,
            feed: None,
            feed_stats,
            shared,
            fifo,
            period: timing.period,
            fault,
        };
        let bodies = LoopBodies {
            control: Box::new(control_body),
            comm: Box::new(comm_body),
            pump,
            feed,
            comm_wake,
            event_driven,
            tick_phase,
            timing,
        };
        (running, bodies)
    }

    /// Takes every loop whose threads failed out of service: the control thread already
    /// brought its robot to the safe state (amplifiers off, or the board's servo holding); here
    /// the threads are joined, the board goes back to its objects as it is, and the controller
    /// shows `error` with the cause until it is re-armed. Runs before every call, so what a
    /// client sees is never a dead loop shown `active`.
    pub(super) fn reap_failed(&self) {
        let failed: Vec<(String, String, Running)> = {
            let Ok(mut reg) = self.lock() else { return };
            let names: Vec<String> = reg
                .objects
                .values()
                .filter(|o| {
                    matches!(&o.body, KindState::Controller(c)
                        if c.running.as_ref().is_some_and(|r| r.failure().is_some()))
                })
                .map(|o| o.name.clone())
                .collect();
            names
                .into_iter()
                .filter_map(|name| {
                    let o = reg.objects.get_mut(&name)?;
                    let KindState::Controller(c) = &mut o.body else {
                        return None;
                    };
                    let robot = c.robot.clone().unwrap_or_default();
                    self.stops.remove(&name);
                    Some((name, robot, c.running.take()?))
                })
                .collect()
        };
        for (name, robot, running) in failed {
            let cause = running
                .failure()
                .unwrap_or_else(|| "a thread failed".into());
            let last = running.shared.newest().map(|n| n.sample);
            let stopped = self.stop_loop(&name, running, None);
            let Ok(mut reg) = self.lock() else { return };
            let stopped = reg.take_back(stopped, &name, true);
            log::error!(
                "node {}: controller `{name}` failed ({cause}); robot `{robot}` stopped: {stopped}",
                self.config.node
            );
            if let Ok(o) = reg.get_mut(&name) {
                o.state = LifecycleState::Error;
                if let KindState::Controller(c) = &mut o.body {
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
    pub fn call_object(&self, object: &str, method: Method) -> Result<Reply, ObjectError> {
        self.reap_failed();
        self.object_call(object, method)
    }

    /// Makes a thread of controller `name`'s running loop panic in its next tick, as a bug
    /// would (fault-injection tests of the failure path).
    ///
    /// # Errors
    /// [`ObjectError::UnknownName`], or [`ObjectError::NotReady`] when it is not running.
    #[cfg(feature = "fault-injection")]
    pub fn inject_thread_panic(
        &self,
        name: &str,
        thread: runtime::LoopThread,
    ) -> Result<(), ObjectError> {
        let reg = self.lock()?;
        match &reg.get(name)?.body {
            KindState::Controller(c) => match &c.running {
                Some(r) => {
                    r.fault.inject_panic(thread);
                    Ok(())
                }
                None => Err(ObjectError::NotReady(format!("`{name}` is not running"))),
            },
            _ => Err(ObjectError::NotReady(format!(
                "`{name}` is not a controller"
            ))),
        }
    }

    /// Re-arms controller `name`: a running loop clears its latched fault or e-stop (and its
    /// boards' own latches) and activates again from the measured state; a loop whose threads
    /// failed (`error`) is built and started anew, from the measured state.
    pub(super) fn rearm(&self, name: &str) -> Result<Reply, ObjectError> {
        let failed = {
            let mut reg = self.lock()?;
            let o = reg.get_mut(name)?;
            if o.kind.class() != Class::Controller {
                return Err(ObjectError::WrongClass {
                    name: name.into(),
                    expected: Class::Controller,
                    found: o.kind.class(),
                });
            }
            let failed = o.state == LifecycleState::Error;
            if failed {
                o.state = LifecycleState::Inactive;
                if let KindState::Controller(c) = &mut o.body {
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
        let KindState::Controller(c) = &mut reg.get_mut(name)?.body else {
            return Err(ObjectError::internal("controller body"));
        };
        let run = c
            .running
            .as_mut()
            .ok_or_else(|| ObjectError::NotReady(format!("controller `{name}` is not running")))?;
        for cmd in [ControlCommand::Rearm, ControlCommand::Activate] {
            run.commands
                .push(cmd)
                .map_err(|_| ObjectError::NotReady("command queue full; retry".into()))?;
        }
        Ok(Reply::Unit)
    }

    /// Stops controller `name`'s loop, joins its threads and gives its boards back: a slave
    /// held where it is by its board's servo, a master with zero torque and amplifiers off.
    /// The registry lock is not held while threads are joined (a sensor feed may be calling back
    /// into this node).
    pub(super) fn deactivate(&self, name: &str) -> Result<(), ObjectError> {
        self.stop_controller(name, true)
    }

    /// Stops controller `name`'s loop as [`deactivate`](Self::deactivate) does, a slave held by
    /// its board's servo when `hold_slave`, otherwise every robot with zero torque and its
    /// amplifiers off (a forced destroy, the node's shutdown).
    pub(super) fn stop_controller(&self, name: &str, hold_slave: bool) -> Result<(), ObjectError> {
        let (running, mode) = {
            let mut reg = self.lock()?;
            let mode = match reg.role_of(name) {
                Some(TeleopRole::Slave) if hold_slave => StopMode::Hold,
                _ => StopMode::Deactivate,
            };
            let o = reg.get_mut(name)?;
            self.stops.remove(name);
            match &mut o.body {
                KindState::Controller(c) => (c.running.take(), mode),
                _ => return Err(ObjectError::internal("not a controller")),
            }
        };
        let mut last = None;
        let stopped = running.map(|r| {
            let shared = r.shared.clone();
            let stopped = self.stop_loop(name, r, Some(mode));
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
        if let KindState::Controller(c) = &mut o.body {
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
    pub fn detach_loop(&self, name: &str) -> Result<DetachedLoop, ObjectError> {
        let launch = self.launch(name)?;
        let built = self.lock()?.build_loop(name, &launch)?;
        Ok(DetachedLoop {
            control: built.control,
            comm: built.comm,
            telemetry: built.telemetry,
            probe: built.probe,
            wrench: built.wrench,
            gains: built.gains,
            goto: built.goto,
            motion: built.motion,
        })
    }

    /// Stops every running loop safely (amplifiers off, threads joined).
    pub fn shutdown(&self) {
        let active: Vec<String> = self
            .lock()
            .map(|r| {
                r.objects
                    .values()
                    .filter(|o| matches!(&o.body, KindState::Controller(c) if c.running.is_some()))
                    .map(|o| o.name.clone())
                    .collect()
            })
            .unwrap_or_default();
        for c in active {
            if let Err(e) = self.stop_controller(&c, false) {
                log::warn!("shutdown: controller `{c}`: {e}");
            }
        }
    }

    /// Moves the simulated clock on by `by`, stepping every active loop in order, and returns
    /// its new time.
    ///
    /// # Errors
    /// [`ObjectError::NotReady`] on a creator clocked in real time.
    pub fn advance(&self, by: Duration) -> Result<Timestamp, ObjectError> {
        let world = self.sim.as_ref().ok_or_else(|| {
            ObjectError::NotReady(
                "this node runs in real time; only a simulated clock advances".into(),
            )
        })?;
        let now = world
            .lock()
            .map_err(|_| ObjectError::Poisoned("simulated clock"))?
            .advance(by);
        // Link records follow the simulated clock that moves the links.
        self.subscriptions.links().publish(now.as_nanos());
        self.reap_failed();
        Ok(now)
    }

    /// The simulated clock's time (`None` in real time).
    pub fn sim_time(&self) -> Option<Timestamp> {
        self.sim
            .as_ref()
            .and_then(|w| w.lock().ok().map(|w| w.now()))
    }

    /// Records every tick of controller `name` (not decimated, with the plant's truth) from now
    /// on, into a stream of up to `capacity` ticks: what a run's report and files are made of.
    /// A reader that falls behind loses ticks (counted), never the loop.
    ///
    /// # Errors
    /// [`ObjectError::UnknownName`], or [`ObjectError::WrongClass`] for an object that is not a
    /// controller.
    pub fn record_ticks(&self, name: &str, capacity: usize) -> Result<TickStream, ObjectError> {
        let class = self.lock()?.get(name)?.kind.class();
        if class != Class::Controller {
            return Err(ObjectError::WrongClass {
                name: name.into(),
                expected: Class::Controller,
                found: class,
            });
        }
        Ok(self.subscriptions.record(name, capacity))
    }

    /// Stops `running` (controller `name`'s loop): its threads, or its steps on the simulated
    /// clock. `failed`: the loop already brought its robot to the safe state.
    /// Stops a loop: on purpose (`mode`), or after a failure (`None`).
    fn stop_loop(&self, name: &str, running: Running, mode: Option<StopMode>) -> StoppedLoop {
        // A creator's clock is fixed at its creation: on the real clock every loop has threads.
        let Some(world) = &self.sim else {
            return match mode {
                Some(mode) => running.stop(mode),
                None => running.stop_failed(),
            };
        };
        let mut running = running;
        if mode == Some(StopMode::Deactivate) {
            let _ = running.commands.push(ControlCommand::Deactivate);
        }
        let Ok(mut world) = world.lock() else {
            return StoppedLoop {
                control: None,
                comm: None,
            };
        };
        let now = world.now();
        match world.remove(name) {
            Some(stepped) => stepped.stop(&running, now, mode),
            None => StoppedLoop {
                control: None,
                comm: None,
            },
        }
    }
}

/// Starts the threads of a loop: control (SCHED_FIFO where permitted), communication, the
/// telemetry pump and the sensor feed. On an error, what did start is in `running`.
/// A controller's loop, wired and not started: what its threads (or the simulated clock's
/// steps) run, and their periods.
struct LoopBodies {
    control: TickBody,
    comm: TickBody,
    pump: runtime::Pump,
    feed: Option<runtime::SensorFeed>,
    /// What wakes the communication thread before its period (a teleoperation end's doorbell
    /// and socket); unused on the simulated clock.
    comm_wake: Option<penelope_rt_core::wake::WakeOn>,
    /// The communication task hands samples on as they are made (on the simulated clock: an
    /// early tick around each control tick, where the doorbell and the socket would wake it).
    event_driven: bool,
    /// Where the control thread ticks on the common clock (a teleoperation end's side), or
    /// `None`: one period after it starts. Unused on the simulated clock, where every loop is
    /// stepped from the clock's time.
    tick_phase: Option<exec::TickPhase>,
    timing: crate::objects::config::LoopTiming,
}

/// How controller `name`'s control thread is scheduled, for `describe`; says once in the log
/// when SCHED_FIFO was asked for and refused.
fn scheduling(name: &str, fifo: bool, priority: Option<u8>) -> String {
    match (fifo, priority) {
        (true, Some(p)) => format!("SCHED_FIFO {p}"),
        (false, Some(p)) => {
            log::warn!(
                "controller `{name}`: SCHED_FIFO {p} is not permitted to this process; its loop runs at normal priority"
            );
            "normal (SCHED_FIFO refused)".to_string()
        }
        (_, None) => "normal".to_string(),
    }
}

/// Puts controller `name`'s loop on the simulated clock, stepped from the clock's present time.
fn step_on_simulated_clock(
    world: &Mutex<SimWorld>,
    name: &str,
    bodies: LoopBodies,
) -> Result<(), ObjectError> {
    let mut world = world
        .lock()
        .map_err(|_| ObjectError::Poisoned("simulated clock"))?;
    let now = world.now();
    let timing = bodies.timing;
    world.add(
        name,
        SteppedLoop::new(
            now,
            bodies.control,
            bodies.comm,
            bodies.feed,
            bodies.pump,
            (timing.period, timing.comm_period, timing.sensor_period),
        )
        .event_driven(bodies.event_driven),
    );
    Ok(())
}

fn start_threads(
    name: &str,
    running: &mut Running,
    bodies: LoopBodies,
    rt: &RtPolicy,
    fifo: bool,
) -> Result<(), ObjectError> {
    let LoopBodies {
        control,
        comm,
        mut pump,
        feed,
        comm_wake,
        tick_phase,
        timing,
        ..
    } = bodies;
    let thread_name =
        |prefix: &str| -> String { format!("{prefix}{name}").chars().take(15).collect() };
    let mut control_cfg = PeriodicConfig::new(thread_name("ctl-"), timing.period);
    control_cfg.lock_memory = rt.lock_memory;
    control_cfg.hold_dma_latency = rt.lock_memory;
    control_cfg.cpu = rt.cpu;
    control_cfg.priority = if fifo { rt.priority } else { None };
    control_cfg.tick_phase = tick_phase;
    let mut comm_cfg = PeriodicConfig::new(thread_name("com-"), timing.comm_period);
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
    // A thread that cannot be spawned is an error, never a silently missing part. (A body that
    // never ran went down with its task and board: the robot must be configured again.)
    running.control = Some(
        exec::spawn(control_cfg, control)
            .map_err(|e| ObjectError::thread("cannot start the control thread", e))?,
    );
    let comm = match comm_wake {
        Some(wake) => exec::spawn_woken(comm_cfg, wake, comm),
        None => exec::spawn(comm_cfg, comm),
    };
    running.comm =
        Some(comm.map_err(|e| ObjectError::thread("cannot start the communication thread", e))?);
    let (stop, period) = (running.aux_stop.clone(), timing.telemetry_period);
    running.pump = Some(
        std::thread::Builder::new()
            .name(thread_name("tel-"))
            .spawn(move || runtime::run_pump(&mut pump, period, &stop))
            .map_err(|e| ObjectError::thread("cannot start the telemetry thread", e))?,
    );
    if let Some(mut feed) = feed {
        let (stop, period) = (running.aux_stop.clone(), timing.sensor_period);
        running.feed = Some(
            std::thread::Builder::new()
                .name(thread_name("sen-"))
                .spawn(move || runtime::run_sensor_feed(&mut feed, period, &stop))
                .map_err(|e| ObjectError::thread("cannot start the sensor feed thread", e))?,
        );
    }
    Ok(())
}

/// Asks the sensor at naming `path` (on another node) where it is published on the data plane.
///
/// # Errors
/// The remote's error; a sensor without `publish` is refused with [`ObjectError::NotReady`]
/// naming the path and the key.
fn sensor_stream(
    remote: &dyn penelope_protocol::service::Remote,
    path: &str,
) -> Result<std::net::SocketAddr, ObjectError> {
    let reply = remote
        .call(
            path,
            Method::Sensor(penelope_protocol::proto::SensorMethod::Stream),
        )
        .map_err(|e| match e {
            WireError::Call(CallError::NotReady(why)) => {
                ObjectError::NotReady(format!("sensor `{path}`: {why}"))
            }
            other => ObjectError::Wire(other),
        })?;
    match reply {
        Reply::Address(a) => a.parse().map_err(|e| {
            ObjectError::RemoteAnswer(format!(
                "sensor `{path}` answered the address {a:?}, which does not parse: {e}"
            ))
        }),
        other => Err(ObjectError::RemoteAnswer(format!(
            "sensor `{path}` answered {other:?}, not its data-plane address"
        ))),
    }
}
