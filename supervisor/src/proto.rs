//! The protocol: the single definition of every message that crosses a Penelope connection (the
//! IDL of this system, after the paper's CORBA IDL).
//!
//! # Framing
//! A connection is a byte stream of frames. A frame is a 4-byte little-endian length `n`
//! followed by `n` bytes of [postcard](https://docs.rs/postcard)-encoded message: a client sends
//! [`ClientMsg`], a node answers [`ServerMsg`]. `n` is at most the receiver's maximum frame size
//! ([`DEFAULT_MAX_FRAME`] unless configured); a longer length is refused with
//! [`WireError::FrameTooLarge`] before any byte of the body is read. `docs/wire-format.md` shows
//! every step with bytes.
//!
//! # A session
//! 1. The client sends [`ClientMsg::Hello`] (magic, protocol version, its name and the [`Role`]
//!    it claims).
//! 2. The node answers [`ServerMsg::Hello`] with its [`Security`]. Under [`Security::Noise`]
//!    (the node has the shared secret) both sides then run the Noise handshake [`NOISE_PATTERN`]
//!    with a pre-shared key derived from the secret, the two hellos as its prologue: the client
//!    sends [`ClientMsg::Handshake`], which only a holder of the secret can make; the node
//!    answers [`ServerMsg::Handshake`], which only a holder of the secret can make. From then on
//!    every frame's body, both ways, is sealed (ChaCha20-Poly1305 under the session's keys,
//!    counted nonces): a replayed, reordered or altered frame fails to open and the connection
//!    closes. A client that holds the secret sends no request to a node that answers
//!    [`Security::Plain`]. See `crate::net::auth`.
//! 3. The client sends [`ClientMsg::Request`]s, each with an id of its choice; the node answers each
//!    with a [`ServerMsg::Response`] carrying the same id. Requests may be pipelined (sent before
//!    earlier answers arrive); answers come back in request order.
//! 4. After [`Call::Subscribe`], the node also sends [`ServerMsg::Telemetry`] frames for that
//!    subscription until [`Call::Unsubscribe`] or the end of the connection. They are dropped,
//!    never queued without bound, when the client reads too slowly (`dropped` counts them).
//! 5. Either side may close. A connection-level problem (bad frame, wrong version, failed
//!    authentication, rate limit) is reported with [`ServerMsg::Error`] before the node closes.
//!
//! The frames of steps 1 and 2 (and an error ending the handshake) are never sealed; every frame
//! after the handshake is, under [`Security::Noise`].
//!
//! # Compatibility
//! Messages are postcard: field order and enum variant order are the encoding. Adding a variant
//! at the end of an enum is compatible for the receiver that knows it; anything else changes
//! [`PROTOCOL_VERSION`].

use std::fmt;

use nalgebra::{Matrix3, SMatrix, Translation3, UnitQuaternion, Vector3};
use penelope_hal::{
    Frame, JointVector, LifecycleState, MAX_JOINTS, NamedPose, Pose, Transition, Wrench,
};
use serde::{Deserialize, Serialize};

/// The first four bytes of every hello: `PNLP`.
pub const MAGIC: [u8; 4] = *b"PNLP";

/// The version of this protocol; a hello with another version is refused.
pub const PROTOCOL_VERSION: u16 = 2;

/// The default maximum frame body, bytes (256 KiB).
pub const DEFAULT_MAX_FRAME: usize = 256 * 1024;

/// The bytes of the frame header (the little-endian `u32` length).
pub const FRAME_HEADER_LEN: usize = 4;

/// The Noise protocol of an authenticated connection (see `crate::net::auth`).
pub const NOISE_PATTERN: &str = "Noise_NNpsk0_25519_ChaChaPoly_BLAKE2s";

/// The default TCP port of a node (and of a naming service run alone).
pub const DEFAULT_PORT: u16 = 7300;

// ---------------------------------------------------------------------------------------------
// Top-level messages
// ---------------------------------------------------------------------------------------------

/// A message from a client to a node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ClientMsg {
    /// Opens the session.
    Hello(ClientHello),
    /// The first Noise handshake message (`-> psk, e`: 32 bytes of ephemeral key and the 16-byte
    /// tag of an empty payload), sent after the node's hello when it says [`Security::Noise`].
    Handshake {
        /// The Noise message.
        #[serde(with = "serde_bytes")]
        noise: Vec<u8>,
    },
    /// A call; answered by a [`ServerMsg::Response`] with the same `id`.
    Request {
        /// Chosen by the client; echoed in the response.
        id: u64,
        /// What to do.
        call: Call,
    },
    /// The client is done; the node closes the connection.
    Bye,
}

/// The client's hello.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ClientHello {
    /// Must be [`MAGIC`].
    pub magic: [u8; 4],
    /// Must be [`PROTOCOL_VERSION`].
    pub version: u16,
    /// Who is calling (a node name or a tool name): the node's name for [`Role::Node`].
    pub client: String,
    /// What the client claims to be; the node's naming service authorizes by it.
    pub role: Role,
}

impl ClientHello {
    /// A hello of this protocol version from `client`, claiming `role`.
    pub fn new(client: impl Into<String>, role: Role) -> Self {
        ClientHello {
            magic: MAGIC,
            version: PROTOCOL_VERSION,
            client: client.into(),
            role,
        }
    }
}

/// What a client claims to be in its hello. Under [`Security::Noise`] the claim is bound into the
/// handshake (the hellos are its prologue), and [`Role::Admin`] needs the admin secret; without a
/// secret ([`Security::Plain`]) the claim is taken on trust.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Role {
    /// A tool or a user: reads the naming tree, calls objects and creators.
    Reader,
    /// A node, named by the hello's `client`: also registers, renews and unregisters itself, and
    /// binds, rebinds and unbinds inside its own context `/<client>/...`.
    Node,
    /// An administrator: may also unregister any node and write anywhere in the tree.
    Admin,
}

/// How a node protects a connection, as its hello says.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Security {
    /// No secret: plain frames, and the client's claimed role is taken on trust (loopback-only
    /// systems).
    Plain,
    /// The shared secret: the Noise handshake [`NOISE_PATTERN`] follows, then sealed frames.
    Noise {
        /// The node has an admin secret: a client claiming [`Role::Admin`] must prove it (its
        /// pre-shared key mixes both secrets). Without one, such a client is served as a
        /// [`Role::Reader`].
        admin: bool,
    },
}

/// A message from a node to a client.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ServerMsg {
    /// The node's hello.
    Hello(ServerHello),
    /// The second Noise handshake message (`<- e, ee`: 32 bytes of ephemeral key and the 16-byte
    /// tag of an empty payload); requests may follow, sealed.
    Handshake {
        /// The Noise message.
        #[serde(with = "serde_bytes")]
        noise: Vec<u8>,
    },
    /// The answer to the request `id`.
    Response {
        /// The request's id.
        id: u64,
        /// The result.
        result: Result<Reply, WireError>,
    },
    /// Samples of a telemetry subscription.
    Telemetry(TelemetryBatch),
    /// A connection-level error; the node closes the connection after sending it.
    Error(WireError),
}

/// The node's hello.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ServerHello {
    /// [`MAGIC`].
    pub magic: [u8; 4],
    /// [`PROTOCOL_VERSION`].
    pub version: u16,
    /// The node's name (its context in the naming tree).
    pub node: String,
    /// Whether (and how) the node requires the shared secret.
    pub security: Security,
}

// ---------------------------------------------------------------------------------------------
// Calls
// ---------------------------------------------------------------------------------------------

/// Every request a node serves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Call {
    /// Echoes `payload` (liveness, and the remote-call round trip of `penelope bench rpc`).
    Ping {
        /// Bytes sent back unchanged.
        // serde_bytes: the same bytes on the wire as a sequence of u8, encoded in one copy.
        #[serde(with = "serde_bytes")]
        payload: Vec<u8>,
    },
    /// What this node is: [`Reply::Node`].
    NodeInfo,
    /// The creator of this node (the paper's `creatorImpl`).
    Creator(CreatorCall),
    /// A method of the object `object` (its name on this node).
    Object {
        /// The object's name on the node.
        object: String,
        /// The method and its arguments.
        method: Method,
    },
    /// The naming service, if this node hosts it (else [`WireError::NoNamingService`]).
    Naming(NamingCall),
    /// Stream the telemetry of `object` (a controller, or a robot driven by an active
    /// controller) to this connection: [`Reply::Subscribed`], then [`ServerMsg::Telemetry`].
    Subscribe {
        /// The object's name on the node.
        object: String,
        /// Send one control tick in `decimation` (1 = every tick; 0 is taken as 1).
        decimation: u32,
    },
    /// Stop a subscription of this connection.
    Unsubscribe {
        /// The id from [`Reply::Subscribed`].
        subscription: u64,
    },
}

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

/// A method of an object. Methods of a class the object is not are refused with
/// [`WireError::WrongClass`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Method {
    /// What the object is: [`Reply::Object`].
    Describe,
    /// A lifecycle transition (`configure`, `activate`, `deactivate`, `cleanup`, `shutdown`,
    /// `reset`): [`Reply::Object`] with the new state. Runs on the non-real-time side; reaches a
    /// running loop through its command ring.
    Transition(Transition),
    /// A robot's method.
    Robot(RobotMethod),
    /// A board's method.
    Board(BoardMethod),
    /// A sensor's method.
    Sensor(SensorMethod),
    /// A controller's method.
    Controller(ControllerMethod),
    /// A trajectory's method.
    Trajectory(TrajectoryMethod),
}

/// Robot methods (the paper's `Puma200` class). `q: None` means "the measured joint positions".
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum RobotMethod {
    /// Measured joint positions, rad: [`Reply::Joints`].
    JointPositions,
    /// Measured joint velocities, rad/s: [`Reply::Joints`].
    JointVelocities,
    /// Estimated joint accelerations, rad/s²: [`Reply::Joints`].
    JointAccelerations,
    /// Operational-space state at the measured joints (tool pose, twist): [`Reply::Operational`].
    Operational,
    /// The wrench at the tool from the bound force sensor, N and N·m in the base frame:
    /// [`Reply::Wrench`].
    ToolWrench,
    /// Forward kinematics: [`Reply::Pose`] (position and the three orientation versors).
    ForwardKinematics {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// Geometric Jacobian in the base frame, `[v; w]` rows: [`Reply::Matrix`] (6 × n).
    Jacobian {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// Damped least-squares inverse of the Jacobian: [`Reply::Matrix`] (n × 6).
    JacobianInverse {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
        /// Damping λ (dimensionless, around 0.01).
        damping: f64,
    },
    /// Inverse kinematics: every branch within the joint limits: [`Reply::Solutions`].
    InverseKinematics {
        /// The target tool pose in the base frame.
        pose: PoseMsg,
    },
    /// Joint torques that balance a tool wrench, `tau = Jᵀ F`: [`Reply::Joints`] (N·m).
    WrenchToTorques {
        /// The wrench at the tool, base frame.
        wrench: WrenchMsg,
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// Gravity torques, N·m: [`Reply::Joints`].
    Gravity {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// Joint-space inertia matrix, kg·m²: [`Reply::Matrix`] (n × n).
    Inertia {
        /// Joint positions, rad (`None`: measured).
        q: Option<Joints>,
    },
    /// Encoder counts to joint radians: [`Reply::Joints`].
    CountsToRadians {
        /// One count per joint.
        counts: Vec<i64>,
    },
    /// Joint radians to encoder counts: [`Reply::Counts`].
    RadiansToCounts {
        /// One angle per joint, rad.
        q: Joints,
    },
    /// The joint positions of a named pose: [`Reply::Joints`].
    NamedPose {
        /// `nest`, `start` or `work`.
        pose: NamedPose,
    },
    /// Moves to a named pose (goNested, goStart, goWork) along a smooth joint trajectory through
    /// the robot's active controller: [`Reply::Unit`] once started.
    GoTo {
        /// `nest`, `start` or `work`.
        pose: NamedPose,
        /// Duration of the motion, s (> 0).
        duration_s: f64,
    },
    /// Maps joints onto a board's axes (a robot may use several boards): [`Reply::Unit`].
    MapJoints {
        /// The board's name on this node.
        board: String,
        /// One entry per joint to map.
        joints: Vec<JointAxis>,
    },
}

/// One joint driven by one board axis.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointAxis {
    /// The joint (0-based).
    pub joint: u8,
    /// The board axis (0-based).
    pub axis: u8,
}

/// Board methods.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum BoardMethod {
    /// Number of axes: [`Reply::Count`].
    AxisCount,
    /// Encoder positions of every axis, counts: [`Reply::Counts`].
    ReadEncoders,
    /// Whether the amplifiers are enabled: [`Reply::Flag`].
    AmplifiersEnabled,
    /// Asks a board that latched a fault of its own (a lost Galil line) to leave it, once its
    /// cause is gone: [`Reply::Unit`]. A board driven by a running loop is re-armed through its
    /// controller (`ControllerMethod::Rearm`), which re-arms the loop too.
    Rearm,
}

/// Sensor methods.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum SensorMethod {
    /// The newest reading (wrench in the sensor frame, N and N·m): [`Reply::Wrench`].
    Read,
    /// Takes the current reading as the zero (bias): [`Reply::Unit`].
    Bias,
    /// Where the sensor's probe is (for `sensor/virtual`: the tool pose and velocity that the
    /// environment model pushes against): [`Reply::Unit`]. A controller bound to the sensor
    /// feeds it every communication period.
    SetProbe {
        /// The probe pose in the base frame.
        pose: PoseMsg,
        /// The probe's linear velocity in the base frame, m/s.
        velocity: [f64; 3],
    },
    /// Reads the wrench for a probe in one round trip (the data path of a remote sensor):
    /// [`Reply::Wrench`].
    Measure {
        /// The probe pose in the base frame.
        pose: PoseMsg,
        /// The probe's linear velocity in the base frame, m/s.
        velocity: [f64; 3],
    },
}

/// Controller methods (the paper's `ControllerImpl`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ControllerMethod {
    /// Binds the robot it drives: a name on this node (robots are not remote). [`Reply::Unit`].
    SetRobot {
        /// The robot's name.
        robot: String,
    },
    /// Binds the trajectory it follows: a name on this node. [`Reply::Unit`].
    SetTrajectory {
        /// The trajectory's name.
        trajectory: String,
    },
    /// Binds the force sensor: a name on this node or a naming path (`/node/sensors/name`) of a
    /// sensor on another node, which the controller's communication thread then reads.
    /// [`Reply::Unit`].
    SetSensor {
        /// Local name or naming path.
        sensor: String,
    },
    /// Replaces gains at run time (keys depend on the kind, as in its config): [`Reply::Unit`].
    SetGains {
        /// TOML text, such as `kp = [100, 100, 100, 10, 10, 10]`.
        gains: String,
    },
    /// Latches the emergency stop of the running loop: [`Reply::Unit`].
    EStop,
    /// Clears a latched fault or e-stop (activate again afterwards): [`Reply::Unit`].
    Rearm,
    /// The running loop's newest sample and its counters: [`Reply::Status`].
    Status,
}

/// Trajectory methods.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum TrajectoryMethod {
    /// The reference at time `t_s` after the trajectory's start (the paper's `getReferiment`):
    /// [`Reply::Reference`].
    Reference {
        /// Seconds after the start.
        t_s: f64,
    },
    /// The total duration, s (`None` for endless ones): [`Reply::Duration`].
    Duration,
}

// ---------------------------------------------------------------------------------------------
// Naming
// ---------------------------------------------------------------------------------------------

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
    /// Renews a node's lease: [`Reply::Unit`] ([`WireError::UnknownName`] after it expired: the
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
    /// [`Reply::Unit`]. Refused with [`WireError::NameTaken`] if bound, unless `rebind`.
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

// ---------------------------------------------------------------------------------------------
// Replies and plain data
// ---------------------------------------------------------------------------------------------

/// Joint values, one per joint (rad, rad/s or N·m as the method says); at most 6.
pub type Joints = Vec<f64>;

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

/// A pose: position and orientation as the three versors of the tool frame (the columns of the
/// rotation matrix: normal `n`, sliding `o`, approach `a`), in the base frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseMsg {
    /// Position, m.
    pub position: [f64; 3],
    /// Normal versor `n` (the tool x axis).
    pub n: [f64; 3],
    /// Sliding versor `o` (the tool y axis).
    pub o: [f64; 3],
    /// Approach versor `a` (the tool z axis).
    pub a: [f64; 3],
}

/// A wrench: force (N) and torque (N·m).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WrenchMsg {
    /// Force, N.
    pub force: [f64; 3],
    /// Torque, N·m.
    pub torque: [f64; 3],
}

/// Operational-space state: tool pose and twist.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OperationalMsg {
    /// The tool pose.
    pub pose: PoseMsg,
    /// Linear velocity, m/s.
    pub linear_velocity: [f64; 3],
    /// Angular velocity, rad/s.
    pub angular_velocity: [f64; 3],
}

/// A dense matrix, row-major.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MatrixMsg {
    /// Rows.
    pub rows: u16,
    /// Columns.
    pub cols: u16,
    /// `rows * cols` values, row after row.
    pub data: Vec<f64>,
}

/// A reference a controller follows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ReferenceMsg {
    /// Joint positions (rad) and velocities (rad/s).
    Joint {
        /// Positions, rad.
        q: Joints,
        /// Velocities, rad/s.
        qd: Joints,
    },
    /// A tool pose.
    Cartesian {
        /// The pose.
        pose: PoseMsg,
    },
    /// A wrench to display or exert.
    Wrench {
        /// The wrench.
        wrench: WrenchMsg,
    },
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

// ---------------------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------------------

/// Every error that crosses the wire.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
pub enum WireError {
    /// A frame's body did not decode as the expected message.
    #[error("malformed message: {0}")]
    Malformed(String),
    /// A frame announced more bytes than the receiver accepts.
    #[error("frame of {len} bytes exceeds the maximum of {max}")]
    FrameTooLarge {
        /// The announced length.
        len: u64,
        /// The receiver's maximum.
        max: u64,
    },
    /// The hello did not start with [`MAGIC`].
    #[error("not a Penelope peer (bad magic)")]
    BadMagic,
    /// The peer speaks another protocol version.
    #[error("protocol version {theirs} is not supported (this side speaks {ours})")]
    VersionMismatch {
        /// Ours.
        ours: u16,
        /// Theirs.
        theirs: u16,
    },
    /// A message came out of order (a request before the hello, a second hello, ...).
    #[error("unexpected message: {0}")]
    Unexpected(String),
    /// The node requires the shared secret and none (or a wrong one) was given.
    #[error("authentication failed")]
    AuthFailed,
    /// Too many requests per second on this connection.
    #[error("rate limit exceeded ({limit} requests/s)")]
    RateLimited {
        /// The limit.
        limit: u32,
    },
    /// The node serves no more connections now.
    #[error("too many connections (limit {limit})")]
    TooManyConnections {
        /// The limit.
        limit: u32,
    },
    /// The peer was silent for too long.
    #[error("timed out: {0}")]
    Timeout(String),
    /// A limit on objects, subscriptions or bindings was reached.
    #[error("limit reached: {what} (at most {limit})")]
    LimitReached {
        /// What is limited.
        what: String,
        /// The limit.
        limit: u32,
    },
    /// No kind of that name.
    #[error("unknown kind `{0}` (see `kinds`)")]
    UnknownKind(String),
    /// No object, node or naming entry of that name.
    #[error("unknown name `{0}`")]
    UnknownName(String),
    /// The name is already used.
    #[error("name `{0}` is already taken")]
    NameTaken(String),
    /// The name or path is not well formed.
    #[error("bad name `{name}`: {reason}")]
    BadName {
        /// The name.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// The configuration does not fit the kind.
    #[error("bad configuration for `{kind}`: {message}")]
    BadConfig {
        /// The kind.
        kind: String,
        /// What is wrong.
        message: String,
    },
    /// An argument is out of range or of the wrong size.
    #[error("bad argument: {0}")]
    BadArgument(String),
    /// The object is of another class than the method's.
    #[error("`{name}` is a {found}, not a {expected}")]
    WrongClass {
        /// The object.
        name: String,
        /// The method's class.
        expected: Class,
        /// The object's class.
        found: Class,
    },
    /// The transition is not allowed from the object's state.
    #[error("cannot {transition:?} `{name}` in state {state:?}")]
    InvalidTransition {
        /// The object.
        name: String,
        /// Its state.
        state: LifecycleState,
        /// The refused transition.
        transition: Transition,
    },
    /// The object is needed by active objects.
    #[error("`{name}` is in use by {dependents:?} (destroy with force to stop them first)")]
    InUse {
        /// The object.
        name: String,
        /// The active objects that use it.
        dependents: Vec<String>,
    },
    /// The object cannot do this now (not configured, no robot bound, not running, ...).
    #[error("not ready: {0}")]
    NotReady(String),
    /// The object's kind does not support this method.
    #[error("`{kind}` does not support {method}")]
    Unsupported {
        /// The object's kind.
        kind: String,
        /// The method.
        method: String,
    },
    /// A device (board, sensor, link) reported an error.
    #[error("device error: {0}")]
    Device(String),
    /// This node does not host the naming service.
    #[error("this node does not host the naming service")]
    NoNamingService,
    /// A remote node could not be reached or answered with a transport error.
    #[error("remote call failed: {0}")]
    Remote(String),
    /// A bug: the node could not do what it should have.
    #[error("internal error: {0}")]
    Internal(String),
    /// The session's role may not do this (a node writing outside its own context, a reader
    /// writing the naming tree, unregistering another node without the admin credential).
    #[error("forbidden: {0}")]
    Forbidden(String),
}

/// Short names of the lifecycle transitions a user types (`configure`, ...).
pub fn parse_transition(word: &str) -> Option<Transition> {
    Some(match word {
        "configure" => Transition::Configure,
        "activate" => Transition::Activate,
        "deactivate" => Transition::Deactivate,
        "cleanup" => Transition::Cleanup,
        "shutdown" => Transition::Shutdown,
        "reset" => Transition::Reset,
        _ => return None,
    })
}

/// Checks one name component: 1-64 characters of `[A-Za-z0-9_.-]`, not `.` or `..`.
///
/// # Errors
/// [`WireError::BadName`] saying what is wrong.
pub fn check_name(name: &str) -> Result<(), WireError> {
    let bad = |reason: &str| {
        Err(WireError::BadName {
            name: name.chars().take(80).collect(),
            reason: reason.to_string(),
        })
    };
    if name.is_empty() {
        return bad("empty");
    }
    if name.len() > 64 {
        return bad("longer than 64 characters");
    }
    if name == "." || name == ".." {
        return bad("`.` and `..` are reserved");
    }
    if !name
        .bytes()
        .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'.' | b'-'))
    {
        return bad("only letters, digits, `_`, `.` and `-` are allowed");
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Conversions between the wire's plain data and the math types of `hal`
// ---------------------------------------------------------------------------------------------

impl From<&Pose> for PoseMsg {
    fn from(pose: &Pose) -> Self {
        let r = pose.rotation.to_rotation_matrix();
        let col = |j: usize| [r[(0, j)], r[(1, j)], r[(2, j)]];
        let t = pose.translation.vector;
        PoseMsg {
            position: [t.x, t.y, t.z],
            n: col(0),
            o: col(1),
            a: col(2),
        }
    }
}

impl PoseMsg {
    /// The pose, after checking that every value is finite and that `n, o, a` are orthonormal
    /// and right-handed within 1e-6 (then re-orthonormalized).
    ///
    /// # Errors
    /// [`WireError::BadArgument`] saying what is wrong.
    pub fn to_pose(&self) -> Result<Pose, WireError> {
        let all = self
            .position
            .iter()
            .chain(&self.n)
            .chain(&self.o)
            .chain(&self.a);
        if !all.into_iter().all(|x| x.is_finite()) {
            return Err(WireError::BadArgument(
                "pose has a NaN or infinite value".into(),
            ));
        }
        let m = Matrix3::from_columns(&[
            Vector3::from(self.n),
            Vector3::from(self.o),
            Vector3::from(self.a),
        ]);
        let off = (m.transpose() * m - Matrix3::identity()).abs().max();
        if off > 1e-6 || m.determinant() < 0.0 {
            return Err(WireError::BadArgument(
                "pose versors n, o, a are not orthonormal and right-handed".into(),
            ));
        }
        let rotation = UnitQuaternion::from_matrix(&m);
        Ok(Pose::from_parts(
            Translation3::from(Vector3::from(self.position)),
            rotation,
        ))
    }
}

impl From<&Wrench> for WrenchMsg {
    fn from(w: &Wrench) -> Self {
        WrenchMsg {
            force: [w.force.x, w.force.y, w.force.z],
            torque: [w.torque.x, w.torque.y, w.torque.z],
        }
    }
}

impl WrenchMsg {
    /// The wrench in `frame`, after checking every value is finite.
    ///
    /// # Errors
    /// [`WireError::BadArgument`] for a NaN or infinite component.
    pub fn to_wrench(&self, frame: Frame) -> Result<Wrench, WireError> {
        if !self.force.iter().chain(&self.torque).all(|x| x.is_finite()) {
            return Err(WireError::BadArgument(
                "wrench has a NaN or infinite value".into(),
            ));
        }
        Ok(Wrench {
            force: Vector3::from(self.force),
            torque: Vector3::from(self.torque),
            frame,
        })
    }
}

/// The first `n` joints of `q` on the wire.
pub fn joints_from_vector(q: &JointVector, n: usize) -> Joints {
    q.iter().take(n.min(MAX_JOINTS)).copied().collect()
}

/// A joint vector from exactly `n` finite wire values (the rest zero).
///
/// # Errors
/// [`WireError::BadArgument`] for a wrong count or a NaN or infinite value.
pub fn joints_to_vector(q: &[f64], n: usize) -> Result<JointVector, WireError> {
    if q.len() != n || n > MAX_JOINTS {
        return Err(WireError::BadArgument(format!(
            "expected {n} joint values, got {}",
            q.len()
        )));
    }
    if !q.iter().all(|x| x.is_finite()) {
        return Err(WireError::BadArgument(
            "a joint value is NaN or infinite".into(),
        ));
    }
    let mut v = JointVector::zeros();
    v.as_mut_slice()[..n].copy_from_slice(q);
    Ok(v)
}

impl MatrixMsg {
    /// The top-left `rows` × `cols` block of `m`, row-major.
    pub fn from_block<const R: usize, const C: usize>(
        m: &SMatrix<f64, R, C>,
        rows: usize,
        cols: usize,
    ) -> Self {
        let (rows, cols) = (rows.min(R), cols.min(C));
        let mut data = Vec::with_capacity(rows * cols);
        for i in 0..rows {
            for j in 0..cols {
                data.push(m[(i, j)]);
            }
        }
        MatrixMsg {
            rows: rows as u16,
            cols: cols as u16,
            data,
        }
    }

    /// The value at row `i`, column `j` (`None` out of range).
    pub fn get(&self, i: usize, j: usize) -> Option<f64> {
        if i < usize::from(self.rows) && j < usize::from(self.cols) {
            self.data.get(i * usize::from(self.cols) + j).copied()
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_wrenches_and_joints_cross_the_wire_intact() {
        let pose = Pose::from_parts(
            Translation3::new(0.1, -0.2, 0.3),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1),
        );
        let back = PoseMsg::from(&pose).to_pose().unwrap();
        assert!((back.translation.vector - pose.translation.vector).norm() < 1e-12);
        assert!(back.rotation.angle_to(&pose.rotation) < 1e-9);
        let mut skew = PoseMsg::from(&pose);
        skew.n = [1.0, 1.0, 0.0];
        assert!(matches!(skew.to_pose(), Err(WireError::BadArgument(_))));
        let mut nan = PoseMsg::from(&pose);
        nan.position[1] = f64::NAN;
        assert!(nan.to_pose().is_err());

        let w = WrenchMsg {
            force: [1.0, 2.0, 3.0],
            torque: [0.1, 0.2, f64::INFINITY],
        };
        assert!(w.to_wrench(Frame::Base).is_err());

        assert!(joints_to_vector(&[0.1, 0.2], 3).is_err());
        assert!(joints_to_vector(&[0.1, f64::NAN, 0.3], 3).is_err());
        let q = joints_to_vector(&[0.1, 0.2, 0.3], 3).unwrap();
        assert_eq!(joints_from_vector(&q, 3), vec![0.1, 0.2, 0.3]);

        let m = MatrixMsg::from_block(
            &nalgebra::Matrix2x3::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0),
            2,
            2,
        );
        assert_eq!(m.data, vec![1.0, 2.0, 4.0, 5.0]);
        assert_eq!(m.get(1, 0), Some(4.0));
        assert_eq!(m.get(2, 0), None);
    }

    #[test]
    fn names_are_checked() {
        assert!(check_name("slave-1.a_b").is_ok());
        for bad in ["", ".", "..", "a/b", "a b", "é", &"x".repeat(65)] {
            assert!(
                matches!(check_name(bad), Err(WireError::BadName { .. })),
                "{bad:?}"
            );
        }
    }

    #[test]
    fn classes_round_trip_their_names() {
        for c in Class::ALL {
            assert_eq!(Class::parse(c.as_str()), Some(c));
        }
        assert_eq!(
            object_path("lab-a", Class::Robot, "slave"),
            "/lab-a/robots/slave"
        );
        assert_eq!(object_path("lab-a", Class::Creator, "x"), "/lab-a/creator");
    }

    #[test]
    fn every_message_round_trips_through_postcard() {
        let msgs = [
            ClientMsg::Hello(ClientHello::new("ctl", Role::Reader)),
            ClientMsg::Request {
                id: 7,
                call: Call::Object {
                    object: "slave".into(),
                    method: Method::Robot(RobotMethod::ForwardKinematics {
                        q: Some(vec![0.0, 0.1, 0.2, 0.0, 0.0, 0.0]),
                    }),
                },
            },
            ClientMsg::Handshake { noise: vec![3; 48] },
            ClientMsg::Bye,
        ];
        for m in msgs {
            let bytes = postcard::to_stdvec(&m).unwrap();
            assert_eq!(postcard::from_bytes::<ClientMsg>(&bytes).unwrap(), m);
        }
        let reply = ServerMsg::Response {
            id: 7,
            result: Err(WireError::InUse {
                name: "slave".into(),
                dependents: vec!["pid".into()],
            }),
        };
        let bytes = postcard::to_stdvec(&reply).unwrap();
        assert_eq!(postcard::from_bytes::<ServerMsg>(&bytes).unwrap(), reply);
    }
}
