//! The lifecycle every object goes through, in ROS 2 words.
//!
//! ```text
//! unconfigured --configure--> inactive --activate--> active
//!      ^                        |  ^                    |
//!      +--------cleanup---------+  +-----deactivate-----+
//! any but finalized --shutdown--> finalized
//! any but finalized --fault--> error --reset--> unconfigured   (re-arming is explicit)
//! ```
//! Transitions run on the non-real-time side; their effects reach the real-time threads through
//! cells.

use core::fmt;

/// Where an object is in its lifecycle. The names are shown verbatim to users.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum LifecycleState {
    /// Created, not yet configured.
    #[default]
    Unconfigured,
    /// Configured, not running.
    Inactive,
    /// Running.
    Active,
    /// Shut down for good.
    Finalized,
    /// Stopped by a fault; needs an explicit reset.
    Error,
}

/// A request to move between lifecycle states.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Transition {
    /// `unconfigured -> inactive`.
    Configure,
    /// `inactive -> active`.
    Activate,
    /// `active -> inactive`.
    Deactivate,
    /// `inactive -> unconfigured`.
    Cleanup,
    /// any state but `finalized` `-> finalized`.
    Shutdown,
    /// any state but `finalized` `-> error`.
    Fault,
    /// `error -> unconfigured`: the explicit re-arm after a fault.
    Reset,
}

/// A transition that is not allowed from the current state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct LifecycleError {
    /// The state the object was in.
    pub from: LifecycleState,
    /// The transition that was refused.
    pub transition: Transition,
}

impl fmt::Display for LifecycleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "cannot {} from state {}",
            self.transition.as_str(),
            self.from.as_str()
        )
    }
}

impl crate::error::Error for LifecycleError {
    fn kind(&self) -> crate::error::ErrorKind {
        crate::error::ErrorKind::WrongState
    }
}

impl LifecycleState {
    /// The state `transition` leads to from `self`, or why it is refused.
    ///
    /// # Errors
    /// [`LifecycleError`] when the transition is not defined from this state.
    pub fn apply(self, transition: Transition) -> Result<LifecycleState, LifecycleError> {
        use LifecycleState::*;
        use Transition::*;
        let next = match (self, transition) {
            (Unconfigured, Configure) => Inactive,
            (Inactive, Activate) => Active,
            (Active, Deactivate) => Inactive,
            (Inactive, Cleanup) => Unconfigured,
            (Error, Reset) => Unconfigured,
            (Finalized, _) => {
                return Err(LifecycleError {
                    from: self,
                    transition,
                });
            }
            (_, Shutdown) => Finalized,
            (_, Fault) => Error,
            _ => {
                return Err(LifecycleError {
                    from: self,
                    transition,
                });
            }
        };
        Ok(next)
    }

    /// The lower-case ROS 2 name of the state.
    pub const fn as_str(self) -> &'static str {
        match self {
            LifecycleState::Unconfigured => "unconfigured",
            LifecycleState::Inactive => "inactive",
            LifecycleState::Active => "active",
            LifecycleState::Finalized => "finalized",
            LifecycleState::Error => "error",
        }
    }
}

impl fmt::Display for LifecycleState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Transition {
    /// The verb users type for this transition.
    pub const fn as_str(self) -> &'static str {
        match self {
            Transition::Configure => "configure",
            Transition::Activate => "activate",
            Transition::Deactivate => "deactivate",
            Transition::Cleanup => "cleanup",
            Transition::Shutdown => "shutdown",
            Transition::Fault => "fault",
            Transition::Reset => "reset",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::LifecycleState::*;
    use super::Transition::*;

    #[test]
    fn the_ros2_happy_path_and_refusals() {
        let s = Unconfigured
            .apply(Configure)
            .and_then(|s| s.apply(Activate))
            .unwrap();
        assert_eq!(s, Active);
        assert_eq!(
            s.apply(Deactivate).and_then(|s| s.apply(Cleanup)),
            Ok(Unconfigured)
        );
        assert!(Unconfigured.apply(Activate).is_err());
        assert!(Active.apply(Cleanup).is_err());
    }

    #[test]
    fn faults_latch_until_an_explicit_reset() {
        let s = Active.apply(Fault).unwrap();
        assert_eq!(s, Error);
        assert!(s.apply(Activate).is_err());
        assert!(s.apply(Configure).is_err());
        assert_eq!(s.apply(Reset), Ok(Unconfigured));
        assert!(Finalized.apply(Reset).is_err());
        assert!(Finalized.apply(Fault).is_err());
    }
}
