//! The naming service's calls and what it binds: classes, object references and entries.

#[cfg(doc)]
use crate::proto::CallError;
use std::fmt;

use serde::{Deserialize, Serialize};

#[cfg(doc)]
use super::{Call, Reply, WireError};

/// The naming service's methods. Paths are absolute, `/`-separated, such as `/lab-a/robots/slave`;
/// each component is 1-64 characters of `[A-Za-z0-9_.-]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum NamingCall {
    /// Registers (or re-registers) a node: its context `/<node>` and its lease. Every binding the
    /// node makes expires with the lease: [`Reply::Unit`].
    Register {
        /// The node's name (its context).
        node: String,
        /// Where its objects answer (`host:port`).
        address: String,
        /// The lease, ms: without a renewal for this long, the node's entries are removed.
        lease_ms: u32,
    },
    /// Renews a node's lease: [`Reply::Unit`] ([`CallError::UnknownName`] after it expired: the
    /// node registers again and re-binds).
    Renew {
        /// The node's name.
        node: String,
    },
    /// Removes a node and all its entries: [`Reply::Unit`].
    Unregister {
        /// The node's name.
        node: String,
    },
    /// Binds `path` to an object reference (intermediate contexts are created):
    /// [`Reply::Unit`]. Refused with [`CallError::NameTaken`] if bound, unless `rebind`.
    Bind {
        /// The absolute path.
        path: String,
        /// What the path names.
        reference: ObjectRef,
        /// Replace an existing binding.
        rebind: bool,
    },
    /// What `path` names: [`Reply::Resolved`].
    Resolve {
        /// The absolute path.
        path: String,
    },
    /// Removes the binding at `path` (and empty contexts above it): [`Reply::Unit`].
    Unbind {
        /// The absolute path.
        path: String,
    },
    /// The entries of a context (`/` for the root): [`Reply::Names`].
    List {
        /// The context's path.
        context: String,
    },
}

/// The five classes of objects (DESIGN.md section 1), plus the creator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Class {
    /// A node's creator.
    Creator,
    /// A board.
    Board,
    /// A robot (manipulator or joystick).
    Robot,
    /// A sensor.
    Sensor,
    /// A controller.
    Controller,
    /// A trajectory.
    Trajectory,
}

impl Class {
    /// Every class.
    pub const ALL: [Class; 6] = [
        Class::Creator,
        Class::Board,
        Class::Robot,
        Class::Sensor,
        Class::Controller,
        Class::Trajectory,
    ];

    /// The singular lower-case name (`robot`), the prefix of a kind (`robot/puma560`).
    pub const fn as_str(self) -> &'static str {
        match self {
            Class::Creator => "creator",
            Class::Board => "board",
            Class::Robot => "robot",
            Class::Sensor => "sensor",
            Class::Controller => "controller",
            Class::Trajectory => "trajectory",
        }
    }

    /// The naming context of the class under a node (`robots`); the creator is bound directly at
    /// `/<node>/creator`.
    pub const fn context(self) -> &'static str {
        match self {
            Class::Creator => "",
            Class::Board => "boards",
            Class::Robot => "robots",
            Class::Sensor => "sensors",
            Class::Controller => "controllers",
            Class::Trajectory => "trajectories",
        }
    }

    /// Parses the singular name.
    pub fn parse(name: &str) -> Option<Class> {
        Class::ALL.into_iter().find(|c| c.as_str() == name)
    }
}

impl fmt::Display for Class {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The naming path of object `name` of `class` on `node`: `/<node>/<context>/<name>`
/// (`/<node>/creator` for the creator).
pub fn object_path(node: &str, class: Class, name: &str) -> String {
    match class {
        Class::Creator => format!("/{node}/creator"),
        _ => format!("/{node}/{}/{name}", class.context()),
    }
}

/// What a naming entry refers to: enough to call the object from anywhere.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ObjectRef {
    /// The node that hosts it.
    pub node: String,
    /// Where the node answers (`host:port`).
    pub address: String,
    /// The object's name on the node (what [`Call::Object`] takes).
    pub name: String,
    /// Its class (the interface it answers).
    pub class: Class,
    /// Its kind (`robot/puma560`).
    pub kind: String,
}

/// One entry of a naming context.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum NameEntry {
    /// A sub-context.
    Context {
        /// The component name.
        name: String,
    },
    /// A bound object.
    Object {
        /// The component name.
        name: String,
        /// What it refers to.
        reference: ObjectRef,
    },
}

impl NameEntry {
    /// The entry's component name.
    pub fn name(&self) -> &str {
        match self {
            NameEntry::Context { name } | NameEntry::Object { name, .. } => name,
        }
    }
}
