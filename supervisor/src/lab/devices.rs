//! The lab's devices as the control loops see them: one board type and one interaction type
//! whatever the configuration chose, so a simulated board and a real one are swapped by a word.

use penelope_drivers::sim::Interaction;
use penelope_drivers::sim::board::{SimBoard, SimBoardError};
use penelope_drivers::sim::environment::Environment;
use penelope_drivers::sim::operator::VirtualOperator;
use penelope_hal::{AxisCommand, AxisState, Board, Error, ErrorKind, Frame, Pose, Timestamp, Twist, Wrench};

use super::model::LabModel;

/// What pushes on a simulated robot's tool.
#[allow(clippy::large_enum_variant)] // one per robot, built once
pub enum LabInteraction {
    /// Nothing.
    Free,
    /// The slave's environment.
    Environment(Environment),
    /// The operator's hand on the master.
    Operator(VirtualOperator),
}

impl Interaction for LabInteraction {
    fn wrench_on_tool(&mut self, now: Timestamp, tool: &Pose, twist: &Twist) -> Wrench {
        match self {
            LabInteraction::Free => Wrench::zero(Frame::Base),
            LabInteraction::Environment(e) => e.wrench_on_tool(now, tool, twist),
            LabInteraction::Operator(o) => o.wrench_on_tool(now, tool, twist),
        }
    }
}

/// Any board the lab can drive.
pub enum LabBoard {
    /// A simulated board with its plant.
    Sim(Box<SimBoard<LabModel, LabInteraction>>),
}

/// A board error, whatever the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LabBoardError {
    /// From a simulated board.
    Sim(SimBoardError),
}

impl Error for LabBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            LabBoardError::Sim(e) => e.kind(),
        }
    }
}

impl Board for LabBoard {
    type Error = LabBoardError;

    fn axis_count(&self) -> usize {
        match self {
            LabBoard::Sim(b) => b.axis_count(),
        }
    }

    fn read_axes(&mut self, now: Timestamp, out: &mut [AxisState]) -> Result<(), LabBoardError> {
        match self {
            LabBoard::Sim(b) => b.read_axes(now, out).map_err(LabBoardError::Sim),
        }
    }

    fn write_axes(&mut self, now: Timestamp, commands: &[AxisCommand]) -> Result<(), LabBoardError> {
        match self {
            LabBoard::Sim(b) => b.write_axes(now, commands).map_err(LabBoardError::Sim),
        }
    }

    fn set_enabled(&mut self, enabled: bool) -> Result<(), LabBoardError> {
        match self {
            LabBoard::Sim(b) => b.set_enabled(enabled).map_err(LabBoardError::Sim),
        }
    }
}
