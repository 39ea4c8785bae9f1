//! The replies: every successful answer and the records it carries (node, kind and object
//! information, control status, telemetry).

use penelope_hal::LifecycleState;
use serde::{Deserialize, Serialize};

#[cfg(doc)]
use super::Call;
use super::{
    Class, Joints, MatrixMsg, NameEntry, ObjectRef, OperationalMsg, PoseMsg, ReferenceMsg,
    WrenchMsg,
};

/// Every successful answer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Reply {
    /// Done, nothing to return.
    Unit,
    /// The echo of [`Call::Ping`].
    Pong(#[serde(with = "serde_bytes")] Vec<u8>),
    /// The node's identity.
    Node(NodeInfo),
    /// The kinds a creator can make.
    Kinds(Vec<KindInfo>),
    /// Objects.
    Objects(Vec<ObjectInfo>),
    /// One object.
    Object(ObjectInfo),
    /// Joint values.
    Joints(Joints),
    /// Encoder counts.
    Counts(Vec<i64>),
    /// A count.
    Count(u32),
    /// A flag.
    Flag(bool),
    /// A duration, s (`None`: endless).
    Duration(Option<f64>),
    /// A pose.
    Pose(PoseMsg),
    /// Operational-space state.
    Operational(OperationalMsg),
    /// A wrench.
    Wrench(WrenchMsg),
    /// A matrix.
    Matrix(MatrixMsg),
    /// Inverse-kinematics solutions (each a joint vector), possibly none.
    Solutions(Vec<Joints>),
    /// A reference.
    Reference(ReferenceMsg),
    /// A controller's running state.
    Status(ControlStatus),
    /// A naming entry.
    Resolved(ObjectRef),
    /// A naming context's entries.
    Names(Vec<NameEntry>),
    /// A telemetry subscription started.
    Subscribed {
        /// Its id on this connection.
        subscription: u64,
    },
    /// A data-plane address, `host:port`.
    Address(String),
}

/// A node's identity.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeInfo {
    /// The node's name.
    pub node: String,
    /// The crate version of the node's build.
    pub software: String,
    /// Whether it hosts the naming service.
    pub hosts_naming: bool,
    /// Number of objects it hosts (the creator excluded).
    pub objects: u32,
}

/// One kind a creator can make.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct KindInfo {
    /// `class/kind`.
    pub kind: String,
    /// Its class.
    pub class: Class,
    /// One line on what it is.
    pub summary: String,
    /// The configuration keys, with units and defaults (TOML), one per line.
    pub config: String,
}

/// An object as the creator sees it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ObjectInfo {
    /// Its name on the node.
    pub name: String,
    /// `class/kind`.
    pub kind: String,
    /// Its class.
    pub class: Class,
    /// Its lifecycle state.
    pub state: LifecycleState,
    /// Its relations, as `(relation, target)` pairs such as `("robot", "slave")`.
    pub relations: Vec<(String, String)>,
}

/// A controller's running state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ControlStatus {
    /// The controller's lifecycle state.
    pub state: LifecycleState,
    /// Whether its control loop runs.
    pub running: bool,
    /// Ticks since the loop started.
    pub ticks: u64,
    /// Ticks that overran their period.
    pub overruns: u64,
    /// Telemetry samples dropped because the ring was full.
    pub telemetry_dropped: u64,
    /// The newest sample (none before the first tick).
    pub last: Option<TelemetryRecord>,
}

/// One control tick as a client sees it (a compact [`penelope_rt_core::telemetry::TelemetrySample`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TelemetryRecord {
    /// The tick's time, ns on the node's monotonic clock.
    pub time_ns: u64,
    /// Tick counter of the loop.
    pub seq: u64,
    /// Measured joint positions, rad.
    pub q: Joints,
    /// Measured joint velocities, rad/s.
    pub qd: Joints,
    /// Commanded joint efforts, N·m.
    pub effort: Joints,
    /// Tool position, m.
    pub tool_position: [f64; 3],
    /// Measured wrench (force sensor), base frame.
    pub wrench: WrenchMsg,
    /// Safety state (`inactive`, `active`, `holding`, `faulted`, ...).
    pub state: String,
    /// The latched fault, if any.
    pub fault: Option<String>,
}

/// Samples of one subscription.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TelemetryBatch {
    /// The subscription's id.
    pub subscription: u64,
    /// Batches dropped for this subscription so far because the client read too slowly.
    pub dropped: u64,
    /// Samples in time order.
    pub samples: Vec<TelemetryRecord>,
}
