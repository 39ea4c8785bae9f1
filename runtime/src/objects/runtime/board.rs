//! The board a loop drives: a robot's simulated body (behind a simulated board or the FRHC's
//! FPGA board), or its joints on Galil boards.

use crate::objects::runtime::SimBody;
use penelope_drivers::galil::{GalilBoard, GalilBoardError};
use penelope_drivers::sim::board::SimBoardError;
use penelope_hal::{
    AxisCommand, AxisState, Board, Error, ErrorKind, MAX_AXES, MAX_JOINTS, Timestamp,
};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

/// The board a control loop sees: one axis per robot joint, in joint order, whatever boards
/// the joints are mapped onto.
pub enum JointBoard {
    /// The robot's simulated body (see [`SimDrive`] for its clock and its plant keeper).
    Sim(SimDrive),
    /// The robot's simulated body behind a `board/fpga` (the FRHC): as [`JointBoard::Sim`], but
    /// a tick's command reaches the motors
    /// [`command_delay_ns`](crate::objects::fpga_board::command_delay_ns) after its encoders
    /// were latched (the board's kinematics, force transformation and DMA transfers); the
    /// plant runs on with the previous command until then.
    Fpga(SimDrive),
    /// One or more Galil boards.
    Galil(Box<GalilSet>),
}

/// A simulated body as a loop drives it: the body, and the offset from the loop's clock to
/// the plant's (set at the first call, so the plant goes on from its own time whenever a loop
/// starts; grown by stalls longer than [`MAX_PLANT_STEP_NS`]).
///
/// On the real clock a loop's simulated world does not stop when its control thread does: a
/// plant keeper ([`SimDrive::start_keeper`]), a thread of its own, steps the plant on the
/// monotonic clock whenever the loop has not called the board for the board's command timeout,
/// so the board's command-freshness watchdog
/// ([`SimBoardError::CommandStale`]) trips as it would on hardware, and the robot ends with
/// zero torque, whether the control thread hangs, stalls or is gone. The body sits behind a
/// mutex only the keeper contends for, and only after the loop was silent that long: the
/// control thread never waits for it otherwise.
pub struct SimDrive {
    shared: Arc<SimShared>,
    keeper: Option<std::thread::JoinHandle<()>>,
}

/// Reads a [`SimDrive`]'s body from another thread ([`SimDrive::observer`]).
#[derive(Clone)]
pub struct SimObserver(std::sync::Weak<SimShared>);

impl SimObserver {
    /// Runs `f` on the body; `None` once the drive is gone.
    pub fn with_body<T>(&self, f: impl FnOnce(&SimBody) -> T) -> Option<T> {
        let shared = self.0.upgrade()?;
        let state = shared.state.lock().unwrap_or_else(PoisonError::into_inner);
        Some(f(&state.body))
    }
}

struct SimShared {
    state: Mutex<SimState>,
    /// The loop's last board call, ns since `epoch` (monotonic).
    fed_ns: AtomicU64,
    epoch: std::time::Instant,
    stop: AtomicBool,
}

struct SimState {
    body: Box<SimBody>,
    offset: Option<u64>,
}

impl SimDrive {
    /// A drive of `body`, stepped by the loop only (a simulated clock, a detached loop).
    pub fn new(body: Box<SimBody>) -> Self {
        SimDrive {
            shared: Arc::new(SimShared {
                state: Mutex::new(SimState { body, offset: None }),
                fed_ns: AtomicU64::new(0),
                epoch: std::time::Instant::now(),
                stop: AtomicBool::new(false),
            }),
            keeper: None,
        }
    }

    /// Starts the plant keeper (real clock only): while the loop does not call the board for
    /// its command timeout, a thread steps the plant on the monotonic clock (polling every
    /// fifth of the timeout, 1 to 10 ms). Does nothing without a command timeout or when
    /// already started.
    pub fn start_keeper(&mut self) {
        if self.keeper.is_some() {
            return;
        }
        let Some(timeout) = self.with_body(|b| b.command_timeout()) else {
            return;
        };
        self.feed();
        let shared = Arc::downgrade(&self.shared);
        let poll = (timeout / 5).clamp(Duration::from_millis(1), Duration::from_millis(10));
        let spawned = std::thread::Builder::new()
            .name("plant-keeper".into())
            .spawn(move || keep_plant(&shared, timeout, poll));
        match spawned {
            Ok(h) => self.keeper = Some(h),
            Err(e) => log::warn!("no plant keeper ({e}): the simulated world waits for its loop"),
        }
    }

    /// Runs `f` on the body (the keeper waits meanwhile).
    pub fn with_body<T>(&self, f: impl FnOnce(&mut SimBody) -> T) -> T {
        let mut state = self
            .shared
            .state
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        f(&mut state.body)
    }

    /// A handle that reads the body from another thread while the loop runs (a test's, a
    /// monitor's); it does not keep the body alive.
    pub fn observer(&self) -> SimObserver {
        SimObserver(Arc::downgrade(&self.shared))
    }

    /// Stops the keeper and gives the body back.
    pub fn into_body(mut self) -> Box<SimBody> {
        self.stop_keeper();
        let mut shared = self.shared;
        loop {
            // The keeper holds the body only through a weak reference, upgraded for one step at
            // a time: once it is joined, this is the only owner.
            match Arc::try_unwrap(shared) {
                Ok(s) => {
                    return s
                        .state
                        .into_inner()
                        .unwrap_or_else(PoisonError::into_inner)
                        .body;
                }
                Err(back) => {
                    shared = back;
                    std::thread::yield_now();
                }
            }
        }
    }

    fn stop_keeper(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        if let Some(h) = self.keeper.take() {
            h.thread().unpark();
            let _ = h.join();
        }
    }

    fn feed(&self) {
        let ns = self.shared.epoch.elapsed().as_nanos() as u64;
        self.shared.fed_ns.store(ns, Ordering::Release);
    }

    /// Runs `f` with the body and the loop's `now` turned into plant time (`delay_ns` later).
    ///
    /// # Real-time
    /// The mutex is uncontended unless the loop was silent for the command timeout.
    fn call<T>(
        &mut self,
        now: Timestamp,
        delay_ns: u64,
        f: impl FnOnce(&mut SimBody, Timestamp) -> T,
    ) -> T {
        let out = {
            let mut state = self
                .shared
                .state
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            let SimState { body, offset } = &mut *state;
            let now = plant_time(
                body,
                offset,
                Timestamp::from_nanos(now.as_nanos().saturating_add(delay_ns)),
            );
            f(body, now)
        };
        if self.keeper.is_some() {
            self.feed();
        }
        out
    }
}

/// The longest stretch of simulated time the plant keeper integrates at once, ns.
const KEEPER_MAX_STEP_NS: u64 = 1_000_000_000;

/// The plant keeper's body: steps the plant by the wall time that passed while the loop was
/// silent for `timeout` or longer, and makes the loop re-anchor its clock to the plant's when
/// it comes back.
fn keep_plant(shared: &std::sync::Weak<SimShared>, timeout: Duration, poll: Duration) {
    let mut stepped_ns: Option<u64> = None;
    loop {
        std::thread::park_timeout(poll);
        // The drive is gone (dropped with its loop), or asked the keeper to stop.
        let Some(shared) = shared.upgrade() else {
            return;
        };
        if shared.stop.load(Ordering::Acquire) {
            return;
        }
        let now_ns = shared.epoch.elapsed().as_nanos() as u64;
        let fed = shared.fed_ns.load(Ordering::Acquire);
        if now_ns.saturating_sub(fed) < timeout.as_nanos() as u64 {
            stepped_ns = None;
            continue;
        }
        let from = stepped_ns.map_or(fed, |s| s.max(fed));
        // The whole silence at once (a thread of no priority, unlike the loop's catch-up
        // capped at MAX_PLANT_STEP_NS): the watchdog trips at the first step, not five later.
        let step = now_ns.saturating_sub(from).min(KEEPER_MAX_STEP_NS);
        let mut state = shared.state.lock().unwrap_or_else(PoisonError::into_inner);
        let plant_now = state.body.plant().snapshot().time;
        state.body.step_to(Timestamp::from_nanos(
            plant_now.as_nanos().saturating_add(step),
        ));
        // The loop's clock no longer matches the plant's: anchor it again at its next call.
        state.offset = None;
        stepped_ns = Some(now_ns);
    }
}

/// Joints spread over Galil boards: joint `j` is axis `map[j].1` of board `map[j].0`.
pub struct GalilSet {
    /// The boards, with their object names (given back when the loop stops).
    pub boards: Vec<(String, GalilBoard)>,
    map: [(u8, u8); MAX_JOINTS],
    joints: usize,
    read: Vec<[AxisState; MAX_AXES]>,
    write: Vec<[AxisCommand; MAX_AXES]>,
}

impl GalilSet {
    /// Joint `j` on board `map[j].0`, axis `map[j].1`, for `joints` joints.
    pub fn new(
        boards: Vec<(String, GalilBoard)>,
        map: [(u8, u8); MAX_JOINTS],
        joints: usize,
    ) -> Self {
        let n = boards.len();
        GalilSet {
            boards,
            map,
            joints: joints.min(MAX_JOINTS),
            read: vec![[AxisState::default(); MAX_AXES]; n],
            write: vec![[AxisCommand::Off; MAX_AXES]; n],
        }
    }
}

/// The longest stretch of simulated time a plant integrates in one board call, ns. A loop that
/// stalls longer (a VM pause, a debug build) finds the simulated world paused for the rest of the
/// stall instead of integrating all of it in its next tick: otherwise the catch-up costs time in
/// proportion to the stall, makes the next tick later still, and the loop never recovers.
pub const MAX_PLANT_STEP_NS: u64 = 10_000_000;

/// The plant's time for the loop's `now` (at most [`MAX_PLANT_STEP_NS`] past the plant's own).
fn plant_time(body: &SimBody, offset: &mut Option<u64>, now: Timestamp) -> Timestamp {
    let plant_now = body.plant().snapshot().time.as_nanos();
    let off = offset.get_or_insert_with(|| now.as_nanos().saturating_sub(plant_now));
    let target = now.as_nanos().saturating_sub(*off);
    let limit = plant_now.saturating_add(MAX_PLANT_STEP_NS);
    if target > limit {
        *off = off.saturating_add(target - limit);
        return Timestamp::from_nanos(limit);
    }
    Timestamp::from_nanos(target)
}

/// A [`JointBoard`] error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointBoardError {
    /// From the simulated board.
    Sim(SimBoardError),
    /// From a Galil board.
    Galil(GalilBoardError),
    /// A slice shorter than the joint count.
    WrongLength,
}

impl Error for JointBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            JointBoardError::Sim(e) => e.kind(),
            JointBoardError::Galil(e) => e.kind(),
            JointBoardError::WrongLength => ErrorKind::InvalidInput,
        }
    }
}

impl Board for JointBoard {
    type Error = JointBoardError;

    fn axis_count(&self) -> usize {
        match self {
            JointBoard::Sim(d) | JointBoard::Fpga(d) => d.with_body(|b| b.axis_count()),
            JointBoard::Galil(g) => g.joints,
        }
    }

    /// # Real-time
    /// Simulated: steps the plant (bounded sub-steps). Galil: one wait-free cell read per board.
    fn read_axes(&mut self, now: Timestamp, out: &mut [AxisState]) -> Result<(), JointBoardError> {
        match self {
            JointBoard::Sim(d) | JointBoard::Fpga(d) => d
                .call(now, 0, |b, now| b.read_axes(now, out))
                .map_err(JointBoardError::Sim),
            JointBoard::Galil(g) => {
                if out.len() < g.joints {
                    return Err(JointBoardError::WrongLength);
                }
                for (i, (_, board)) in g.boards.iter_mut().enumerate() {
                    let count = board.axis_count().min(MAX_AXES);
                    board
                        .read_axes(now, &mut g.read[i][..count])
                        .map_err(JointBoardError::Galil)?;
                }
                for (j, o) in out.iter_mut().enumerate().take(g.joints) {
                    let (b, a) = g.map[j];
                    *o = g.read[usize::from(b)][usize::from(a)];
                }
                Ok(())
            }
        }
    }

    /// # Real-time
    /// As [`read_axes`](Self::read_axes).
    fn write_axes(
        &mut self,
        now: Timestamp,
        commands: &[AxisCommand],
    ) -> Result<(), JointBoardError> {
        match self {
            JointBoard::Sim(d) => d
                .call(now, 0, |b, now| b.write_axes(now, commands))
                .map_err(JointBoardError::Sim),
            JointBoard::Fpga(d) => {
                let delay = crate::objects::fpga_board::command_delay_ns();
                d.call(now, delay, |b, now| b.write_axes(now, commands))
                    .map_err(JointBoardError::Sim)
            }
            JointBoard::Galil(g) => {
                if commands.len() < g.joints {
                    return Err(JointBoardError::WrongLength);
                }
                for w in g.write.iter_mut() {
                    *w = [AxisCommand::Off; MAX_AXES];
                }
                for (j, c) in commands.iter().enumerate().take(g.joints) {
                    let (b, a) = g.map[j];
                    g.write[usize::from(b)][usize::from(a)] = *c;
                }
                for (i, (_, board)) in g.boards.iter_mut().enumerate() {
                    let count = board.axis_count().min(MAX_AXES);
                    board
                        .write_axes(now, &g.write[i][..count])
                        .map_err(JointBoardError::Galil)?;
                }
                Ok(())
            }
        }
    }

    /// # Real-time
    /// Wait-free: a simulated board clears its command watchdog; each Galil board takes the
    /// request to its I/O thread.
    fn rearm(&mut self) -> Result<(), JointBoardError> {
        match self {
            JointBoard::Sim(d) | JointBoard::Fpga(d) => {
                d.with_body(|b| b.rearm()).map_err(JointBoardError::Sim)
            }
            JointBoard::Galil(g) => {
                for (_, board) in g.boards.iter_mut() {
                    board.rearm().map_err(JointBoardError::Galil)?;
                }
                Ok(())
            }
        }
    }

    fn set_enabled(&mut self, enabled: bool) -> Result<(), JointBoardError> {
        match self {
            JointBoard::Sim(d) | JointBoard::Fpga(d) => d
                .with_body(|b| b.set_enabled(enabled))
                .map_err(JointBoardError::Sim),
            JointBoard::Galil(g) => {
                let mut result = Ok(());
                for (_, board) in g.boards.iter_mut() {
                    if let Err(e) = board.set_enabled(enabled) {
                        result = Err(JointBoardError::Galil(e));
                    }
                }
                result
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_drivers::model::puma560;
    use penelope_drivers::sim::ToolContact;
    use penelope_drivers::sim::board::SimBoardConfig as DriverSimConfig;
    use penelope_drivers::sim::environment::Environment;
    use penelope_drivers::sim::plant::PlantConfig;
    use penelope_hal::JointVector;

    fn body() -> SimBody {
        let model = puma560();
        SimBody::new(
            model.clone(),
            PlantConfig::default(),
            DriverSimConfig {
                counts_per_radian: JointVector::repeat(1000.0),
                effort_full_scale: JointVector::repeat(100.0),
                dac_bits: 16,
                position_kp: JointVector::repeat(100.0),
                position_kd: JointVector::repeat(1.0),
                velocity_cutoff_hz: 0.0,
                command_timeout: None,
                brake: false,
            },
            ToolContact::Environment(Environment::new()),
            JointVector::zeros(),
            Timestamp::ZERO,
        )
    }

    fn plant_ns(b: &JointBoard) -> u64 {
        match b {
            JointBoard::Sim(d) | JointBoard::Fpga(d) => {
                d.with_body(|s| s.plant().snapshot().time.as_nanos())
            }
            JointBoard::Galil(_) => unreachable!(),
        }
    }

    #[test]
    fn an_fpga_boards_command_reaches_the_motors_after_the_modelled_delay() {
        let delay = crate::objects::fpga_board::command_delay_ns();
        assert!(delay > 20_000 && delay < 40_000, "{delay} ns");
        let now = Timestamp::from_nanos(1_000_000);
        let push = [AxisCommand::Effort(20.0); 6];
        let mut out = [AxisState::default(); MAX_AXES];
        let mut ticked = |mut board: JointBoard| {
            board.set_enabled(true).unwrap();
            board.read_axes(now, &mut out[..6]).unwrap();
            board.write_axes(now, &push).unwrap();
            let at_write = plant_ns(&board);
            let later = Timestamp::from_nanos(now.as_nanos() + 1_000_000);
            board.read_axes(later, &mut out[..6]).unwrap();
            let v = match &board {
                JointBoard::Sim(d) | JointBoard::Fpga(d) => {
                    d.with_body(|s| s.plant().snapshot().joints.velocity)
                }
                JointBoard::Galil(_) => unreachable!(),
            };
            (at_write, v[0])
        };
        let (sim_write, sim_v) = ticked(JointBoard::Sim(SimDrive::new(Box::new(body()))));
        let (fpga_write, fpga_v) = ticked(JointBoard::Fpga(SimDrive::new(Box::new(body()))));
        // The plain board applies the command at once; the FPGA board holds the old one (none)
        // for the delay, so its joint has had less time to speed up.
        assert_eq!(sim_write, 0);
        assert_eq!(fpga_write, delay);
        assert!(fpga_v.abs() < sim_v.abs(), "{fpga_v} vs {sim_v}");
    }

    #[test]
    fn a_stalled_loop_finds_the_simulated_world_paused_not_fast_forwarded() {
        let mut board = JointBoard::Sim(SimDrive::new(Box::new(body())));
        let mut out = [AxisState::default(); MAX_AXES];
        let start = 5_000_000_000_u64;
        board
            .read_axes(Timestamp::from_nanos(start), &mut out[..6])
            .unwrap();
        // The first call anchors the loop's clock to the plant's.
        assert_eq!(plant_ns(&board), 0);
        // A 1 ms tick advances the plant by 1 ms.
        board
            .read_axes(Timestamp::from_nanos(start + 1_000_000), &mut out[..6])
            .unwrap();
        assert_eq!(plant_ns(&board), 1_000_000);
        // A 2 s stall advances it by at most MAX_PLANT_STEP_NS...
        board
            .read_axes(Timestamp::from_nanos(start + 2_001_000_000), &mut out[..6])
            .unwrap();
        assert_eq!(plant_ns(&board), 1_000_000 + MAX_PLANT_STEP_NS);
        // ...and the ticks after it advance it by their period again.
        board
            .read_axes(Timestamp::from_nanos(start + 2_002_000_000), &mut out[..6])
            .unwrap();
        assert_eq!(plant_ns(&board), 2_000_000 + MAX_PLANT_STEP_NS);
    }
}
