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
//!
//! Determinism: nothing here reads a clock or an unseeded random source; every call takes the
//! time, and noise comes from a seeded generator.

pub mod board;
pub mod environment;
pub mod force_sensor;
pub mod operator;
pub mod plant;
pub mod tap;

use penelope_hal::{Pose, Twist, Wrench};

use penelope_hal::Timestamp;

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
}

/// No interaction: free motion.
#[derive(Clone, Copy, Debug, Default)]
pub struct FreeSpace;

impl Interaction for FreeSpace {
    fn wrench_on_tool(&mut self, _now: Timestamp, _tool: &Pose, _twist: &Twist) -> Wrench {
        Wrench::zero(penelope_hal::Frame::Base)
    }
}
