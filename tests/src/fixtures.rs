//! Small stand-ins and rigs the fault-injection tests share: a constant-torque law, a
//! discarding telemetry port, a 1 rad move on a simulated chain, and a control thread that can
//! be made to hang.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, mpsc};
use std::time::{Duration, Instant};

use penelope_hal::{
    ControlInput, Controller, ControllerError, JointCommand, JointReference, JointState,
    JointVector, Reference, RobotModel, Timestamp,
};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Stamped, latest};
use penelope_rt_core::comm::CommLoop;
use penelope_rt_core::control::{
    ControlCommand, ControlConfig, ControlLoop, ControlPorts, NoCommands,
};
use penelope_rt_core::controller::JointPid;
use penelope_rt_core::safety::SafetyConfig;
use penelope_rt_core::telemetry::{TelemetrySample, TelemetrySink};
use penelope_rt_core::trajectory::Trapezoidal;
use penelope_testbed::{ChainBoard, DecoupledChain, critically_damped_gains};

/// A law that asks for the same torque on every joint, whatever the state: a loop that drives
/// its board by effort, for the watchdog and stop tests.
pub struct ConstantTorque(pub f64);

impl Controller for ConstantTorque {
    fn kind(&self) -> &'static str {
        "constant-torque"
    }
    fn activate(&mut self, _now: Timestamp, _measured: &JointState, _model: &dyn RobotModel) {}
    fn update(&mut self, _input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        Ok(JointCommand::Effort(JointVector::repeat(self.0)))
    }
}

/// A telemetry port that keeps nothing.
pub struct Discard;

impl TelemetrySink for Discard {
    fn push(&mut self, _sample: &TelemetrySample) -> bool {
        true
    }
}

/// The loop of [`one_radian_move`].
pub type MoveLoop = ControlLoop<
    ChainBoard,
    DecoupledChain,
    [JointPid; 1],
    ArcLatestReader<Stamped<Reference>>,
    Discard,
    NoCommands,
>;

/// The communication task of [`one_radian_move`]: the move, written to the loop's reference.
pub type MoveFeed = CommLoop<Trapezoidal, ArcLatestWriter<Stamped<Reference>>>;

/// Encoder counts per radian of [`one_radian_move`]'s board.
pub const MOVE_COUNTS_PER_RADIAN: f64 = 10_000.0;

/// A 1 rad move of joint 0 (1 rad/s, 2 rad/s²: 1.5 s) on a six-joint chain without gravity (with
/// its amplifiers off it coasts to rest, as a braked arm stands: what moves it is the loop
/// alone), held by a joint PID at a 1 ms period; started and activated at t = 0.
pub fn one_radian_move() -> (MoveLoop, MoveFeed) {
    let model = DecoupledChain {
        mass: JointVector::zeros(),
        ..DecoupledChain::six_joint()
    };
    let board = ChainBoard::new(model.clone(), MOVE_COUNTS_PER_RADIAN);
    let config = ControlConfig::new(
        Duration::from_millis(1),
        SafetyConfig::slave(6, model.limits),
    )
    .with_counts_per_radian(MOVE_COUNTS_PER_RADIAN);
    let (reference, reference_port) = latest::<Stamped<Reference>>();
    let ports = ControlPorts {
        reference: reference_port,
        telemetry: Discard,
        commands: NoCommands,
    };
    let pid = JointPid::new(critically_damped_gains(&model, 20.0));
    let mut ctl = ControlLoop::new(config, board, model, [pid], ports).expect("a valid loop");
    let mut goal = JointVector::zeros();
    goal[0] = 1.0;
    let trajectory = Trapezoidal::joint(goal, JointVector::repeat(1.0), JointVector::repeat(2.0))
        .expect("a valid move");
    let mut comm = CommLoop::new(trajectory, reference);
    comm.start(Timestamp::ZERO, &hold_at(JointVector::zeros()));
    ctl.tick(Timestamp::ZERO);
    ctl.apply(Timestamp::ZERO, ControlCommand::Activate);
    (ctl, comm)
}

/// A joint reference that holds `q`.
pub fn hold_at(q: JointVector) -> Reference {
    Reference::Joint(JointReference {
        position: q,
        ..JointReference::default()
    })
}

/// A control loop's thread on the real clock, as a node runs it, that a test can make hang:
/// alive, not ticking, until released. The thread owns `S` (a loop and what feeds it).
pub struct HangableThread<S> {
    hang: Arc<AtomicBool>,
    running: Arc<AtomicBool>,
    release: mpsc::Sender<()>,
    thread: std::thread::JoinHandle<S>,
    start: Instant,
}

impl<S: Send + 'static> HangableThread<S> {
    /// Starts the thread: `activate(state, clock)` once, then `tick(state, now)` every
    /// millisecond (it says whether the loop runs) until [`HangableThread::hang`].
    pub fn spawn(
        mut state: S,
        activate: impl FnOnce(&mut S, &dyn Fn() -> Timestamp) + Send + 'static,
        mut tick: impl FnMut(&mut S, Timestamp) -> bool + Send + 'static,
    ) -> Self {
        let hang = Arc::new(AtomicBool::new(false));
        let running = Arc::new(AtomicBool::new(false));
        let (release, hung) = mpsc::channel::<()>();
        let start = Instant::now();
        let thread = {
            let (hang, running) = (hang.clone(), running.clone());
            std::thread::spawn(move || {
                let now = || Timestamp::from_nanos(start.elapsed().as_nanos() as u64);
                activate(&mut state, &now);
                while !hang.load(Ordering::Acquire) {
                    running.store(tick(&mut state, now()), Ordering::Release);
                    std::thread::sleep(Duration::from_millis(1));
                }
                // Hung: alive, not ticking, until the test lets it go.
                let _ = hung.recv();
                state
            })
        };
        HangableThread {
            hang,
            running,
            release,
            thread,
            start,
        }
    }

    /// Whether the loop's last tick found it running.
    pub fn is_running(&self) -> bool {
        self.running.load(Ordering::Acquire)
    }

    /// Makes the thread hang after its current tick.
    pub fn hang(&self) {
        self.hang.store(true, Ordering::Release);
    }

    /// The thread's clock now.
    pub fn now(&self) -> Timestamp {
        Timestamp::from_nanos(self.start.elapsed().as_nanos() as u64)
    }

    /// Lets a hung thread go and returns what it owned.
    pub fn release(self) -> S {
        drop(self.release);
        self.thread.join().expect("the loop's thread ends")
    }
}
