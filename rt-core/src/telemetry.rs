//! What the control thread reports every tick: one fixed-size, `Copy` [`TelemetrySample`] pushed
//! into an SPSC ring for the non-real-time side (plots, logs, the supervisor).

use core::ops::Deref;
use core::time::Duration;

use nalgebra::Vector3;
use penelope_hal::{Frame, JointVector, Reference, Timestamp, Wrench};

use crate::ring::{Producer, Ring};
use crate::safety::{EventSet, FaultCause, SafetyState};

/// Which kind of reference the controller followed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ReferenceKind {
    /// No reference received yet.
    #[default]
    None,
    /// [`Reference::Joint`].
    Joint,
    /// [`Reference::Cartesian`].
    Cartesian,
    /// [`Reference::Wrench`].
    Wrench,
    /// [`Reference::Hybrid`].
    Hybrid,
}

impl ReferenceKind {
    /// The kind of `r`.
    pub fn of(r: &Reference) -> Self {
        match r {
            Reference::Joint(_) => ReferenceKind::Joint,
            Reference::Cartesian(_) => ReferenceKind::Cartesian,
            Reference::Wrench(_) => ReferenceKind::Wrench,
            Reference::Hybrid(_) => ReferenceKind::Hybrid,
        }
    }
}

/// One control tick, as the non-real-time side sees it. Units: seconds-based SI (rad, rad/s,
/// N·m, m, N).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TelemetrySample {
    /// The tick's time (its scheduled instant).
    pub time: Timestamp,
    /// Tick counter of the control loop (1 for the first tick).
    pub seq: u64,
    /// Measured joint positions, rad.
    pub q: JointVector,
    /// Measured joint velocities, rad/s.
    pub qd: JointVector,
    /// Joint efforts commanded this tick, N·m (zero when the amplifiers are off or the board
    /// servos a position).
    pub effort: JointVector,
    /// Joint positions commanded to the board's servo this tick, rad (holds; zero otherwise).
    pub position_command: JointVector,
    /// Which kind of reference was in force.
    pub reference_kind: ReferenceKind,
    /// The joint reference's positions, rad (for joint references; zero otherwise).
    pub reference_q: JointVector,
    /// The reference's tool position in the base frame, m (Cartesian and hybrid references;
    /// zero otherwise).
    pub reference_position: Vector3<f64>,
    /// Age of the reference at this tick (`time - stamp`); `Duration::MAX` when none arrived.
    pub reference_age: Duration,
    /// The measured wrench from the force sensor (zero without one): the contact force on a slave.
    pub wrench: Wrench,
    /// The commanded (displayed) wrench: a master's reference wrench after the force limits
    /// (zero when the reference carries none).
    pub commanded_wrench: Wrench,
    /// Tool position from forward kinematics of the measured `q`, m (zero if disabled).
    pub tool_position: Vector3<f64>,
    /// Index of the active controller.
    pub controller: u8,
    /// Safety state after this tick.
    pub state: SafetyState,
    /// Events of this tick.
    pub events: EventSet,
    /// The latched fault's cause, if faulted.
    pub fault: Option<FaultCause>,
    /// Wake-up latency of the previous tick, as reported by the executor (zero in simulation).
    pub wake_latency: Duration,
    /// Execution time of the previous tick, as reported by the executor (zero in simulation).
    pub exec_time: Duration,
    /// The active law's passivity observer energy after this tick, J
    /// ([`Controller::port_energy`](penelope_hal::Controller::port_energy)): negative when the
    /// law has given out more energy than it received. `None` for laws without an observer.
    #[cfg_attr(feature = "serde", serde(default))]
    pub port_energy: Option<f64>,
    /// The teleoperation two-port's energy at this side's port after this tick, J: what the
    /// other side has put in minus what this side has taken out (time-domain passivity's
    /// delayed observer, run by the communication thread that feeds the loop; see
    /// [`TwoPortObserver`](crate::teleop::TwoPortObserver)). Negative: the channel with its
    /// delays has given out energy that never entered it. `None` for laws without one.
    #[cfg_attr(feature = "serde", serde(default))]
    pub channel_energy: Option<f64>,
}

impl Default for TelemetrySample {
    fn default() -> Self {
        TelemetrySample {
            time: Timestamp::ZERO,
            seq: 0,
            q: JointVector::zeros(),
            qd: JointVector::zeros(),
            effort: JointVector::zeros(),
            position_command: JointVector::zeros(),
            reference_kind: ReferenceKind::None,
            reference_q: JointVector::zeros(),
            reference_position: Vector3::zeros(),
            reference_age: Duration::MAX,
            wrench: Wrench::zero(Frame::Base),
            commanded_wrench: Wrench::zero(Frame::Base),
            tool_position: Vector3::zeros(),
            controller: 0,
            state: SafetyState::Inactive,
            events: EventSet::EMPTY,
            fault: None,
            wake_latency: Duration::ZERO,
            exec_time: Duration::ZERO,
            port_energy: None,
            channel_energy: None,
        }
    }
}

/// Where the control loop puts its samples.
pub trait TelemetrySink {
    /// Offers one sample; `false` when it was dropped (sink full).
    ///
    /// # Real-time
    /// Implementations must be wait-free and allocation-free.
    fn push(&mut self, sample: &TelemetrySample) -> bool;
}

impl<const N: usize, P: Deref<Target = Ring<TelemetrySample, N>>> TelemetrySink
    for Producer<TelemetrySample, N, P>
{
    fn push(&mut self, sample: &TelemetrySample) -> bool {
        Producer::push(self, *sample).is_ok()
    }
}

/// A sink that discards every sample (for loops whose telemetry nobody reads).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoTelemetry;

impl TelemetrySink for NoTelemetry {
    fn push(&mut self, _sample: &TelemetrySample) -> bool {
        true
    }
}
