//! The TCP server of a node.
//!
//! SKELETON (lead): signatures are the contract; NET fills in the bodies.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use crate::proto::DEFAULT_MAX_FRAME;
use crate::service::Service;

/// How a server runs.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// The node's name (sent in the hello).
    pub node: String,
    /// The shared secret; required to bind anything but loopback.
    pub secret: Option<Vec<u8>>,
    /// Largest frame accepted, bytes.
    pub max_frame: usize,
    /// Connections served at once.
    pub max_connections: u32,
    /// Requests per second per connection (token bucket).
    pub max_requests_per_s: u32,
    /// Time allowed for the hello (and authentication).
    pub handshake_timeout: Duration,
    /// A connection silent this long is closed.
    pub idle_timeout: Duration,
    /// A client that does not take a frame within this time is dropped.
    pub write_timeout: Duration,
    /// Frames queued per connection before telemetry is dropped.
    pub outbox_capacity: usize,
}

impl ServerConfig {
    /// Defaults for `node`.
    pub fn new(node: impl Into<String>) -> Self {
        ServerConfig {
            node: node.into(),
            secret: None,
            max_frame: DEFAULT_MAX_FRAME,
            max_connections: 64,
            max_requests_per_s: 200_000,
            handshake_timeout: Duration::from_secs(5),
            idle_timeout: Duration::from_secs(300),
            write_timeout: Duration::from_secs(5),
            outbox_capacity: 256,
        }
    }
}

/// Why a server could not start.
#[derive(Debug, thiserror::Error)]
pub enum NetError {
    /// A non-loopback address without a shared secret.
    #[error(
        "refusing to listen on {0} without a shared secret (use a loopback address or give a secret)"
    )]
    SecretRequired(SocketAddr),
    /// The socket failed.
    #[error("i/o: {0}")]
    Io(#[from] std::io::Error),
}

/// Counters of a server.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ServerStats {
    /// Connections accepted.
    pub accepted: u64,
    /// Connections refused (limit).
    pub refused: u64,
    /// Connections open now.
    pub open: u64,
    /// Connections dropped for a protocol error, a timeout or the rate limit.
    pub dropped: u64,
    /// Requests served.
    pub requests: u64,
}

/// A running server.
#[derive(Debug)]
pub struct Server {
    addr: SocketAddr,
}

impl Server {
    /// Listens on `addr` and serves `service`.
    ///
    /// # Errors
    /// [`NetError`].
    pub fn bind(
        addr: SocketAddr,
        config: ServerConfig,
        service: Arc<dyn Service>,
    ) -> Result<Server, NetError> {
        let _ = (config, service);
        Ok(Server { addr })
    }

    /// The bound address (the real port when bound to port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Counters.
    pub fn stats(&self) -> ServerStats {
        ServerStats::default()
    }

    /// Stops accepting, closes connections and joins the threads.
    pub fn shutdown(self) {}
}
