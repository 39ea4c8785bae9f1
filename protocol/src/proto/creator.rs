//! The creator's calls: objects come and go by name.

#[cfg(doc)]
use crate::proto::CallError;
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
    /// Removes an object and its naming entry. Refused with [`CallError::InUse`] while an active
    /// object depends on it, unless `force`: then the dependents are deactivated (amplifiers off,
    /// loops stopped) first.
    Destroy {
        /// The object's name.
        name: String,
        /// Stop the active dependents first instead of refusing.
        force: bool,
    },
    /// Moves a node's simulated clock on by `seconds` (0 to 3600), stepping every active loop:
    /// [`Reply::Duration`] with the clock's new time, s. Refused with [`CallError::NotReady`]
    /// on a node clocked in real time.
    Advance {
        /// How far, s.
        seconds: f64,
    },
    /// Starts recording to the new MCAP file `path`, a plain file name `*.mcap` (no `/`, no
    /// `..`) in the node's recordings directory (`penelope node --records DIR`), created
    /// exclusively without following a link (an existing file or link of that name is
    /// [`CallError::BadArgument`], left as it was); [`Reply::Recording`]'s `path` says where
    /// it is on the node's host. Every tick of the controllers among
    /// `objects`, their safety events, and the link statistics of the `trajectory/teleop`
    /// channels among them; no `objects` records every controller and linked channel of the
    /// node. [`Reply::Recording`] with the path and what is recorded. One recording per node
    /// at a time ([`CallError::NotReady`] for a second); an object that is neither a
    /// controller nor a channel is [`CallError::BadArgument`], a missing one
    /// [`CallError::UnknownName`]. (Appended last: every earlier variant keeps its encoding.)
    RecordStart {
        /// The file's plain name in the node's recordings directory.
        path: String,
        /// The objects' names on the node (none: all of them).
        objects: Vec<String>,
    },
    /// Ends the recording and closes its file: [`Reply::Recorded`]. [`CallError::NotReady`]
    /// when there is none.
    RecordStop,
    /// Latches the e-stop of every loop running on this node: [`Reply::Stopped`]. Served
    /// before any other work of the node and without its object lock, so a slow call (a
    /// `create` reading a file) never holds it back; allowed to every authenticated peer.
    /// (Appended last.)
    EStop,
    /// Applies a system file (its TOML `text`) to this node, as `penelope node --config` does:
    /// the objects the file places on this node are created, related, configured and
    /// activated through the node's own creator, and on any refusal everything created from
    /// the file is destroyed again. [`Reply::Objects`] with the objects created, in creation
    /// order. A file that cannot be read, places nothing on this node while naming other
    /// nodes, or has a step refused is [`CallError::BadConfig`] with `kind` `system file` and
    /// a message naming the line, the object and the step. Needs the create role, like
    /// [`CreatorCall::Create`]. (Appended last.)
    ApplySystem {
        /// The system file's TOML text.
        text: String,
    },
    /// As [`CreatorCall::RecordStart`], drawing the recorded controllers' robots in 3D (`/tf`,
    /// `/scene`) at `scene_hz` of tick time (0..=10000; 0: their descriptions only;
    /// `RecordStart` draws at 100 Hz). A rate out of range is [`CallError::BadArgument`].
    /// (Appended last.)
    RecordStartScene {
        /// The file's plain name in the node's recordings directory.
        path: String,
        /// The objects' names on the node (none: all of them).
        objects: Vec<String>,
        /// `/tf` and `/scene` per second of tick time.
        scene_hz: f64,
    },
}
