//! The protocol: the single definition of every message that crosses a Penelope connection (the
//! IDL of this system, after the paper's CORBA IDL).
//!
//! # Framing
//! A connection is a byte stream of frames. A frame is a 4-byte little-endian length `n`
//! followed by `n` bytes of [postcard](https://docs.rs/postcard)-encoded message: a client sends
//! [`ClientMsg`], a node answers [`ServerMsg`]. `n` is at most the receiver's maximum frame size
//! ([`DEFAULT_MAX_FRAME`] unless configured); a longer length is refused with
//! [`ProtocolError::FrameTooLarge`] before any byte of the body is read. `docs/wire-format.md`
//! shows every step with bytes.
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
//! 4. After [`Call::Subscribe`], the node also sends [`ServerMsg::Telemetry`] frames (a
//!    controller), [`ServerMsg::Link`] frames (a channel linked to another node) or
//!    [`ServerMsg::Frames`] (a camera) for that
//!    subscription until [`Call::Unsubscribe`], the end of the connection or, for a channel, its
//!    destruction or cleanup. They are dropped,
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

mod camera;
mod creator;
mod data;
mod errors;
mod messages;
mod naming;
mod object;
mod replies;
#[cfg(test)]
mod tests;

pub use camera::{CameraFrame, CameraModelMsg, FrameBatch, ImageEncoding};
pub use creator::CreatorCall;
pub use data::{
    ContactShapeMsg, Joints, MatrixMsg, OperationalMsg, PoseMsg, ReferenceMsg, WrenchMsg,
    joints_from_vector, joints_to_vector,
};
pub use errors::{
    CallError, ProtocolError, WireError, call_error_kinds, check_name, parse_transition,
    protocol_error_kinds,
};
pub use messages::{Call, ClientHello, ClientMsg, Role, Security, ServerHello, ServerMsg};
pub use naming::{Class, NameEntry, NamingCall, ObjectRef, object_path};
pub use object::{
    BoardMethod, ControllerMethod, JointAxis, Method, RobotMethod, SensorMethod, TrajectoryMethod,
};
pub use replies::{
    ControlStatus, KindInfo, LinkBatch, LinkRecord, NodeInfo, ObjectInfo, OperatingStateMsg, Reply,
    RobotDescriptionMsg, SetpointsMsg, StopReport, TelemetryBatch, TelemetryRecord,
};

/// The first four bytes of every hello: `PNLP`.
pub const MAGIC: [u8; 4] = *b"PNLP";

/// The version of this protocol; a hello with another version is refused.
pub const PROTOCOL_VERSION: u16 = 6;

/// The default maximum frame body, bytes (256 KiB).
pub const DEFAULT_MAX_FRAME: usize = 256 * 1024;

/// The bytes of the frame header (the little-endian `u32` length).
pub const FRAME_HEADER_LEN: usize = 4;

/// The Noise protocol of an authenticated connection (see `crate::net::auth`).
pub const NOISE_PATTERN: &str = "Noise_NNpsk0_25519_ChaChaPoly_BLAKE2s";

/// The default TCP port of a node (and of a naming service run alone).
pub const DEFAULT_PORT: u16 = 7300;
