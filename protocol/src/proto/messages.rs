//! The top-level messages: the hellos of both sides, the envelopes of requests, responses,
//! telemetry and errors, and [`Call`], every request a node serves.

#[cfg(doc)]
use crate::proto::CallError;
use serde::{Deserialize, Serialize};

#[cfg(doc)]
use super::NOISE_PATTERN;
use super::{
    CreatorCall, FrameBatch, LinkBatch, MAGIC, Method, NamingCall, PROTOCOL_VERSION, Reply,
    TelemetryBatch, WireError,
};

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
    /// A tool or a user that watches: reads the naming tree, lists and describes objects, reads
    /// their state, subscribes to telemetry, and stops (an e-stop or a deactivation is allowed
    /// to every authenticated peer: safety over secrecy). It may not operate, create or destroy.
    Reader,
    /// A node, named by the hello's `client`: also registers, renews and unregisters itself, and
    /// binds, rebinds and unbinds inside its own context `/<client>/...`; it operates objects
    /// (as [`Role::Operator`]) but does not create or destroy them on another node.
    Node,
    /// An administrator: may also unregister any node and write anywhere in the tree, and
    /// create and destroy objects.
    Admin,
    /// A tool or a user that operates: what a [`Role::Reader`] may, and lifecycle transitions,
    /// object methods, recordings, gains and the simulated clock. (Appended last: every earlier
    /// variant keeps its encoding.)
    Operator,
}

impl Role {
    /// The role's name in messages (`reader`, `operator`, `node`, `admin`).
    pub fn name(self) -> &'static str {
        match self {
            Role::Reader => "reader",
            Role::Operator => "operator",
            Role::Node => "node",
            Role::Admin => "admin",
        }
    }
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
        /// [`Role::Operator`].
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
    /// Link records of a subscription to a channel linked to another node (appended last, so
    /// every earlier variant keeps its encoding).
    Link(LinkBatch),
    /// Frames of a subscription to a camera (appended last).
    Frames(FrameBatch),
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
    /// The naming service, if this node hosts it (else [`CallError::NoNamingService`]).
    Naming(NamingCall),
    /// Stream the telemetry of `object` to this connection: [`Reply::Subscribed`], then, for a
    /// controller (or a robot driven by an active controller), [`ServerMsg::Telemetry`]; for a
    /// `trajectory/teleop` channel whose end here is linked to another node,
    /// [`ServerMsg::Link`] every 100 ms (a channel with both ends on one node has no link:
    /// [`CallError::NoLink`]); for a camera (`sensor/sim-camera`, `sensor/camera`),
    /// [`ServerMsg::Frames`], one in `decimation` of its frames.
    Subscribe {
        /// The object's name on the node.
        object: String,
        /// Send one control tick (or one link record) in `decimation` (1 = every one; 0 is
        /// taken as 1).
        decimation: u32,
    },
    /// Stop a subscription of this connection.
    Unsubscribe {
        /// The id from [`Reply::Subscribed`].
        subscription: u64,
    },
    /// The serving host's clock, for the four-timestamp estimate of its offset (a node asks
    /// its naming service: the system's common clock): [`Reply::Time`]. Appended last.
    Time,
}
