//! What can go wrong in the creator and its objects ([`ObjectError`]), and the one place those
//! errors become the wire's call errors (`impl From<ObjectError> for WireError`): the service
//! boundary, where the node (or a creator served alone) answers a call.
//!
//! Errors carry values (names, classes, states, limits) and their source errors (a board's, a
//! file's, a thread's); the text a client reads is made from them only at that boundary.

use std::borrow::Cow;
use std::path::PathBuf;

use penelope_hal::{LifecycleState, Transition};
use penelope_protocol::proto::{CallError, Class, WireError};

use super::files::FileRefused;

/// A source error of any type (a driver's, a socket's), kept as the cause of an [`ObjectError`].
pub type SourceError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// An error of the creator or one of its objects.
#[derive(Debug, thiserror::Error)]
pub enum ObjectError {
    // Registry: names, kinds, classes, limits, rights.
    /// No kind of that name.
    #[error("unknown kind `{0}` (see `kinds`)")]
    UnknownKind(String),
    /// No object (or subscription) of that name.
    #[error("unknown name `{0}`")]
    UnknownName(String),
    /// The name is already used.
    #[error("name `{0}` is already taken")]
    NameTaken(String),
    /// A limit on objects or subscriptions was reached.
    #[error("limit reached: {what} (at most {limit})")]
    LimitReached {
        /// What is limited.
        what: Cow<'static, str>,
        /// The limit.
        limit: u32,
    },
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
    /// The object's kind does not support this method.
    #[error("`{kind}` does not support {method}")]
    Unsupported {
        /// The object's kind (or `creator`).
        kind: String,
        /// The method.
        method: Cow<'static, str>,
    },
    /// The creator hosts no naming service.
    #[error("this node does not host the naming service")]
    NoNamingService,
    /// The session's role may not make this call.
    #[error("forbidden: {0}")]
    Forbidden(String),

    // Configuration and arguments.
    /// The configuration does not fit the kind.
    #[error("bad configuration for `{kind}`: {message}")]
    BadConfig {
        /// The kind.
        kind: String,
        /// What is wrong.
        message: String,
    },
    /// A recording played back (`sensor/replay`, `sensor/operator-replay`) cannot be used.
    #[error("bad configuration for `{kind}`: {source}")]
    Replay {
        /// The replay's kind.
        kind: String,
        /// Why its recording cannot be played.
        #[source]
        source: ReplayError,
    },
    /// A robot cannot be on its `board/fpga` (not the FRHC, or its chain split between boards).
    #[error("bad configuration for `board/fpga`: {0}")]
    FpgaBoard(#[from] super::fpga_board::FpgaBoardError),
    /// An argument is out of range or of the wrong size.
    #[error("bad argument: {0}")]
    BadArgument(String),
    /// A file the call names was refused (not a plain name, exists, no directory, ...).
    #[error("bad argument: {0}")]
    File(#[from] FileRefused),

    // Lifecycle and loops.
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
    /// The channel has both ends on this node: it has no data-plane link.
    #[error("`{0}` has both ends on this node: it has no data-plane link to watch")]
    NoLink(String),

    // Devices, threads and the node's own faults.
    /// A device (board, sensor, socket, recorder) failed.
    #[error("device error: {what}: {source}")]
    Device {
        /// Which device, and what was being done.
        what: String,
        /// The device's error.
        #[source]
        source: SourceError,
    },
    /// A device answered, but not as it should (wrong axis count, wrong sample rate, ...).
    #[error("device error: {0}")]
    DeviceRefused(String),
    /// A thread the object needs could not be started.
    #[error("internal error: {what}: {source}")]
    Thread {
        /// Which thread.
        what: Cow<'static, str>,
        /// Why it did not start.
        #[source]
        source: SourceError,
    },
    /// A recording could not be started with these streams (the recorder refused them).
    #[error("bad argument: {0}")]
    RecordingRefused(#[source] SourceError),
    /// The recorder failed while writing or closing its file.
    #[error("device error: {0}")]
    Recorder(#[source] SourceError),
    /// A lock was poisoned by a thread that panicked while holding it.
    #[error("internal error: {0} poisoned")]
    Poisoned(&'static str),
    /// A bug: the creator could not do what it should have (an object's body is not what its
    /// kind says, ...).
    #[error("internal error: {0}")]
    Internal(Cow<'static, str>),

    // Other nodes.
    /// A remote object answered, but not as the call expects.
    #[error("remote call failed: {0}")]
    RemoteAnswer(String),
    /// An error that already is a wire error where it arises: a kind's configuration check
    /// (the kinds speak the wire error), a name check, or a remote object's own error,
    /// passed on unchanged.
    #[error(transparent)]
    Wire(#[from] WireError),
}

impl ObjectError {
    /// An [`ObjectError::Internal`] for a fixed description of the bug.
    pub(crate) const fn internal(what: &'static str) -> ObjectError {
        ObjectError::Internal(Cow::Borrowed(what))
    }

    /// An [`ObjectError::Thread`]: thread `what` could not be started, because of `source`.
    pub(crate) fn thread(
        what: impl Into<Cow<'static, str>>,
        source: impl Into<SourceError>,
    ) -> ObjectError {
        ObjectError::Thread {
            what: what.into(),
            source: source.into(),
        }
    }

    /// An [`ObjectError::Device`]: `what` failed with `source`.
    pub(crate) fn device(what: impl Into<String>, source: impl Into<SourceError>) -> ObjectError {
        ObjectError::Device {
            what: what.into(),
            source: source.into(),
        }
    }
}

/// The one conversion of the creator's errors into the wire's: the call error a client reads
/// (an error that already was a wire error passes unchanged).
impl From<ObjectError> for WireError {
    fn from(e: ObjectError) -> WireError {
        WireError::Call(match e {
            ObjectError::Wire(wire) => return wire,
            ObjectError::UnknownKind(kind) => CallError::UnknownKind(kind),
            ObjectError::UnknownName(name) => CallError::UnknownName(name),
            ObjectError::NameTaken(name) => CallError::NameTaken(name),
            ObjectError::LimitReached { what, limit } => CallError::LimitReached {
                what: what.into_owned(),
                limit,
            },
            ObjectError::WrongClass {
                name,
                expected,
                found,
            } => CallError::WrongClass {
                name,
                expected,
                found,
            },
            ObjectError::Unsupported { kind, method } => CallError::Unsupported {
                kind,
                method: method.into_owned(),
            },
            ObjectError::NoNamingService => CallError::NoNamingService,
            ObjectError::Forbidden(why) => CallError::Forbidden(why),
            ObjectError::BadConfig { kind, message } => CallError::BadConfig { kind, message },
            ObjectError::Replay { kind, source } => CallError::BadConfig {
                kind,
                message: source.to_string(),
            },
            ObjectError::FpgaBoard(refused) => CallError::BadConfig {
                kind: "board/fpga".into(),
                message: refused.to_string(),
            },
            ObjectError::BadArgument(why) => CallError::BadArgument(why),
            ObjectError::File(refused) => CallError::BadArgument(refused.to_string()),
            ObjectError::RecordingRefused(source) => CallError::BadArgument(source.to_string()),
            ObjectError::InvalidTransition {
                name,
                state,
                transition,
            } => CallError::InvalidTransition {
                name,
                state,
                transition,
            },
            ObjectError::InUse { name, dependents } => CallError::InUse { name, dependents },
            ObjectError::NotReady(why) => CallError::NotReady(why),
            ObjectError::NoLink(name) => CallError::NoLink(name),
            ObjectError::Device { what, source } => CallError::Device(format!("{what}: {source}")),
            ObjectError::DeviceRefused(why) => CallError::Device(why),
            ObjectError::Recorder(source) => CallError::Device(source.to_string()),
            ObjectError::Thread { what, source } => {
                CallError::Internal(format!("{what}: {source}"))
            }
            ObjectError::Poisoned(what) => CallError::Internal(format!("{what} poisoned")),
            ObjectError::Internal(what) => CallError::Internal(what.into_owned()),
            ObjectError::RemoteAnswer(why) => CallError::Remote(why),
        })
    }
}

/// Why a recording cannot be replayed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// No file at the path.
    #[error("{path}: no such recording")]
    MissingFile {
        /// The path.
        path: PathBuf,
    },
    /// The file is not a readable recording.
    #[error(transparent)]
    Unreadable(#[from] super::recording::RecordingError),
    /// The recording has no such channel.
    #[error("{path}: no channel {topic} (it has: {available})")]
    MissingTopic {
        /// The file.
        path: PathBuf,
        /// The channel asked for.
        topic: String,
        /// The controller channels it has, comma-separated.
        available: String,
    },
    /// The channel has no ticks.
    #[error("{path}: channel {topic} holds no ticks")]
    Empty {
        /// The file.
        path: PathBuf,
        /// The channel.
        topic: String,
    },
    /// A tick has no plant truth (a real board's recording): no motion to replay.
    #[error("{path}: tick {seq} of {topic} has no plant truth (recorded on a real board?)")]
    NoTruth {
        /// The file.
        path: PathBuf,
        /// The channel.
        topic: String,
        /// The tick's sequence number.
        seq: u64,
    },
    /// A value to replay is NaN or infinite.
    #[error("{path}: tick {seq} of {topic} has a NaN or infinite {field}")]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// The channel.
        topic: String,
        /// The tick's sequence number.
        seq: u64,
        /// The field.
        field: String,
    },
    /// Ticks out of time order.
    #[error("{path}: tick {seq} of {topic} is earlier than the tick before it")]
    OutOfOrder {
        /// The file.
        path: PathBuf,
        /// The channel.
        topic: String,
        /// The tick's sequence number.
        seq: u64,
    },
}

impl ReplayError {
    /// The error as the creator reports it: the configuration of `kind` refused, for this
    /// reason.
    pub fn for_kind(self, kind: &str) -> ObjectError {
        ObjectError::Replay {
            kind: kind.into(),
            source: self,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One error of every variant; the `match` below has no wildcard, so a new variant does not
    /// compile until it has a sample here.
    fn one_of_each() -> Vec<ObjectError> {
        let source = || -> SourceError { Box::new(std::io::Error::other("the cause")) };
        let samples = vec![
            ObjectError::UnknownKind("board/x".into()),
            ObjectError::UnknownName("arm".into()),
            ObjectError::NameTaken("arm".into()),
            ObjectError::LimitReached {
                what: "objects".into(),
                limit: 256,
            },
            ObjectError::WrongClass {
                name: "arm".into(),
                expected: Class::Board,
                found: Class::Robot,
            },
            ObjectError::Unsupported {
                kind: "board/sim".into(),
                method: "fk".into(),
            },
            ObjectError::NoNamingService,
            ObjectError::Forbidden("a reader may not create".into()),
            ObjectError::BadConfig {
                kind: "board/sim".into(),
                message: "`axes` = 9 is outside 1..=8".into(),
            },
            ObjectError::Replay {
                kind: "sensor/replay".into(),
                source: ReplayError::MissingFile {
                    path: "run.mcap".into(),
                },
            },
            ObjectError::FpgaBoard(super::super::fpga_board::FpgaBoardError::NotTheFrhc {
                board: "fk".into(),
                robot: "arm".into(),
                model: "PUMA 560".into(),
            }),
            ObjectError::BadArgument("no such joint".into()),
            ObjectError::File(FileRefused::NotPlainName("../x".into())),
            ObjectError::InvalidTransition {
                name: "arm".into(),
                state: LifecycleState::Unconfigured,
                transition: Transition::Activate,
            },
            ObjectError::InUse {
                name: "arm".into(),
                dependents: vec!["follow".into()],
            },
            ObjectError::NotReady("not configured".into()),
            ObjectError::NoLink("teleop".into()),
            ObjectError::Device {
                what: "board `galil`".into(),
                source: source(),
            },
            ObjectError::DeviceRefused("4 axes, not 6".into()),
            ObjectError::Thread {
                what: "control thread".into(),
                source: source(),
            },
            ObjectError::RecordingRefused(source()),
            ObjectError::Recorder(source()),
            ObjectError::Poisoned("registry"),
            ObjectError::Internal("robot body".into()),
            ObjectError::RemoteAnswer("node b: timeout".into()),
            ObjectError::Wire(WireError::Call(CallError::NotReady("remote".into()))),
        ];
        for e in &samples {
            match e {
                ObjectError::UnknownKind(_)
                | ObjectError::UnknownName(_)
                | ObjectError::NameTaken(_)
                | ObjectError::LimitReached { .. }
                | ObjectError::WrongClass { .. }
                | ObjectError::Unsupported { .. }
                | ObjectError::NoNamingService
                | ObjectError::Forbidden(_)
                | ObjectError::BadConfig { .. }
                | ObjectError::Replay { .. }
                | ObjectError::FpgaBoard(_)
                | ObjectError::BadArgument(_)
                | ObjectError::File(_)
                | ObjectError::InvalidTransition { .. }
                | ObjectError::InUse { .. }
                | ObjectError::NotReady(_)
                | ObjectError::NoLink(_)
                | ObjectError::Device { .. }
                | ObjectError::DeviceRefused(_)
                | ObjectError::Thread { .. }
                | ObjectError::RecordingRefused(_)
                | ObjectError::Recorder(_)
                | ObjectError::Poisoned(_)
                | ObjectError::Internal(_)
                | ObjectError::RemoteAnswer(_)
                | ObjectError::Wire(_) => {}
            }
        }
        samples
    }

    /// The text a client reads is the text the runtime's error says: the conversion to the wire
    /// error keeps it, for every variant (the two enums' messages cannot drift apart).
    #[test]
    fn every_object_error_reads_the_same_on_the_wire() {
        let samples = one_of_each();
        assert_eq!(samples.len(), 26, "one sample per variant");
        for e in samples {
            let here = e.to_string();
            let wire = WireError::from(e);
            assert!(
                matches!(wire, WireError::Call(_)),
                "{here}: a call failure, not a protocol one"
            );
            assert_eq!(wire.to_string(), here);
        }
    }
}
