//! The client side of one connection to a node.
//!
//! SKELETON (lead): signatures are the contract; NET fills in the bodies.

use std::net::SocketAddr;
use std::time::Duration;

use crate::net::frame::FrameError;
use crate::proto::{Call, DEFAULT_MAX_FRAME, Reply, TelemetryBatch, WireError};

/// How a client connects.
#[derive(Clone, Debug)]
pub struct ClientConfig {
    /// The name sent in the hello.
    pub name: String,
    /// The shared secret, if the node requires one.
    pub secret: Option<Vec<u8>>,
    /// Connect and per-call timeout.
    pub timeout: Duration,
    /// Largest frame accepted, bytes.
    pub max_frame: usize,
}

impl ClientConfig {
    /// Defaults for a client named `name`.
    pub fn new(name: impl Into<String>) -> Self {
        ClientConfig {
            name: name.into(),
            secret: None,
            timeout: Duration::from_secs(5),
            max_frame: DEFAULT_MAX_FRAME,
        }
    }
}

/// What can go wrong with a remote call.
#[derive(Debug, thiserror::Error)]
pub enum RpcError {
    /// The socket failed.
    #[error("i/o: {0}")]
    Io(#[from] std::io::Error),
    /// A frame could not be read or written.
    #[error("{0}")]
    Frame(#[from] FrameError),
    /// The node answered with an error.
    #[error("{0}")]
    Remote(WireError),
    /// The node broke the protocol.
    #[error("protocol error: {0}")]
    Protocol(String),
    /// No answer in time.
    #[error("timed out")]
    Timeout,
}

impl From<RpcError> for WireError {
    fn from(e: RpcError) -> Self {
        match e {
            RpcError::Remote(w) => w,
            other => WireError::Remote(other.to_string()),
        }
    }
}

/// One connection to a node.
#[derive(Debug)]
pub struct Connection {
    node: String,
}

impl Connection {
    /// Connects, says hello and authenticates if asked.
    ///
    /// # Errors
    /// [`RpcError`].
    pub fn connect(addr: SocketAddr, config: &ClientConfig) -> Result<Connection, RpcError> {
        let _ = (addr, config);
        Err(RpcError::Protocol("skeleton".into()))
    }

    /// The node's name from its hello.
    pub fn node(&self) -> &str {
        &self.node
    }

    /// One call, waiting for its answer.
    ///
    /// # Errors
    /// [`RpcError::Remote`] for an error reply, others for transport failures.
    pub fn call(&mut self, call: Call) -> Result<Reply, RpcError> {
        let _ = call;
        Err(RpcError::Protocol("skeleton".into()))
    }

    /// Several calls sent back to back, then their answers in order.
    ///
    /// # Errors
    /// Transport failures; each call's own error is in its slot.
    pub fn call_many(
        &mut self,
        calls: Vec<Call>,
    ) -> Result<Vec<Result<Reply, WireError>>, RpcError> {
        let _ = calls;
        Err(RpcError::Protocol("skeleton".into()))
    }

    /// The next telemetry batch, waiting at most `timeout`.
    ///
    /// # Errors
    /// Transport failures.
    pub fn next_telemetry(
        &mut self,
        timeout: Duration,
    ) -> Result<Option<TelemetryBatch>, RpcError> {
        let _ = timeout;
        Err(RpcError::Protocol("skeleton".into()))
    }
}
