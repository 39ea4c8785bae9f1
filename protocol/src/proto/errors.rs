//! The errors that cross the wire, and the checks of names and words that produce them.

use penelope_hal::{LifecycleState, Transition};
use serde::{Deserialize, Serialize};

use super::Class;
#[cfg(doc)]
use super::MAGIC;

/// Every error that crosses the wire: a failure of the protocol itself (framing, handshake,
/// limits of the connection), or the refusal of one call by what the node serves.
///
/// Encoded as postcard encodes an enum: the index of [`WireError::Protocol`] (0) or
/// [`WireError::Call`] (1), then the inner error's variant index and fields. New variants of
/// either inner enum are appended last, so every earlier one keeps its encoding.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
pub enum WireError {
    /// The connection or a frame broke the protocol.
    #[error(transparent)]
    Protocol(#[from] ProtocolError),
    /// The call was refused (unknown name, bad configuration, not ready, ...).
    #[error(transparent)]
    Call(#[from] CallError),
}

/// A failure of the protocol: framing, handshake, the connection's limits and timing. The
/// connection usually closes after one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
pub enum ProtocolError {
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
}

/// The refusal of one call by what the node serves (the creator, its objects, the naming
/// service): the connection stays open.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, thiserror::Error)]
pub enum CallError {
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
    /// The channel has both ends on this node: no data-plane link, so no link statistics to
    /// stream.
    #[error("`{0}` has both ends on this node: it has no data-plane link to watch")]
    NoLink(String),
}

impl WireError {
    /// The name of the variant of the inner error (`UnknownName`, `AuthFailed`, ...): the
    /// kind a client (the Python package's exception classes) tells errors apart by.
    pub fn kind(&self) -> &'static str {
        let (names, index) = match self {
            WireError::Protocol(p) => (protocol_error_kinds(), variant_index(p)),
            WireError::Call(c) => (call_error_kinds(), variant_index(c)),
        };
        names.get(index).copied().unwrap_or("Unknown")
    }
}

/// The names of the variants of [`ProtocolError`], in their wire order (read from the enum's
/// own `Deserialize`, so never out of step with it).
pub fn protocol_error_kinds() -> &'static [&'static str] {
    variants::of::<ProtocolError>()
}

/// The names of the variants of [`CallError`], in their wire order (read from the enum's own
/// `Deserialize`, so never out of step with it).
pub fn call_error_kinds() -> &'static [&'static str] {
    variants::of::<CallError>()
}

/// The postcard variant index of an enum value: its first byte (a varint below 128).
fn variant_index<T: Serialize>(value: &T) -> usize {
    postcard::to_allocvec(value)
        .ok()
        .and_then(|bytes| bytes.first().copied())
        .map_or(usize::MAX, usize::from)
}

/// The variant names a derived `Deserialize` of an enum hands to its deserializer.
mod variants {
    use serde::Deserialize;
    use serde::de::{self, Deserializer, Visitor};

    /// What the probing deserializer stops with: the names, or that it was not an enum.
    #[derive(Debug)]
    struct Found(Option<&'static [&'static str]>);

    impl std::fmt::Display for Found {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("variant names probed")
        }
    }

    impl std::error::Error for Found {}

    impl de::Error for Found {
        fn custom<T: std::fmt::Display>(_: T) -> Self {
            Found(None)
        }
    }

    /// A deserializer that reads nothing: asked for an enum, it fails with the enum's names.
    struct Probe;

    impl<'de> Deserializer<'de> for Probe {
        type Error = Found;

        fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Found> {
            Err(Found(None))
        }

        fn deserialize_enum<V: Visitor<'de>>(
            self,
            _name: &'static str,
            variants: &'static [&'static str],
            _visitor: V,
        ) -> Result<V::Value, Found> {
            Err(Found(Some(variants)))
        }

        serde::forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes
            byte_buf option unit unit_struct newtype_struct seq tuple tuple_struct map struct
            identifier ignored_any
        }
    }

    /// The variant names of enum `T` (empty for a type that is not an enum).
    pub(super) fn of<T: for<'de> Deserialize<'de>>() -> &'static [&'static str] {
        match T::deserialize(Probe) {
            Err(Found(Some(names))) => names,
            _ => &[],
        }
    }
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
/// [`CallError::BadName`] saying what is wrong.
pub fn check_name(name: &str) -> Result<(), WireError> {
    let bad = |reason: &str| {
        Err(WireError::Call(CallError::BadName {
            name: name.chars().take(80).collect(),
            reason: reason.to_string(),
        }))
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
