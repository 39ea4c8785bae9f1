//! The replies: every successful answer and the records it carries (node, kind and object
//! information, control status, telemetry, link statistics).

use penelope_hal::LifecycleState;
use serde::{Deserialize, Serialize};

#[cfg(doc)]
use super::Call;
use super::{
    Class, ContactShapeMsg, Joints, MatrixMsg, NameEntry, ObjectRef, OperationalMsg, PoseMsg,
    ReferenceMsg, WrenchMsg,
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
    /// A recording started ([`CreatorCall::RecordStart`](super::CreatorCall::RecordStart);
    /// appended last, as is the next).
    Recording {
        /// The file, on the node's host.
        path: String,
        /// The controllers recorded.
        controllers: Vec<String>,
        /// The channels whose links are recorded.
        links: Vec<String>,
    },
    /// A recording ended ([`CreatorCall::RecordStop`](super::CreatorCall::RecordStop)).
    Recorded {
        /// The file.
        path: String,
        /// Control ticks written.
        ticks: u64,
    },
    /// The answer to [`Call::Time`](super::Call::Time) (appended last).
    Time {
        /// When the call was taken, ns on the serving host's monotonic clock.
        received_ns: i64,
        /// When it was answered, ns on the same clock.
        sent_ns: i64,
    },
    /// The answer to a node's e-stop ([`CreatorCall::EStop`](super::CreatorCall::EStop);
    /// appended last).
    Stopped(StopReport),
    /// A robot's description ([`RobotMethod::Description`](super::RobotMethod::Description);
    /// appended last).
    RobotDescription(RobotDescriptionMsg),
    /// Several poses, such as a robot's link frames
    /// ([`RobotMethod::LinkFrames`](super::RobotMethod::LinkFrames); appended last).
    Poses(Vec<PoseMsg>),
    /// The reference a robot's active controller follows now
    /// ([`RobotMethod::Setpoints`](super::RobotMethod::Setpoints); appended last, as is the
    /// next).
    Setpoints(SetpointsMsg),
    /// A robot's CRTK operating state
    /// ([`RobotMethod::OperatingState`](super::RobotMethod::OperatingState)).
    OperatingState(OperatingStateMsg),
}

/// The reference the robot's active controller follows now (CRTK `setpoint_js` /
/// `setpoint_cp`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SetpointsMsg {
    /// The loop's time of the sample the setpoint was read from, ns.
    pub time_ns: u64,
    /// Joint reference, rad (`None` when the controller follows a tool pose only).
    pub joints: Option<Joints>,
    /// Tool pose reference in the base frame (forward kinematics of the joint reference when
    /// the law is a joint law).
    pub pose: Option<PoseMsg>,
}

/// CRTK's operating state of a robot.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct OperatingStateMsg {
    /// `DISABLED` (no active controller), `ENABLED` (running), `PAUSED` (holding: a stale
    /// reference, a clutch), `FAULT` (a latched fault or e-stop).
    pub state: String,
    /// Whether the joints' positions are known (encoders referenced; simulated: always).
    pub is_homed: bool,
    /// Whether a `move_jp` / `move_cp` (or a GoTo) is under way.
    pub is_busy: bool,
}

/// What a 3D viewer needs to draw a robot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RobotDescriptionMsg {
    /// A URDF whose link names are `frames`: a URDF robot's own, or one generated from the DH
    /// table with simple link geometry.
    pub urdf: String,
    /// The robot's frames, root first, the tool frame last (what
    /// [`RobotMethod::LinkFrames`](super::RobotMethod::LinkFrames) gives a pose for, in order).
    pub frames: Vec<String>,
    /// The joint names, one per joint.
    pub joint_names: Vec<String>,
    /// The contact shapes of the simulated environment the robot's tool touches (its simulated
    /// board's), in the root frame; empty behind a real board.
    pub contacts: Vec<ContactShapeMsg>,
}

/// What a node's e-stop reached.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct StopReport {
    /// The node's name.
    pub node: String,
    /// The controllers whose loops latched their e-stop before the answer.
    pub stopped: Vec<String>,
    /// The controllers asked to stop whose loops had not yet ticked when the answer left (a
    /// loop on a simulated clock latches on its next step; one whose thread stalls is caught by
    /// its watchdog).
    pub pending: Vec<String>,
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
    /// The newest sample (none before the first tick); boxed, so that a reply stays small
    /// (the encoding is the record's).
    pub last: Option<Box<TelemetryRecord>>,
}

/// One control tick as a client sees it (a compact `TelemetrySample` of `penelope-rt-core`).
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
    /// The wrench the loop commanded, after its caps: a master's displayed force, what its
    /// motors produce at the handle (tau = J^T F); zero when the reference carries none.
    pub commanded_wrench: WrenchMsg,
    /// Whether the operator held the clutch at this tick (`None`: no hand holds this robot, or
    /// not known, as in a status reply).
    pub clutch: Option<bool>,
    /// The active law's passivity observer energy after this tick, J (`None`: the law has
    /// none).
    pub port_energy: Option<f64>,
    /// The teleoperation two-port's energy at this side's port, J (`None`: the law has none).
    pub channel_energy: Option<f64>,
}

/// A data-plane link's state and statistics as a client sees them (one end's view of a
/// `trajectory/teleop` channel whose other end is on another node).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LinkRecord {
    /// When it was read, ns on the node's monotonic clock.
    pub time_ns: u64,
    /// The link is lost (the other side silent past the timeout).
    pub down: bool,
    /// Times it was lost.
    pub losses: u64,
    /// Times it came back.
    pub restorations: u64,
    /// Samples taken (newest wins).
    pub samples_taken: u64,
    /// Samples dropped as late, duplicate or of a stale session.
    pub samples_dropped: u64,
    /// Sequence numbers skipped between taken samples (lost, or overtaken).
    pub samples_missed: u64,
    /// Datagrams refused: bad tag, wrong authentication, malformed, from a stranger.
    pub refused: u64,
    /// The other node's clock minus this node's, ns, as heartbeats estimate it.
    pub clock_offset_ns: Option<i64>,
    /// The heartbeats' round trip, ns (the other side's turnaround excluded).
    pub round_trip_ns: Option<i64>,
    /// The one-way delay estimate, ns (half the round trip).
    pub one_way_delay_ns: Option<i64>,
    /// The jitter of the offset estimate, ns.
    pub jitter_ns: Option<i64>,
    /// Since the other side was last heard, ns.
    pub last_heard_ns: Option<i64>,
    /// The share of heartbeats not answered (0 to 1).
    pub heartbeat_loss: f64,
    /// The samples' one-way trips measured.
    pub trips: u64,
    /// Their median, ns (arrival less send time on the common clock).
    pub trip_p50_ns: Option<i64>,
    /// Their 99th percentile, ns.
    pub trip_p99_ns: Option<i64>,
    /// The longest, ns.
    pub trip_max_ns: Option<i64>,
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
    /// The node's common-clock offset when the batch was sent, ns: a sample's time on the
    /// system's common clock is `time_ns + common_offset_ns` (zero on the node that hosts the
    /// naming service, on a simulated clock, or without a naming service). What lets a viewer
    /// put samples of several hosts, and camera frames, on one time line.
    pub common_offset_ns: i64,
}

impl TelemetryBatch {
    /// `time_ns` of one of its samples on the system's common clock.
    pub fn to_common(&self, time_ns: u64) -> u64 {
        time_ns.saturating_add_signed(self.common_offset_ns)
    }
}

/// Link records of one subscription to a `trajectory/teleop` channel linked to another node
/// (pushed every 100 ms, times the subscription's decimation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LinkBatch {
    /// The subscription's id.
    pub subscription: u64,
    /// Batches dropped for this subscription so far because the client read too slowly.
    pub dropped: u64,
    /// Records in time order.
    pub records: Vec<LinkRecord>,
}
