//! The threads of a running controller: their bodies, how they stop, how they fail.

use super::{COMMAND_CAPACITY, GAINS_CAPACITY, GOTO_CAPACITY};
use crate::objects::runtime::{FeedStats, GoToCommand, LoopShared, RoutedGains};
use crate::objects::{CommTask, ControlTask};
use penelope_rt_core::exec::{Flow, PeriodicThread};
use penelope_rt_core::ring::ArcProducer;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The threads of an active controller and the non-real-time ends of their ports.
pub struct Running {
    /// The control thread.
    pub control: Option<PeriodicThread>,
    /// Asks the control thread to hand its task back and stop.
    pub control_stop: Arc<AtomicBool>,
    /// Where the control thread hands its task back.
    pub control_back: Receiver<ControlTask>,
    /// The communication thread.
    pub comm: Option<PeriodicThread>,
    /// Asks the communication thread to hand its task back and stop.
    pub comm_stop: Arc<AtomicBool>,
    /// Where the communication thread hands its task back.
    pub comm_back: Receiver<CommTask>,
    /// Commands to the loop.
    pub commands: ArcProducer<penelope_rt_core::control::ControlCommand, COMMAND_CAPACITY>,
    /// The loop's stop latch (also on the creator's [`StopBoard`](crate::objects::stop_board::StopBoard)).
    pub stop: Arc<penelope_rt_core::stop::StopLatch>,
    /// GoTo requests to the communication task.
    pub goto: ArcProducer<GoToCommand, GOTO_CAPACITY>,
    /// Servo targets to the communication task, and its moves' status.
    pub motion: crate::objects::runtime::MotionControl,
    /// New gains to the loop.
    pub gains: ArcProducer<RoutedGains, GAINS_CAPACITY>,
    /// The pump thread and its stop flag.
    pub pump: Option<std::thread::JoinHandle<()>>,
    /// Stops the pump and the sensor feed.
    pub aux_stop: Arc<AtomicBool>,
    /// The sensor feed thread.
    pub feed: Option<std::thread::JoinHandle<()>>,
    /// Sensor feed counters.
    pub feed_stats: Arc<FeedStats>,
    /// Newest state and counters.
    pub shared: Arc<LoopShared>,
    /// True when the control thread runs SCHED_FIFO.
    pub fifo: bool,
    /// The control period.
    pub period: Duration,
    /// Where the loop's threads report a failure.
    pub fault: Arc<LoopFault>,
}

impl Running {
    /// Overruns of the control thread so far.
    pub fn overruns(&mut self) -> u64 {
        self.control
            .as_mut()
            .and_then(PeriodicThread::live)
            .map_or(0, |l| l.overruns)
    }

    /// Why the loop failed, if it did: a thread reported a panic, or a thread ended although
    /// nobody asked it to.
    pub fn failure(&self) -> Option<String> {
        if self.fault.is_failed() {
            return Some(
                self.fault
                    .cause()
                    .unwrap_or_else(|| "a thread failed".into()),
            );
        }
        if self.control_stop.load(Ordering::Acquire) {
            return None;
        }
        if self
            .control
            .as_ref()
            .is_some_and(PeriodicThread::is_finished)
        {
            return Some("the control thread ended unexpectedly".into());
        }
        if self.comm.as_ref().is_some_and(PeriodicThread::is_finished) {
            return Some("the communication thread ended unexpectedly".into());
        }
        None
    }

    /// Stops the threads of a loop that failed (its control thread already brought the robot
    /// to its safe state, or is told to now) and returns the control task (`None` if its
    /// thread died with it).
    pub fn stop_failed(mut self) -> StoppedLoop {
        if let Some(cause) = self.failure() {
            self.fault.record(cause);
        }
        // The control thread sees the failure on its next tick, stops the robot and hands
        // the task back.
        let control = self.control_back.recv_timeout(Duration::from_secs(2)).ok();
        self.control_stop.store(true, Ordering::Release);
        let comm = self.join_all();
        StoppedLoop { control, comm }
    }

    /// Joins every thread; returns the communication task if its thread handed it back.
    fn join_all(&mut self) -> Option<CommTask> {
        if let Some(t) = self.control.take() {
            let _ = t.join();
        }
        self.comm_stop.store(true, Ordering::Release);
        let comm = match self.comm.take() {
            Some(t) if !t.is_finished() => {
                let task = self.comm_back.recv_timeout(Duration::from_secs(2)).ok();
                let _ = t.join();
                task
            }
            Some(t) => {
                let _ = t.join();
                self.comm_back.try_recv().ok()
            }
            None => None,
        };
        self.aux_stop.store(true, Ordering::Release);
        if let Some(t) = self.feed.take() {
            let _ = t.join();
        }
        if let Some(t) = self.pump.take() {
            let _ = t.join();
        }
        comm
    }

    /// Stops everything: with [`StopMode::Deactivate`], `Deactivate` to the loop (amplifiers
    /// off) and a few periods for it to take effect; with [`StopMode::Hold`], at once, the law
    /// still commanding (the caller then hands the robot to its board's servo). Then the threads
    /// are joined. Returns the tasks (`None` where a thread died).
    pub fn stop(mut self, mode: StopMode) -> StoppedLoop {
        if mode == StopMode::Deactivate {
            let _ = self
                .commands
                .push(penelope_rt_core::control::ControlCommand::Deactivate);
            std::thread::sleep((self.period * 4).max(Duration::from_millis(5)));
        }
        self.control_stop.store(true, Ordering::Release);
        let control = self.control_back.recv_timeout(Duration::from_secs(2)).ok();
        let comm = self.join_all();
        StoppedLoop { control, comm }
    }
}

/// How a loop is stopped on purpose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopMode {
    /// The loop deactivates first: zero torque, amplifiers off (a master).
    Deactivate,
    /// The loop stops while its law still commands; the robot is then held where it is by its
    /// board's own servo (a slave: deactivating its controller must not drop it).
    Hold,
}

/// How the threads of a running loop report that one of them failed (a panic, or an exit
/// nobody asked for). The control thread reads [`is_failed`](Self::is_failed) every tick; the
/// cause is written once, on the failure path only.
#[derive(Debug, Default)]
pub struct LoopFault {
    failed: AtomicBool,
    cause: Mutex<Option<String>>,
    /// A panic asked for by a fault-injection test: 0 none, else a [`LoopThread`] + 1.
    #[cfg(feature = "fault-injection")]
    inject: std::sync::atomic::AtomicU8,
}

/// The threads of a running loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopThread {
    /// The control thread.
    Control,
    /// The communication thread.
    Communication,
}

impl LoopFault {
    /// Makes `thread` panic in its next tick, as a bug would (fault-injection tests only).
    #[cfg(feature = "fault-injection")]
    pub fn inject_panic(&self, thread: LoopThread) {
        self.inject.store(thread as u8 + 1, Ordering::Release);
    }

    /// Panics if a panic of `thread` was injected (nothing without the `fault-injection`
    /// feature).
    #[inline(always)]
    fn injected(&self, thread: LoopThread) {
        #[cfg(feature = "fault-injection")]
        if self.inject.load(Ordering::Acquire) == thread as u8 + 1 {
            panic!("injected fault");
        }
        let _ = thread;
    }
}

impl LoopFault {
    /// Records a failure (the first cause is kept).
    pub fn record(&self, cause: String) {
        if let Ok(mut c) = self.cause.lock() {
            c.get_or_insert(cause);
        }
        self.failed.store(true, Ordering::Release);
    }

    /// True once a thread of the loop failed.
    ///
    /// # Real-time
    /// One atomic load.
    pub fn is_failed(&self) -> bool {
        self.failed.load(Ordering::Acquire)
    }

    /// The first failure's cause.
    pub fn cause(&self) -> Option<String> {
        self.cause.lock().ok().and_then(|c| c.clone())
    }
}

/// The text of a panic's payload.
fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_string())
}

/// Runs `f`; a panic in it becomes `Err(its message)` instead of unwinding further.
///
/// # Real-time
/// Free when `f` does not panic (unwinding costs only on the failure path).
pub fn guarded<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|p| panic_text(p.as_ref()))
}

/// The body of a control thread: ticks `task` until `stop`, then makes the robot safe
/// ([`ControlTask::stop_safely`]) and hands the task back through `back`.
///
/// A tick that panics, or a failure of the loop's other threads reported through `fault`,
/// brings the robot to its safe state ([`ControlLoop::fail_safe`](penelope_rt_core::control::ControlLoop::fail_safe): e-stop latched, amplifiers
/// off or the board's servo holding), records the cause, hands the task back and ends the
/// thread; the creator then shows the controller in `error`.
pub fn control_body(
    task: ControlTask,
    stop: Arc<AtomicBool>,
    back: SyncSender<ControlTask>,
    fault: Arc<LoopFault>,
) -> impl FnMut(penelope_rt_core::exec::Tick) -> Flow + Send + 'static {
    let mut task = Some(task);
    move |tick| {
        let Some(t) = task.as_mut() else {
            return Flow::Stop;
        };
        if stop.load(Ordering::Acquire) {
            // The thread's last act is the safe command; the joins of the other threads (up
            // to seconds) come after it, never with the law's torque still on.
            if let Err(why) = guarded(|| t.stop_safely(tick.deadline)) {
                fault.record(format!("stopping the loop panicked: {why}"));
            }
            if let Some(t) = task.take() {
                let _ = back.try_send(t);
            }
            return Flow::Stop;
        }
        let failed = fault.is_failed()
            || match guarded(|| {
                fault.injected(LoopThread::Control);
                t.note_timing(tick.latency(), tick.previous_exec);
                t.tick(tick.deadline)
            }) {
                Ok(_) => false,
                Err(why) => {
                    fault.record(format!("the control thread panicked: {why}"));
                    true
                }
            };
        if failed {
            if let Err(why) = guarded(|| t.fail_safe(tick.deadline)) {
                // The loop cannot even stop itself: the creator turns the board off when it
                // takes it back.
                log::error!("stopping a failed loop panicked too: {why}");
            }
            if let Some(t) = task.take() {
                let _ = back.try_send(t);
            }
            return Flow::Stop;
        }
        Flow::Continue
    }
}

/// The body of a communication thread: ticks `comm` until `stop`, then hands it back through
/// `back` (it may hold a teleoperation channel's end); a panicking tick records the cause in
/// `fault` (the control thread then stops the robot safely) and ends the thread.
pub fn comm_body(
    comm: CommTask,
    fault: Arc<LoopFault>,
    stop: Arc<AtomicBool>,
    back: SyncSender<CommTask>,
) -> impl FnMut(penelope_rt_core::exec::Tick) -> Flow + Send + 'static {
    let mut comm = Some(comm);
    move |tick| {
        let Some(c) = comm.as_mut() else {
            return Flow::Stop;
        };
        if stop.load(Ordering::Acquire) {
            if let Some(c) = comm.take() {
                let _ = back.try_send(c);
            }
            return Flow::Stop;
        }
        match guarded(|| {
            fault.injected(LoopThread::Communication);
            if tick.early {
                c.early(tick.deadline);
            } else {
                c.tick(tick.deadline);
            }
        }) {
            Ok(()) => Flow::Continue,
            Err(why) => {
                fault.record(format!("the communication thread panicked: {why}"));
                Flow::Stop
            }
        }
    }
}

/// What a stopped loop hands back: its control task (with the board) and its communication
/// task (with a teleoperation channel's end), each `None` if its thread died with it.
pub struct StoppedLoop {
    /// The control task.
    pub control: Option<ControlTask>,
    /// The communication task.
    pub comm: Option<CommTask>,
}
