//! Safety, always on in the control loop: the reference-freshness watchdog, joint limits, master
//! force limits, NaN/inf rejection and the e-stop latch.
//!
//! [`Safety`] is a small state machine the control loop consults every tick:
//!
//! ```text
//!            activate                  reference older than `watchdog`
//! Inactive ----------> Running <------------------------------------> Holding
//!    ^                    |     fresh reference again (controller re-activated)  |
//!    | rearm              | limit, NaN, controller or board error                | stale for
//!    |                    v                                                      | `stale_to_fault`
//! Fault / EStop <---------+------------------------------------------------------+
//!         (e-stop from any state; both latch until an explicit `rearm`, then `activate`)
//! ```
//!
//! A reset never starts motion (IEC 60204-1): after a re-arm the machine holds where it is
//! activated, fresh references or not, until the loop reports a reference that starts where the
//! robot is ([`Safety::motion_reanchored`]): the producer restarted from the measured state.
//!
//! What each state commands ([`Action`]):
//!
//! | state | slave | master |
//! |---|---|---|
//! | `Inactive`, `EStop` | amplifiers off | amplifiers off |
//! | `Running` | the controller's command, clamped to the limits | same, reference wrench capped at the force limits |
//! | `Holding` | hold the position measured when the reference went stale | zero force |
//! | `Fault` | [`FaultAction`] (default: hold position) | [`FaultAction`] (default: amplifiers off) |

mod config;
mod events;

use core::fmt;

use penelope_hal::controller::ControllerError;
use penelope_hal::{
    ErrorKind, JointCommand, JointSet, JointState, JointVector, MAX_JOINTS, Reference, Timestamp,
    Wrench,
};

pub use config::{FaultAction, HoldMode, SafetyConfig, SafetyConfigError, TeleopRole};
pub use events::{EventSet, SafetyEvent};

/// Where the safety machine is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum SafetyState {
    /// Not activated: amplifiers off.
    #[default]
    Inactive,
    /// Following the reference.
    Running,
    /// The reference is stale: a slave holds position, a master applies zero force.
    Holding,
    /// Stopped by a fault; needs [`Safety::rearm`].
    Fault,
    /// Emergency stop latched; needs [`Safety::rearm`].
    EStop,
}

impl SafetyState {
    /// The lower-case name shown to users.
    pub const fn as_str(self) -> &'static str {
        match self {
            SafetyState::Inactive => "inactive",
            SafetyState::Running => "running",
            SafetyState::Holding => "holding",
            SafetyState::Fault => "fault",
            SafetyState::EStop => "estop",
        }
    }
}

impl fmt::Display for SafetyState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Why the robot faulted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum FaultCause {
    /// The reference stayed stale past the watchdog and `stale_to_fault`.
    ReferenceTimeout,
    /// A measured joint position left its range.
    PositionLimit {
        /// The joint (0-based).
        joint: u8,
    },
    /// A measured joint speed exceeded its limit.
    VelocityLimit {
        /// The joint (0-based).
        joint: u8,
    },
    /// The measured state held NaN or infinity.
    NonFiniteState,
    /// The controller's command held NaN or infinity.
    NonFiniteCommand,
    /// The controller could not compute a command.
    Controller(ControllerError),
    /// Reading the board failed (repeatedly).
    BoardRead(ErrorKind),
    /// Writing the board failed.
    BoardWrite(ErrorKind),
}

impl fmt::Display for FaultCause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FaultCause::ReferenceTimeout => f.write_str("reference timed out"),
            FaultCause::PositionLimit { joint } => write!(f, "joint {joint} position limit"),
            FaultCause::VelocityLimit { joint } => write!(f, "joint {joint} velocity limit"),
            FaultCause::NonFiniteState => f.write_str("measured state is NaN or infinite"),
            FaultCause::NonFiniteCommand => f.write_str("command is NaN or infinite"),
            FaultCause::Controller(e) => write!(f, "controller: {e}"),
            FaultCause::BoardRead(k) => write!(f, "board read: {k}"),
            FaultCause::BoardWrite(k) => write!(f, "board write: {k}"),
        }
    }
}

/// What the joints are told to do this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Amplifiers off.
    Off,
    /// Run the active controller.
    Run,
    /// Hold these joint positions, rad (see [`HoldMode`]).
    Hold(JointVector),
    /// Zero effort on every joint, amplifiers on (a master's safe state).
    ZeroForce,
}

/// Why [`Safety::activate`] refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ActivateError {
    /// The e-stop is latched: re-arm first.
    EStopLatched,
    /// A fault is latched: re-arm first.
    Faulted,
    /// The measured state is NaN or infinite.
    NonFiniteState,
}

impl fmt::Display for ActivateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ActivateError::EStopLatched => "e-stop latched: re-arm first",
            ActivateError::Faulted => "fault latched: re-arm first",
            ActivateError::NonFiniteState => "measured state is NaN or infinite",
        })
    }
}

/// [`Safety::rearm`] found nothing latched.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NothingLatched;

impl fmt::Display for NothingLatched {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("nothing to re-arm: no fault or e-stop is latched")
    }
}

/// The safety state machine of one robot. See the [module docs](self).
///
/// # Real-time
/// Every method is constant-time, allocation-free and never panics.
#[derive(Clone, Debug)]
pub struct Safety {
    config: SafetyConfig,
    state: SafetyState,
    cause: Option<FaultCause>,
    activated_at: Timestamp,
    /// The last finite measured position: where holds and fault holds start.
    last_good: JointVector,
    hold_at: JointVector,
    events: EventSet,
    /// Set by a re-arm: hold, whatever the references, until one starts where the robot is.
    awaiting_new_motion: bool,
}

impl Safety {
    /// A machine in [`SafetyState::Inactive`].
    ///
    /// # Errors
    /// [`SafetyConfigError`] from [`SafetyConfig::validate`].
    pub fn new(config: SafetyConfig) -> Result<Self, SafetyConfigError> {
        config.validate()?;
        Ok(Safety {
            config,
            state: SafetyState::Inactive,
            cause: None,
            activated_at: Timestamp::ZERO,
            last_good: JointVector::zeros(),
            hold_at: JointVector::zeros(),
            events: EventSet::EMPTY,
            awaiting_new_motion: false,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &SafetyConfig {
        &self.config
    }

    /// The current state.
    pub fn state(&self) -> SafetyState {
        self.state
    }

    /// The cause of the latched fault, if any.
    pub fn fault_cause(&self) -> Option<FaultCause> {
        self.cause
    }

    /// The events noted since the last call, clearing them.
    pub fn take_events(&mut self) -> EventSet {
        core::mem::take(&mut self.events)
    }

    /// The events noted since the last [`take_events`](Safety::take_events).
    pub fn events(&self) -> EventSet {
        self.events
    }

    /// Notes an event observed elsewhere (board, sensor, telemetry).
    pub fn note(&mut self, event: SafetyEvent) {
        self.events.insert(event);
    }

    /// Notes every event of `events`, observed elsewhere (a communication thread's link).
    pub fn note_all(&mut self, events: EventSet) {
        self.events = self.events.union(events);
    }

    /// Starts running from the measured state (holding until a fresh reference arrives).
    ///
    /// # Errors
    /// [`ActivateError`] while a fault or e-stop is latched, or for a non-finite state.
    pub fn activate(&mut self, now: Timestamp, measured: &JointState) -> Result<(), ActivateError> {
        match self.state {
            SafetyState::EStop => return Err(ActivateError::EStopLatched),
            SafetyState::Fault => return Err(ActivateError::Faulted),
            _ => {}
        }
        if !measured.is_finite() {
            return Err(ActivateError::NonFiniteState);
        }
        self.last_good = measured.position;
        self.hold_at = measured.position;
        self.activated_at = now;
        if self.state == SafetyState::Inactive {
            self.events.insert(SafetyEvent::Activated);
        }
        // Until a fresh reference is seen, hold (slave) or apply zero force (master).
        self.state = SafetyState::Holding;
        Ok(())
    }

    /// Stops running (amplifiers off). A latched fault or e-stop stays latched.
    pub fn deactivate(&mut self) {
        if matches!(self.state, SafetyState::Running | SafetyState::Holding) {
            self.state = SafetyState::Inactive;
            self.events.insert(SafetyEvent::Deactivated);
        }
    }

    /// Latches the e-stop (amplifiers off) from any state.
    pub fn estop(&mut self) {
        if self.state != SafetyState::EStop {
            self.state = SafetyState::EStop;
            self.events.insert(SafetyEvent::EStopped);
        }
    }

    /// Latches a fault (the first cause is kept). An e-stop takes precedence; an inactive robot
    /// faults too, so a broken board is reported before activation.
    pub fn fault(&mut self, cause: FaultCause) {
        match self.state {
            SafetyState::EStop | SafetyState::Fault => {}
            _ => {
                self.state = SafetyState::Fault;
                self.cause = Some(cause);
                self.hold_at = self.last_good;
                self.events.insert(SafetyEvent::Faulted);
            }
        }
    }

    /// Clears a latched fault or e-stop: the robot becomes [`SafetyState::Inactive`] and must be
    /// activated again.
    ///
    /// # Errors
    /// [`NothingLatched`] when there was no fault or e-stop.
    pub fn rearm(&mut self) -> Result<(), NothingLatched> {
        match self.state {
            SafetyState::Fault | SafetyState::EStop => {
                self.state = SafetyState::Inactive;
                self.cause = None;
                self.awaiting_new_motion = true;
                self.events.insert(SafetyEvent::Rearmed);
                Ok(())
            }
            _ => Err(NothingLatched),
        }
    }

    /// True after a re-arm until [`motion_reanchored`](Safety::motion_reanchored): the robot
    /// holds (slave) or displays zero force (master) even with fresh references, since the
    /// motion they belong to was interrupted.
    pub fn awaiting_new_motion(&self) -> bool {
        self.awaiting_new_motion
    }

    /// Where the robot is held (in [`SafetyState::Holding`], or faulted with
    /// [`FaultAction::Hold`]), rad.
    pub fn hold_position(&self) -> JointVector {
        self.hold_at
    }

    /// The loop found a fresh reference that starts where the robot is (its producer restarted
    /// from the measured state, or a new motion began there): references are followed again.
    pub fn motion_reanchored(&mut self) {
        self.awaiting_new_motion = false;
    }

    /// Checks the measured state and the reference's age, moves the machine, and says what the
    /// joints should do. `reference_stamp` is the production time of the newest finite reference,
    /// if any arrived.
    pub fn supervise(
        &mut self,
        now: Timestamp,
        measured: &JointState,
        reference_stamp: Option<Timestamp>,
    ) -> Action {
        if matches!(self.state, SafetyState::Running | SafetyState::Holding) {
            self.check_measured(measured);
        }
        if matches!(self.state, SafetyState::Running | SafetyState::Holding) {
            self.check_freshness(now, measured, reference_stamp);
        }
        self.action()
    }

    /// What the current state commands, without checking anything.
    pub fn action(&self) -> Action {
        match self.state {
            SafetyState::Inactive | SafetyState::EStop => Action::Off,
            SafetyState::Running => Action::Run,
            SafetyState::Holding => match self.config.role {
                TeleopRole::Slave => Action::Hold(self.hold_at),
                TeleopRole::Master => Action::ZeroForce,
            },
            SafetyState::Fault => match self.config.fault_action {
                FaultAction::Hold => Action::Hold(self.hold_at),
                FaultAction::Off => Action::Off,
            },
        }
    }

    fn check_measured(&mut self, measured: &JointState) {
        let n = self.config.joint_count;
        let finite = (0..n).all(|j| {
            measured.position[j].is_finite()
                && measured.velocity[j].is_finite()
                && measured.effort[j].is_finite()
        });
        if !finite {
            self.fault(FaultCause::NonFiniteState);
            return;
        }
        let l = &self.config.limits;
        for j in 0..n {
            let q = measured.position[j];
            if !(q >= l.position_min[j] && q <= l.position_max[j]) {
                self.fault(FaultCause::PositionLimit { joint: j as u8 });
                return;
            }
            if measured.velocity[j].abs() > l.velocity_max[j] {
                self.fault(FaultCause::VelocityLimit { joint: j as u8 });
                return;
            }
        }
        self.last_good = measured.position;
    }

    fn check_freshness(&mut self, now: Timestamp, measured: &JointState, stamp: Option<Timestamp>) {
        let fresh = stamp.is_some_and(|s| now.saturating_since(s) <= self.config.watchdog);
        if fresh {
            if self.state == SafetyState::Holding && !self.awaiting_new_motion {
                self.state = SafetyState::Running;
                self.events.insert(SafetyEvent::ReferenceRecovered);
            }
            return;
        }
        // Stale (or never received): measure from the later of the last reference and activation.
        let since = stamp.map_or(self.activated_at, |s| s.max(self.activated_at));
        let age = now.saturating_since(since);
        if self.state == SafetyState::Running {
            self.state = SafetyState::Holding;
            self.hold_at = measured.position;
            self.events.insert(SafetyEvent::ReferenceStale);
        }
        if age
            > self
                .config
                .watchdog
                .saturating_add(self.config.stale_to_fault)
        {
            self.fault(FaultCause::ReferenceTimeout);
        }
    }

    /// Caps a master's reference wrench at the force limits (slaves: unchanged).
    pub fn limit_reference(&mut self, reference: Reference) -> Reference {
        if self.config.role != TeleopRole::Master {
            return reference;
        }
        match reference {
            Reference::Wrench(w) => Reference::Wrench(self.limit_wrench(w)),
            Reference::Hybrid(mut h) => {
                h.wrench = self.limit_wrench(h.wrench);
                Reference::Hybrid(h)
            }
            other => other,
        }
    }

    /// Scales the force and the moment of `w` down to the configured limits (each separately,
    /// keeping their directions). Non-finite wrenches become zero.
    pub fn limit_wrench(&mut self, mut w: Wrench) -> Wrench {
        if !w.is_finite() {
            self.events.insert(SafetyEvent::ForceLimited);
            return Wrench::zero(w.frame);
        }
        let f = w.force.norm();
        if f > self.config.max_force {
            w.force *= self.config.max_force / f;
            self.events.insert(SafetyEvent::ForceLimited);
        }
        let m = w.torque.norm();
        if m > self.config.max_moment {
            w.torque *= self.config.max_moment / m;
            self.events.insert(SafetyEvent::ForceLimited);
        }
        w
    }

    /// Checks a command for NaN/inf and clamps it to the torque or position limits; joints past
    /// `joint_count` are zeroed.
    ///
    /// # Errors
    /// [`FaultCause::NonFiniteCommand`] (the caller faults).
    pub fn limit_command(&mut self, command: JointCommand) -> Result<JointCommand, FaultCause> {
        let n = self.config.joint_count;
        let l = &self.config.limits;
        // Which joints carry position targets; the others carry torques.
        let (mut effort, mut position, position_joints) = match command {
            JointCommand::Effort(v) => (v, JointVector::zeros(), JointSet::EMPTY),
            JointCommand::Position(v) => (JointVector::zeros(), v, JointSet::first(n)),
            JointCommand::Mixed {
                effort,
                position,
                position_joints,
            } => (effort, position, position_joints),
        };
        let finite = (0..n).all(|j| {
            if position_joints.contains(j) {
                position[j].is_finite()
            } else {
                effort[j].is_finite()
            }
        });
        if !finite {
            return Err(FaultCause::NonFiniteCommand);
        }
        let (mut effort_clamped, mut position_clamped) = (false, false);
        for j in 0..MAX_JOINTS {
            if j >= n {
                effort[j] = 0.0;
                position[j] = 0.0;
            } else if position_joints.contains(j) {
                let c = position[j].clamp(l.position_min[j], l.position_max[j]);
                position_clamped |= c != position[j];
                position[j] = c;
                effort[j] = 0.0;
            } else {
                let c = effort[j].clamp(-l.effort_max[j], l.effort_max[j]);
                effort_clamped |= c != effort[j];
                effort[j] = c;
                position[j] = 0.0;
            }
        }
        if effort_clamped {
            self.events.insert(SafetyEvent::EffortClamped);
        }
        if position_clamped {
            self.events.insert(SafetyEvent::PositionClamped);
        }
        Ok(match command {
            JointCommand::Effort(_) => JointCommand::Effort(effort),
            JointCommand::Position(_) => JointCommand::Position(position),
            JointCommand::Mixed { .. } => JointCommand::Mixed {
                effort,
                position,
                position_joints,
            },
        })
    }
}

#[cfg(test)]
mod tests;
