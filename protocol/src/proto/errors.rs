//! The errors that cross the wire, and the checks of names and words that produce them.

use penelope_hal::{LifecycleState, Transition};
use serde::{Deserialize, Serialize};

use super::Class;
#[cfg(doc)]
use super::MAGIC;

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
    /// The channel has both ends on this node: no data-plane link, so no link statistics to
    /// stream (appended last, so every earlier variant keeps its encoding).
    #[error("`{0}` has both ends on this node: it has no data-plane link to watch")]
    NoLink(String),
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
