//! The simulated lab: real models, seeded and deterministic, behind the same traits as hardware.
//!
//! - [`plant`]: a rigid-body plant that integrates a robot model's dynamics with friction and
//!   motor torque limits.
//! - [`board`]: a simulated motion board in front of a plant: encoder quantisation, DAC
//!   saturation and resolution, sample-and-hold of commands, an optional on-board position loop.
//! - [`environment`]: what the slave touches (a stiff wall or plane, a sphere), as spring-dampers.
//! - [`operator`]: a virtual operator whose hand (an impedance) holds the master and follows a
//!   script of motions (reach, sine sweeps, pushes, taps); it feels the force the master displays.
//! - [`force_sensor`]: a wrist force/torque sensor reading the plant's contact wrench in its own
//!   frame, with bias, noise and a low-pass filter.
//! - [`tap`]: the lock-free hand-off of the plant's interaction wrench to the sensor and the
//!   telemetry.
//! - [`scripts`]: the operator's built-in scripts (the demo's), by name.
//! - [`recorded_hand`]: the operator's hand played back from a recording (the master's recorded
//!   motion imposed on its plant).
//! - [`ToolContact`]: what touches a robot's tool, whatever the robot: nothing, the environment,
//!   or the operator's hand.
//!
//! Determinism: nothing here reads a clock or an unseeded random source; every call takes the
//! time, and noise comes from a seeded generator.

pub mod board;
pub mod camera;
pub mod environment;
pub mod force_sensor;
pub mod operator;
pub mod plant;
pub mod recorded_hand;
pub mod scripts;
pub mod tap;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use penelope_hal::{Frame, Pose, Timestamp, Twist, Wrench};

use environment::Environment;
use operator::VirtualOperator;
use recorded_hand::{ImposedState, RecordedHand};

/// Something that pushes on a robot's tool: the environment the slave touches, or the hand that
/// holds the master.
///
/// # Real-time
/// Called by the plant at every integration sub-step, inside the control thread: implementations
/// must not allocate, lock or block.
pub trait Interaction: Send {
    /// The wrench applied *to* the robot at its tool origin, in the robot's base frame (N, N·m),
    /// given the tool's pose and twist in the base frame at time `now`.
    fn wrench_on_tool(&mut self, now: Timestamp, tool: &Pose, twist: &Twist) -> Wrench;

    /// The state the tool's surroundings force the plant into at `now`, read by the board after
    /// it has integrated up to `now`: `None` (the default) for anything that only pushes; a
    /// recorded hand ([`RecordedHand`]) moves the handle as recorded.
    fn imposed_state(&mut self, _now: Timestamp) -> Option<ImposedState> {
        None
    }
}

/// No interaction: free motion.
#[derive(Clone, Copy, Debug, Default)]
pub struct FreeSpace;

impl Interaction for FreeSpace {
    fn wrench_on_tool(&mut self, _now: Timestamp, _tool: &Pose, _twist: &Twist) -> Wrench {
        Wrench::zero(penelope_hal::Frame::Base)
    }
}

/// What touches a simulated robot's tool: nothing, the environment (the slave's wall), or the
/// operator's hand holding the handle (the master), one type for any robot.
// One per simulated robot, built once: the size difference costs nothing worth a box.
#[allow(clippy::large_enum_variant)]
pub enum ToolContact {
    /// Free motion.
    Free,
    /// The environment's contact models.
    Environment(Environment),
    /// The operator's hand; its clutch button's state is published to `clutch` at every
    /// sub-step (as a handle's switch would be read), lock-free.
    Hand {
        /// The hand.
        operator: VirtualOperator,
        /// Whether the clutch is held, for whoever sends the master's pose.
        clutch: Arc<AtomicBool>,
    },
    /// The operator's hand played back from a recording: the handle moves, and the clutch is
    /// held, as recorded.
    Recorded(RecordedHand),
}

impl Interaction for ToolContact {
    /// # Real-time
    /// As the variant's own model; the clutch is one atomic store.
    fn wrench_on_tool(&mut self, now: Timestamp, tool: &Pose, twist: &Twist) -> Wrench {
        match self {
            ToolContact::Free => Wrench::zero(Frame::Base),
            ToolContact::Environment(e) => e.wrench_on_tool(now, tool, twist),
            ToolContact::Hand { operator, clutch } => {
                clutch.store(operator.clutch(now), Ordering::Relaxed);
                operator.wrench_on_tool(now, tool, twist)
            }
            ToolContact::Recorded(hand) => hand.wrench_on_tool(now, tool, twist),
        }
    }

    fn imposed_state(&mut self, now: Timestamp) -> Option<ImposedState> {
        match self {
            ToolContact::Recorded(hand) => hand.imposed_state(now),
            _ => None,
        }
    }
}
