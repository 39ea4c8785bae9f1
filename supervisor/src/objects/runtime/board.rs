//! The board a loop drives: a robot's simulated body (behind a simulated board or the FRHC's
//! FPGA board), or its joints on Galil boards.

use super::*;

/// The board a control loop sees: one axis per robot joint, in joint order, whatever boards
/// the joints are mapped onto.
pub enum LoopBoard {
    /// The robot's simulated body, and the offset from the loop's clock to the plant's (set at
    /// the first call, so the plant goes on from its own time whenever a loop starts; grown by
    /// stalls longer than [`MAX_PLANT_STEP_NS`]).
    Sim(Box<SimBody>, Option<u64>),
    /// The robot's simulated body behind a `board/fpga` (the FRHC): as [`LoopBoard::Sim`], but
    /// a tick's command reaches the motors
    /// [`command_delay_ns`](crate::objects::fpga_board::command_delay_ns) after its encoders
    /// were latched (the board's kinematics, force transformation and DMA transfers); the
    /// plant runs on with the previous command until then.
    Fpga(Box<SimBody>, Option<u64>),
    /// One or more Galil boards.
    Galil(Box<GalilSet>),
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

/// A [`LoopBoard`] error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopBoardError {
    /// From the simulated board.
    Sim(SimBoardError),
    /// From a Galil board.
    Galil(GalilBoardError),
    /// A slice shorter than the joint count.
    WrongLength,
}

impl Error for LoopBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            LoopBoardError::Sim(e) => e.kind(),
            LoopBoardError::Galil(e) => e.kind(),
            LoopBoardError::WrongLength => ErrorKind::InvalidInput,
        }
    }
}

impl Board for LoopBoard {
    type Error = LoopBoardError;

    fn axis_count(&self) -> usize {
        match self {
            LoopBoard::Sim(b, _) | LoopBoard::Fpga(b, _) => b.axis_count(),
            LoopBoard::Galil(g) => g.joints,
        }
    }

    /// # Real-time
    /// Simulated: steps the plant (bounded sub-steps). Galil: one wait-free cell read per board.
    fn read_axes(&mut self, now: Timestamp, out: &mut [AxisState]) -> Result<(), LoopBoardError> {
        match self {
            LoopBoard::Sim(b, offset) | LoopBoard::Fpga(b, offset) => {
                let now = plant_time(b, offset, now);
                b.read_axes(now, out).map_err(LoopBoardError::Sim)
            }
            LoopBoard::Galil(g) => {
                if out.len() < g.joints {
                    return Err(LoopBoardError::WrongLength);
                }
                for (i, (_, board)) in g.boards.iter_mut().enumerate() {
                    let count = board.axis_count().min(MAX_AXES);
                    board
                        .read_axes(now, &mut g.read[i][..count])
                        .map_err(LoopBoardError::Galil)?;
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
    ) -> Result<(), LoopBoardError> {
        match self {
            LoopBoard::Sim(b, offset) => {
                let now = plant_time(b, offset, now);
                b.write_axes(now, commands).map_err(LoopBoardError::Sim)
            }
            LoopBoard::Fpga(b, offset) => {
                let delay = crate::objects::fpga_board::command_delay_ns();
                let now = plant_time(
                    b,
                    offset,
                    Timestamp::from_nanos(now.as_nanos().saturating_add(delay)),
                );
                b.write_axes(now, commands).map_err(LoopBoardError::Sim)
            }
            LoopBoard::Galil(g) => {
                if commands.len() < g.joints {
                    return Err(LoopBoardError::WrongLength);
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
                        .map_err(LoopBoardError::Galil)?;
                }
                Ok(())
            }
        }
    }

    /// # Real-time
    /// Wait-free: a simulated board has no latch; each Galil board takes the request to its
    /// I/O thread.
    fn rearm(&mut self) -> Result<(), LoopBoardError> {
        match self {
            LoopBoard::Sim(b, _) | LoopBoard::Fpga(b, _) => b.rearm().map_err(LoopBoardError::Sim),
            LoopBoard::Galil(g) => {
                for (_, board) in g.boards.iter_mut() {
                    board.rearm().map_err(LoopBoardError::Galil)?;
                }
                Ok(())
            }
        }
    }

    fn set_enabled(&mut self, enabled: bool) -> Result<(), LoopBoardError> {
        match self {
            LoopBoard::Sim(b, _) | LoopBoard::Fpga(b, _) => {
                b.set_enabled(enabled).map_err(LoopBoardError::Sim)
            }
            LoopBoard::Galil(g) => {
                let mut result = Ok(());
                for (_, board) in g.boards.iter_mut() {
                    if let Err(e) = board.set_enabled(enabled) {
                        result = Err(LoopBoardError::Galil(e));
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
    use penelope_drivers::sim::board::SimBoardConfig as DriverSimConfig;
    use penelope_drivers::sim::plant::PlantConfig;

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
            },
            ToolContact::Environment(Environment::new()),
            JointVector::zeros(),
            Timestamp::ZERO,
        )
    }

    fn plant_ns(b: &LoopBoard) -> u64 {
        match b {
            LoopBoard::Sim(s, _) | LoopBoard::Fpga(s, _) => s.plant().snapshot().time.as_nanos(),
            LoopBoard::Galil(_) => unreachable!(),
        }
    }

    #[test]
    fn an_fpga_boards_command_reaches_the_motors_after_the_modelled_delay() {
        let delay = crate::objects::fpga_board::command_delay_ns();
        assert!(delay > 20_000 && delay < 40_000, "{delay} ns");
        let now = Timestamp::from_nanos(1_000_000);
        let push = [AxisCommand::Effort(20.0); 6];
        let mut out = [AxisState::default(); MAX_AXES];
        let mut ticked = |mut board: LoopBoard| {
            board.set_enabled(true).unwrap();
            board.read_axes(now, &mut out[..6]).unwrap();
            board.write_axes(now, &push).unwrap();
            let at_write = plant_ns(&board);
            let later = Timestamp::from_nanos(now.as_nanos() + 1_000_000);
            board.read_axes(later, &mut out[..6]).unwrap();
            let v = match &board {
                LoopBoard::Sim(s, _) | LoopBoard::Fpga(s, _) => {
                    s.plant().snapshot().joints.velocity
                }
                LoopBoard::Galil(_) => unreachable!(),
            };
            (at_write, v[0])
        };
        let (sim_write, sim_v) = ticked(LoopBoard::Sim(Box::new(body()), None));
        let (fpga_write, fpga_v) = ticked(LoopBoard::Fpga(Box::new(body()), None));
        // The plain board applies the command at once; the FPGA board holds the old one (none)
        // for the delay, so its joint has had less time to speed up.
        assert_eq!(sim_write, 0);
        assert_eq!(fpga_write, delay);
        assert!(fpga_v.abs() < sim_v.abs(), "{fpga_v} vs {sim_v}");
    }

    #[test]
    fn a_stalled_loop_finds_the_simulated_world_paused_not_fast_forwarded() {
        let mut board = LoopBoard::Sim(Box::new(body()), None);
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
