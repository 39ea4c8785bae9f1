//! The creator's calls: objects come and go by name.

use serde::{Deserialize, Serialize};

#[cfg(doc)]
use super::{Reply, WireError};
#[cfg(doc)]
use penelope_hal::LifecycleState;

/// The creator's methods: objects come and go by name.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum CreatorCall {
    /// The kinds this node can create: [`Reply::Kinds`].
    Kinds,
    /// The objects of this node: [`Reply::Objects`].
    List,
    /// Makes an object `kind` (`class/kind`, such as `robot/puma560`) named `name`, configured by
    /// `config` (TOML text; `""` for the kind's defaults): [`Reply::Object`]. The object starts
    /// [`LifecycleState::Unconfigured`] and is bound in the naming tree.
    Create {
        /// `class/kind`, as listed by [`CreatorCall::Kinds`].
        kind: String,
        /// The object's name on this node: 1-64 characters of `[A-Za-z0-9_.-]`.
        name: String,
        /// TOML text with the kind's settings.
        config: String,
    },
    /// Removes an object and its naming entry. Refused with [`WireError::InUse`] while an active
    /// object depends on it, unless `force`: then the dependents are deactivated (amplifiers off,
    /// loops stopped) first.
    Destroy {
        /// The object's name.
        name: String,
        /// Stop the active dependents first instead of refusing.
        force: bool,
    },
    /// Moves a node's simulated clock on by `seconds` (0 to 3600), stepping every active loop:
    /// [`Reply::Duration`] with the clock's new time, s. Refused with [`WireError::NotReady`]
    /// on a node clocked in real time.
    Advance {
        /// How far, s.
        seconds: f64,
    },
}
