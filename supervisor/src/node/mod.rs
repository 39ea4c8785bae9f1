//! A node: its creator and objects, and optionally the naming service, behind one server (the
//! paper's Penelope process, one per PC).
//!
//! At start only the creator exists: the node registers its context `/<node>` in the naming
//! service with a lease and binds its creator at `/<node>/creator`. Every object it creates is
//! bound at [`object_path`] (`/<node>/robots/slave`), every object it destroys is unbound. A
//! thread renews the lease every third of it; when the naming service forgot the node (its lease
//! lapsed, or the naming service restarted), the node registers again and re-binds everything.
//!
//! Nodes and the naming service start in any order: a node whose naming service does not answer
//! yet (or stops answering) says so once, keeps serving, retries with a growing backoff (from
//! [`REGISTER_RETRY_FIRST`] up to [`REGISTER_RETRY_MAX`]) and registers, binding every object it
//! holds, as soon as the naming service answers. Only answers that cannot change by waiting end
//! the start: a refused secret or a refused registration.
//!
//! The node is also how its objects reach objects of other nodes ([`Remote`]): a path is resolved
//! in the hosted tree or by the naming service (and cached briefly), then the object is called on
//! its node through a [`Client`] (one cached connection per node).
//!
//! # Objects at start
//! `penelope node --config FILE` brings up the objects a system file places on the node: see
//! [`crate::system`].
//!
//! # Layout
//! - this file: the node's configuration and errors, the [`Node`] handle (start, calls, stop)
//!   and the state its threads share;
//! - `node/naming_link.rs`: that shared state's link to the naming service (registration,
//!   renewal, bindings) and to other nodes' objects (resolution, remote calls);
//! - `node/service.rs`: what the node's server serves;
//! - `node/tests.rs`: the unit tests.

use std::collections::HashMap;
use std::fmt;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{self, Sender};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock, PoisonError, Weak};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::naming::{NamingLimits, NamingService, Reaper};
use crate::system::ApplyTarget;
use crate::zenoh_bridge::{BridgeStats, ZenohBridge, ZenohError, ZenohSettings};
use penelope_protocol::client::Client;
use penelope_protocol::net::conn::{ClientConfig, RpcError};
use penelope_protocol::net::server::{NetError, Server, ServerConfig, ServerStats};
#[cfg(doc)]
use penelope_protocol::proto::object_path;
use penelope_protocol::proto::{
    Call, CallError, NamingCall, ObjectRef, ProtocolError, Reply, WireError, check_name,
};
use penelope_protocol::service::{Remote, Service, Session};
use penelope_runtime::common_clock::CommonClock;
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::{Creator, CreatorConfig};

mod naming_link;
mod service;
#[cfg(test)]
mod tests;

use service::NodeService;

/// Where a node's naming service is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum NamingChoice {
    /// The node hosts the naming service itself (and registers in it).
    Host,
    /// The naming service answers at this address (another node, or `penelope naming`).
    Remote(SocketAddr),
    /// No naming service at all: nothing is registered or bound, remote paths do not resolve.
    /// For tests of a node alone.
    None,
}

/// How a node runs.
#[derive(Clone, Debug)]
pub struct NodeConfig {
    /// The node's name: its context `/<name>` in the naming tree (checked by [`check_name`]).
    pub name: String,
    /// Where the server listens (port 0: any free port). Anything but loopback needs `secret`.
    pub listen: SocketAddr,
    /// The address registered in the naming service (`host:port`); `None`: the bound address,
    /// with an unspecified IP (`0.0.0.0`) replaced by loopback, so set it when listening on
    /// every interface.
    pub advertise: Option<String>,
    /// Where the naming service is.
    pub naming: NamingChoice,
    /// The shared secret: required by this node's server (and by a hosted naming service), and
    /// sent to the other nodes and the naming service. At least
    /// [`MIN_SECRET_BITS`](penelope_protocol::net::auth::MIN_SECRET_BITS) (else the start fails).
    pub secret: Option<penelope_protocol::net::auth::Secret>,
    /// The lease in the naming service; renewed every third of it.
    pub lease: Duration,
    /// The creator's settings (`node` and `remote` are set by the node).
    pub creator: CreatorConfig,
    /// The server's settings (`node` and `secret` are set by the node).
    pub server: ServerConfig,
    /// Limits of a hosted naming tree.
    pub naming_limits: NamingLimits,
    /// Connect and per-call timeout of the node's own calls (naming, other nodes).
    pub call_timeout: Duration,
    /// How long a resolved path is reused before it is resolved again.
    pub resolve_ttl: Duration,
    /// The Zenoh bridge's settings (`None`: no bridge).
    pub zenoh: Option<ZenohSettings>,
    /// The node's ROS 2 presence on that bridge's session (`None`: none; needs `zenoh`).
    pub ros2: Option<crate::ros2::Ros2Settings>,
}

impl NodeConfig {
    /// Defaults for node `name` using the naming service `naming`: loopback on any free port, a
    /// 3 s lease, default creator and server limits.
    pub fn new(name: impl Into<String>, naming: NamingChoice) -> Self {
        let name = name.into();
        NodeConfig {
            listen: SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 0),
            advertise: None,
            naming,
            secret: None,
            lease: Duration::from_secs(3),
            creator: CreatorConfig::new(name.clone()),
            server: ServerConfig::new(name.clone()),
            naming_limits: NamingLimits::default(),
            call_timeout: Duration::from_secs(2),
            resolve_ttl: Duration::from_secs(1),
            zenoh: None,
            ros2: None,
            name,
        }
    }
}

/// The first wait before registering again when the naming service does not answer.
pub const REGISTER_RETRY_FIRST: Duration = Duration::from_millis(50);
/// The longest wait between two registration attempts (the backoff doubles up to it).
pub const REGISTER_RETRY_MAX: Duration = Duration::from_secs(1);

/// Why a node could not start.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// The node's name is not a valid naming component.
    #[error("bad node name: {0}")]
    BadName(WireError),
    /// The lease is outside what the naming service accepts.
    #[error("bad lease {0:?}: it must be between 10 ms and 1 h")]
    BadLease(Duration),
    /// The server could not listen.
    #[error("cannot listen: {0}")]
    Listen(#[from] NetError),
    /// The naming service answered but refused this node's credentials (no secret, or another
    /// one): waiting cannot fix that, so the start fails. (A naming service that does not answer
    /// yet is not an error: the node registers when it does.)
    #[error("the naming service at {address} refused the connection: {cause}")]
    NamingRefused {
        /// Its address.
        address: SocketAddr,
        /// What failed.
        cause: RpcError,
    },
    /// The naming service refused the registration (name taken by a live node, limits).
    #[error("the naming service refused to register the node: {0}")]
    Registration(WireError),
    /// The Zenoh bridge could not start (its error names Zenoh; said once, not twice).
    #[error(transparent)]
    Zenoh(#[from] ZenohError),
}

/// A running node.
pub struct Node {
    shared: Arc<Shared>,
    creator: Arc<Creator>,
    server: Option<Server>,
    renewer: Option<(Sender<()>, JoinHandle<()>)>,
    reaper: Option<Reaper>,
    zenoh: Option<ZenohBridge>,
    address: SocketAddr,
}

impl fmt::Debug for Node {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Node")
            .field("name", &self.shared.name)
            .field("address", &self.address)
            .field("advertised", &self.shared.advertised())
            .finish_non_exhaustive()
    }
}

/// What the node shares between its server, its renewal thread and its objects' remote calls.
struct Shared {
    name: String,
    lease: Duration,
    hosted: Option<Arc<NamingService>>,
    remote_naming: Option<SocketAddr>,
    /// Set once the server is bound.
    advertised: OnceLock<String>,
    /// Set once the server is bound (a client of the naming service and of the other nodes).
    client: OnceLock<Client>,
    /// Whether the naming service holds the node's registration (as far as the node knows).
    registered: AtomicBool,
    /// Whether the naming service's silence was reported (reported once until it answers).
    silence_reported: AtomicBool,
    /// The creator, for calls to this node's own objects (weak: the creator holds this as its
    /// [`Remote`]).
    creator: Weak<Creator>,
    /// Serializes "change the creator, then the naming tree" against "register again and
    /// re-bind", so the tree ends up matching the creator.
    ops: Mutex<()>,
    /// Resolved paths and when they were resolved.
    resolved: Mutex<HashMap<String, (ObjectRef, Instant)>>,
    resolve_ttl: Duration,
    /// The system's common clock (the naming service's host's), estimated by the registration
    /// thread.
    common_clock: CommonClock,
}

/// Whether a refusal by the naming service at start is final (waiting cannot change it): wrong
/// credentials or protocol, a name taken by a live node or malformed. Busy answers (too many
/// connections, rate limits, time-outs) are retried.
fn refusal_is_final(refused: &WireError) -> bool {
    matches!(
        refused,
        WireError::Protocol(ProtocolError::AuthFailed)
            | WireError::Protocol(ProtocolError::BadMagic)
            | WireError::Protocol(ProtocolError::VersionMismatch { .. })
            | WireError::Call(CallError::NameTaken(_))
            | WireError::Call(CallError::BadName { .. })
            | WireError::Call(CallError::Forbidden(_))
    )
}

/// A node's name, and its lease when it uses a naming service (within the service's limits,
/// 10 ms to an hour at most).
fn check_config(config: &NodeConfig) -> Result<(), NodeError> {
    check_name(&config.name).map_err(NodeError::BadName)?;
    let limits = config.naming_limits;
    if config.naming != NamingChoice::None
        && (config.lease < limits.min_lease.max(Duration::from_millis(10))
            || config.lease > limits.max_lease.min(Duration::from_secs(3600)))
    {
        return Err(NodeError::BadLease(config.lease));
    }
    Ok(())
}

/// The node's creator, with the data plane's key from the node's secret, and the common
/// clock it keeps.
fn new_creator(
    mut creator_config: CreatorConfig,
    name: &str,
    secret: Option<&penelope_protocol::net::auth::Secret>,
    remote_naming: Option<SocketAddr>,
) -> (Arc<Creator>, CommonClock) {
    creator_config.node = name.to_string();
    // The data plane's datagrams are authenticated with a key from the same secret.
    if let Some(secret) = secret {
        creator_config.datagram_key =
            Some(penelope_runtime::dataplane::frame::DatagramKey::from_secret(secret.bytes()));
    }
    // The common clock: the naming service's host's, when it is another process on the
    // real clock.
    let common_clock = match remote_naming {
        Some(address) if creator_config.clock == ClockMode::RealTime => {
            CommonClock::of_naming(address)
        }
        _ => CommonClock::own(),
    };
    creator_config.common_clock = common_clock.clone();
    (Arc::new(Creator::new(creator_config)), common_clock)
}

/// The address registered in the naming tree: `advertise`, else the bound address (loopback
/// for an unspecified one).
fn advertised_address(advertise: Option<String>, bound: SocketAddr) -> String {
    advertise.unwrap_or_else(|| {
        let mut a = bound;
        if a.ip().is_unspecified() {
            a.set_ip(IpAddr::V4(Ipv4Addr::LOCALHOST));
        }
        a.to_string()
    })
}

/// The first registration. A silent naming service is waited for (the registration thread
/// retries); a refusal is final.
fn first_registration(shared: &Shared, naming_address: SocketAddr) -> Result<(), NodeError> {
    match shared.register() {
        Ok(()) => Ok(()),
        Err(RpcError::Remote(refused)) if refusal_is_final(&refused) => Err(match refused {
            WireError::Call(CallError::NameTaken(_))
            | WireError::Call(CallError::BadName { .. }) => NodeError::Registration(refused),
            other => NodeError::NamingRefused {
                address: naming_address,
                cause: RpcError::Remote(other),
            },
        }),
        // It does not prove the secret this node holds: nothing was sent, waiting cannot fix it.
        Err(cause @ RpcError::Unauthenticated(_)) => Err(NodeError::NamingRefused {
            address: naming_address,
            cause,
        }),
        // Silent (said once by `lost_naming`) or busy: the registration thread retries.
        Err(_) => Ok(()),
    }
}

/// Starts the thread that renews the node's lease every `period` (none when it cannot be
/// spawned: said in the log).
fn start_renewer(shared: &Arc<Shared>, period: Duration) -> Option<(Sender<()>, JoinHandle<()>)> {
    let (stop, rx) = mpsc::channel::<()>();
    let renewing = shared.clone();
    let name = &shared.name;
    let spawned = std::thread::Builder::new()
        .name(format!("lease-{name}"))
        .spawn(move || renewing.keep_registered(&rx, period));
    match spawned {
        Ok(handle) => Some((stop, handle)),
        Err(e) => {
            log::error!("node {name}: cannot spawn the lease renewal thread: {e}");
            None
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

fn local_session(name: &str) -> Session {
    Session::in_process(name)
}

impl ApplyTarget for Node {
    fn node_name(&self) -> &str {
        self.name()
    }

    fn node_call(&self, call: Call) -> Result<Reply, WireError> {
        self.call(call)
    }
}

impl Node {
    /// Starts a node: the server listens, the node registers in the naming service and binds its
    /// creator at `/<node>/creator`, and the lease renewal thread runs.
    ///
    /// # Errors
    /// [`NodeError`]: a bad name or lease, the address cannot be bound (or is not loopback and
    /// there is no secret), the naming service cannot be reached or refuses the registration.
    pub fn start(config: NodeConfig) -> Result<Node, NodeError> {
        check_config(&config)?;
        let name = config.name.clone();
        let hosted = (config.naming == NamingChoice::Host)
            .then(|| Arc::new(NamingService::new(name.clone(), config.naming_limits)));
        let remote_naming = match config.naming {
            NamingChoice::Remote(a) => Some(a),
            _ => None,
        };
        let (creator, common_clock) =
            new_creator(config.creator, &name, config.secret.as_ref(), remote_naming);
        // First of what the node runs: a bridge that cannot start leaves nothing to undo.
        let zenoh = match &config.zenoh {
            Some(settings) => Some(ZenohBridge::start(
                &name,
                Arc::downgrade(&creator),
                settings,
                config.ros2,
            )?),
            None if config.ros2.is_some() => {
                return Err(ZenohError::Config(
                    "a ROS 2 presence runs on the Zenoh bridge: set `zenoh` too".into(),
                )
                .into());
            }
            None => None,
        };
        let shared = Arc::new(Shared {
            name: name.clone(),
            lease: config.lease,
            hosted: hosted.clone(),
            remote_naming,
            advertised: OnceLock::new(),
            client: OnceLock::new(),
            registered: AtomicBool::new(false),
            silence_reported: AtomicBool::new(false),
            creator: Arc::downgrade(&creator),
            ops: Mutex::new(()),
            resolved: Mutex::new(HashMap::new()),
            resolve_ttl: config.resolve_ttl,
            common_clock,
        });
        creator.set_remote(shared.clone());

        let mut server_config = config.server;
        server_config.node = name.clone();
        server_config.secret = config.secret.clone();
        let service = Arc::new(NodeService {
            shared: shared.clone(),
            creator: creator.clone(),
        });
        let server = Server::bind(config.listen, server_config, service)?;
        let address = server.local_addr();
        let _ = shared
            .advertised
            .set(advertised_address(config.advertise, address));

        let mut client_config = ClientConfig::node(name.clone());
        client_config.secret = config.secret;
        client_config.timeout = config.call_timeout;
        let naming_address = remote_naming.unwrap_or(address);
        let _ = shared
            .client
            .set(Client::lazy(naming_address, client_config));

        if let Err(e) = first_registration(&shared, naming_address) {
            creator.shutdown();
            server.shutdown();
            return Err(e);
        }
        let reaper = hosted.as_ref().and_then(|s| {
            s.start_reaper(Duration::from_millis(100))
                .map_err(|e| log::warn!("node {name}: no naming reaper thread: {e}"))
                .ok()
        });
        let renewer = if shared.uses_naming() {
            start_renewer(&shared, config.lease / 3)
        } else {
            None
        };
        Ok(Node {
            shared,
            creator,
            server: Some(server),
            renewer,
            reaper,
            zenoh,
            address,
        })
    }

    /// The node's name.
    pub fn name(&self) -> &str {
        &self.shared.name
    }

    /// The address the server is bound to (the real port when started on port 0).
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// The address registered in the naming service (`host:port`).
    pub fn advertised(&self) -> &str {
        self.shared.advertised()
    }

    /// Whether the naming service holds this node's registration, as far as the node knows
    /// (false while the naming service does not answer; a node without naming is never
    /// registered).
    pub fn is_registered(&self) -> bool {
        self.shared.uses_naming() && self.shared.registered()
    }

    /// The node's naming context, `/<name>`.
    pub fn context(&self) -> String {
        format!("/{}", self.shared.name)
    }

    /// The node's creator.
    pub fn creator(&self) -> &Creator {
        &self.creator
    }

    /// The naming service this node hosts, if it does.
    pub fn hosted_naming(&self) -> Option<&Arc<NamingService>> {
        self.shared.hosted.as_ref()
    }

    /// What the Zenoh bridge did so far (`None`: the node runs none).
    pub fn zenoh_stats(&self) -> Option<BridgeStats> {
        self.zenoh.as_ref().map(ZenohBridge::stats)
    }

    /// The server's counters.
    pub fn stats(&self) -> ServerStats {
        self.server.as_ref().map(Server::stats).unwrap_or_default()
    }

    /// Serves `call` as if a client had sent it over a connection (object creation binds the
    /// object in the naming tree, exactly as over the wire).
    ///
    /// # Errors
    /// The call's typed error.
    pub fn call(&self, call: Call) -> Result<Reply, WireError> {
        let service = NodeService {
            shared: self.shared.clone(),
            creator: self.creator.clone(),
        };
        let session = local_session(&self.shared.name);
        let result = service.call(&session, call);
        service.closed(&session);
        result
    }

    /// The node's [`Remote`]: calls an object anywhere by its naming path.
    pub fn remote(&self) -> Arc<dyn Remote> {
        self.shared.clone()
    }

    /// Stops the node: the lease renewal, the server (no new calls), every loop safely
    /// (amplifiers off, threads joined), then unregisters from the naming service (removing
    /// every entry of the node).
    pub fn shutdown(mut self) {
        self.stop(true);
    }

    /// Stops serving and renewing WITHOUT unregistering, as if the process had crashed (for
    /// tests of lease expiry). The loops are still stopped and joined.
    pub fn kill(mut self) {
        self.stop(false);
    }

    fn stop(&mut self, unregister: bool) {
        if let Some((stop, handle)) = self.renewer.take() {
            let _ = stop.send(());
            let _ = handle.join();
        }
        if let Some(server) = self.server.take() {
            server.shutdown();
        }
        // Before the loops stop: no operator pose arrives while they go to their safe state.
        if let Some(bridge) = self.zenoh.take() {
            bridge.stop();
        }
        self.creator.shutdown();
        if unregister && self.shared.uses_naming() && self.shared.registered() {
            let _ops = lock(&self.shared.ops);
            match self.shared.naming(NamingCall::Unregister {
                node: self.shared.name.clone(),
            }) {
                Ok(_) | Err(WireError::Call(CallError::UnknownName(_))) => {}
                Err(e) => log::warn!("node {}: cannot unregister: {e}", self.shared.name),
            }
        }
        if let Some(reaper) = self.reaper.take() {
            reaper.stop();
        }
    }
}

impl Drop for Node {
    fn drop(&mut self) {
        if self.server.is_some() {
            self.stop(true);
        }
    }
}
