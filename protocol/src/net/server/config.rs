//! How a server is configured ([`ServerConfig`]), how it fails to start ([`NetError`]) and what
//! it counts ([`ServerStats`]).

#[cfg(doc)]
use crate::proto::ProtocolError;
use std::net::SocketAddr;
use std::time::Duration;

use crate::net::auth::Secret;
use crate::proto::DEFAULT_MAX_FRAME;
#[cfg(doc)]
use crate::service::Service;

/// How a server runs.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// The node's name (sent in the hello).
    pub node: String,
    /// The shared secret; required to bind anything but loopback. When set (even on loopback),
    /// every client must authenticate and every frame is sealed.
    /// It must hold at least [`MIN_SECRET_BITS`](crate::net::auth::MIN_SECRET_BITS).
    pub secret: Option<Secret>,
    /// The admin secret (used only with `secret`): a client claiming
    /// [`Role::Admin`](crate::proto::Role::Admin) must prove it. Without it, such clients are
    /// served as operators. It must be as strong as `secret`.
    pub admin_secret: Option<Secret>,
    /// Largest frame accepted (and sent), bytes of body.
    pub max_frame: usize,
    /// Sessions (connections past their handshake) served at once.
    pub max_connections: u32,
    /// Of `max_connections`, the sessions kept for [`Role::Admin`](crate::proto::Role::Admin)
    /// clients.
    pub admin_reserve: u32,
    /// Connections in their handshake at once; at the bound the oldest is evicted.
    pub max_handshakes: u32,
    /// Connections in their handshake at once from one IP address; at the bound that address's
    /// oldest is evicted.
    pub max_handshakes_per_peer: u32,
    /// Sessions of one IP address that a full pool never evicts for another address (one
    /// address may hold more while there is room; see [`crate::net::limits`]).
    pub max_sessions_per_peer: u32,
    /// Failed handshakes one IP address may make at once before it is throttled.
    pub auth_failure_burst: u32,
    /// Failed handshakes per second one IP address may make after its burst: beyond it, its
    /// handshakes are refused with [`ProtocolError::RateLimited`] before
    /// the secret is checked.
    pub auth_failures_per_s: f64,
    /// Requests per second per connection (token bucket; bursts up to one second's worth).
    pub max_requests_per_s: u32,
    /// Time allowed for the hello (and authentication).
    pub handshake_timeout: Duration,
    /// A connection with no frame in either direction for this long is closed.
    pub idle_timeout: Duration,
    /// A client that does not take a frame within this time is dropped.
    pub write_timeout: Duration,
    /// Frames queued per connection before telemetry is dropped.
    pub outbox_capacity: usize,
}

impl ServerConfig {
    /// Defaults for `node`: 256 KiB frames, 64 sessions (4 of them for administrators, 16 per
    /// address safe from eviction), 32 handshakes at once (8 per address), 8 failed handshakes
    /// per address then 2 a second, 200 000 requests/s per connection, 5 s handshake, 300 s
    /// idle, 5 s write timeout, 256 queued frames.
    pub fn new(node: impl Into<String>) -> Self {
        ServerConfig {
            node: node.into(),
            secret: None,
            admin_secret: None,
            max_frame: DEFAULT_MAX_FRAME,
            max_connections: 64,
            admin_reserve: 4,
            max_handshakes: 32,
            max_handshakes_per_peer: 8,
            max_sessions_per_peer: 16,
            auth_failure_burst: 8,
            auth_failures_per_s: 2.0,
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
    /// An admin secret without the system secret: nobody could prove it (the plain protocol
    /// takes roles on trust), so the configuration is refused rather than silently weaker.
    #[error("an admin secret needs the shared secret too (give both, or neither)")]
    AdminSecretWithoutSecret,
    /// A secret too weak to hold off a guess (under
    /// [`MIN_SECRET_BITS`](crate::net::auth::MIN_SECRET_BITS)); the message says how to make one.
    #[error("{0}")]
    WeakSecret(String),
    /// The socket failed.
    #[error("i/o: {0}")]
    Io(#[from] std::io::Error),
}

/// Counters of a server (since it started).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ServerStats {
    /// Connections accepted.
    pub accepted: u64,
    /// Connections refused or evicted (limits).
    pub refused: u64,
    /// Connections open now.
    pub open: u64,
    /// Connections dropped for a protocol error, a timeout, the rate limit or a client that did
    /// not read.
    pub dropped: u64,
    /// Requests served (rate-limited ones not included).
    pub requests: u64,
    /// Sessions that passed the handshake (each ends with one [`Service::closed`]).
    pub sessions: u64,
    /// Frames received.
    pub frames_in: u64,
    /// Frames sent.
    pub frames_out: u64,
    /// Malformed frames, wrong hellos and frames that failed to open.
    pub malformed: u64,
    /// Frames refused for their announced length.
    pub too_large: u64,
    /// Failed authentications.
    pub auth_failures: u64,
    /// Handshake, idle and write timeouts.
    pub timeouts: u64,
    /// Requests refused by the rate limit.
    pub rate_limited: u64,
}
