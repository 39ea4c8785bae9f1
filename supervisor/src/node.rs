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

use std::collections::HashMap;
use std::fmt;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock, PoisonError, Weak};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::client::Client;
use crate::naming::{NamingLimits, NamingService, Reaper};
use crate::net::conn::{ClientConfig, RpcError};
use crate::net::server::{NetError, Server, ServerConfig, ServerStats};
use crate::objects::{Creator, CreatorConfig};
use crate::proto::{
    Call, Class, CreatorCall, Method, NamingCall, NodeInfo, ObjectInfo, ObjectRef, Reply,
    WireError, check_name, object_path,
};
use crate::service::{Remote, Service, Session};

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
    /// sent to the other nodes and the naming service.
    pub secret: Option<Vec<u8>>,
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
}

/// A running node.
pub struct Node {
    shared: Arc<Shared>,
    creator: Arc<Creator>,
    server: Option<Server>,
    renewer: Option<(Sender<()>, JoinHandle<()>)>,
    reaper: Option<Reaper>,
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
}

/// Whether a refusal by the naming service at start is final (waiting cannot change it): wrong
/// credentials or protocol, a name taken by a live node or malformed. Busy answers (too many
/// connections, rate limits, time-outs) are retried.
fn refusal_is_final(refused: &WireError) -> bool {
    matches!(
        refused,
        WireError::AuthFailed
            | WireError::BadMagic
            | WireError::VersionMismatch { .. }
            | WireError::NameTaken(_)
            | WireError::BadName { .. }
            | WireError::Forbidden(_)
    )
}

/// Most resolved paths cached at once.
const MAX_RESOLVED: usize = 256;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

fn local_session(name: &str) -> Session {
    Session::in_process(name)
}

impl Shared {
    fn advertised(&self) -> &str {
        self.advertised.get().map_or("", String::as_str)
    }

    fn uses_naming(&self) -> bool {
        self.hosted.is_some() || self.remote_naming.is_some()
    }

    fn registered(&self) -> bool {
        self.registered.load(Ordering::Acquire)
    }

    /// One call to the naming service (hosted or remote), with transport failures kept apart
    /// from the naming service's answers ([`RpcError::Remote`]).
    fn naming_rpc(&self, call: NamingCall) -> Result<Reply, RpcError> {
        if let Some(service) = &self.hosted {
            return service.handle(call).map_err(RpcError::Remote);
        }
        match (self.remote_naming, self.client.get()) {
            (Some(address), Some(client)) => client.call_at(address, Call::Naming(call)),
            (Some(_), None) => Err(RpcError::Remote(WireError::NotReady(
                "the node is starting".into(),
            ))),
            (None, _) => Err(RpcError::Remote(WireError::NoNamingService)),
        }
    }

    /// One call to the naming service (hosted or remote).
    fn naming(&self, call: NamingCall) -> Result<Reply, WireError> {
        self.naming_rpc(call).map_err(WireError::from)
    }

    fn naming_address(&self) -> String {
        self.remote_naming
            .map_or_else(|| "(hosted)".to_string(), |a| a.to_string())
    }

    /// The naming service stopped answering: registering again is the registration thread's
    /// job from now on. Said once until it answers again.
    fn lost_naming(&self, cause: &RpcError) {
        self.registered.store(false, Ordering::Release);
        if !self.silence_reported.swap(true, Ordering::AcqRel) {
            log::warn!(
                "node {}: the naming service at {} does not answer ({cause}); serving on and \
                 registering as soon as it answers",
                self.name,
                self.naming_address()
            );
        }
    }

    fn reference(&self, info: &ObjectInfo) -> ObjectRef {
        ObjectRef {
            node: self.name.clone(),
            address: self.advertised().to_string(),
            name: info.name.clone(),
            class: info.class,
            kind: info.kind.clone(),
        }
    }

    fn creator_reference(&self) -> ObjectRef {
        ObjectRef {
            node: self.name.clone(),
            address: self.advertised().to_string(),
            name: "creator".into(),
            class: Class::Creator,
            kind: "creator".into(),
        }
    }

    /// Binds `info` in the naming tree. While the naming service does not answer, binding waits
    /// for the next registration (which binds every object), so only a refusal is an error.
    fn bind(&self, info: &ObjectInfo) -> Result<(), WireError> {
        if !self.uses_naming() || !self.registered() {
            return Ok(());
        }
        match self.naming_rpc(NamingCall::Bind {
            path: object_path(&self.name, info.class, &info.name),
            reference: self.reference(info),
            // The node owns its context: whatever is there is a stale entry of its own.
            rebind: true,
        }) {
            Ok(_) => Ok(()),
            Err(RpcError::Remote(refused)) => Err(refused),
            Err(transport) => {
                self.lost_naming(&transport);
                Ok(())
            }
        }
    }

    fn unbind(&self, info: &ObjectInfo) {
        if !self.uses_naming() {
            return;
        }
        let path = object_path(&self.name, info.class, &info.name);
        lock(&self.resolved).remove(&path);
        match self.naming(NamingCall::Unbind { path: path.clone() }) {
            Ok(_) | Err(WireError::UnknownName(_)) => {}
            Err(e) => log::warn!("node {}: cannot unbind {path}: {e}", self.name),
        }
    }

    /// Registers the node and binds its creator and every object (at start, when the naming
    /// service first answers, and after the lease lapsed). Holds `ops`.
    fn register(&self) -> Result<(), RpcError> {
        if !self.uses_naming() {
            return Ok(());
        }
        let _ops = lock(&self.ops);
        let result = self.register_and_bind();
        match &result {
            Ok(()) => {
                self.registered.store(true, Ordering::Release);
                if self.silence_reported.swap(false, Ordering::AcqRel) {
                    log::warn!(
                        "node {}: registered in the naming service at {}",
                        self.name,
                        self.naming_address()
                    );
                }
            }
            Err(RpcError::Remote(_)) => self.registered.store(false, Ordering::Release),
            Err(transport) => self.lost_naming(transport),
        }
        result
    }

    fn register_and_bind(&self) -> Result<(), RpcError> {
        self.naming_rpc(NamingCall::Register {
            node: self.name.clone(),
            address: self.advertised().to_string(),
            lease_ms: u32::try_from(self.lease.as_millis()).unwrap_or(u32::MAX),
        })?;
        self.naming_rpc(NamingCall::Bind {
            path: object_path(&self.name, Class::Creator, ""),
            reference: self.creator_reference(),
            rebind: true,
        })?;
        if let Some(creator) = self.creator.upgrade() {
            for info in creator.list() {
                self.naming_rpc(NamingCall::Bind {
                    path: object_path(&self.name, info.class, &info.name),
                    reference: self.reference(&info),
                    rebind: true,
                })?;
            }
        }
        Ok(())
    }

    /// One renewal; registers again if the naming service forgot the node (its lease lapsed,
    /// or it restarted).
    fn renew(&self) {
        match self.naming_rpc(NamingCall::Renew {
            node: self.name.clone(),
        }) {
            Ok(_) => {}
            Err(RpcError::Remote(WireError::UnknownName(_))) => {
                log::warn!(
                    "node {}: the naming service forgot this node (lease lapsed or restart); \
                     registering again",
                    self.name
                );
                if let Err(e) = self.register() {
                    log::warn!("node {}: registering again failed: {e}", self.name);
                }
            }
            Err(RpcError::Remote(e)) => {
                log::warn!("node {}: lease renewal refused: {e}", self.name);
            }
            Err(transport) => self.lost_naming(&transport),
        }
    }

    /// The registration thread: renews the lease every `period` while registered; otherwise
    /// tries to register with a doubling backoff, until `stop` says stop.
    fn keep_registered(&self, stop: &mpsc::Receiver<()>, period: Duration) {
        let mut backoff = REGISTER_RETRY_FIRST;
        loop {
            let wait = if self.registered() { period } else { backoff };
            match stop.recv_timeout(wait) {
                Err(RecvTimeoutError::Timeout) => {}
                Ok(()) | Err(RecvTimeoutError::Disconnected) => return,
            }
            if self.registered() {
                self.renew();
                backoff = REGISTER_RETRY_FIRST;
            } else if let Err(e) = self.register() {
                if let RpcError::Remote(refused) = &e {
                    // A live node of the same name, or limits: may change when leases lapse.
                    log::warn!("node {}: registration refused: {refused}", self.name);
                }
                backoff = (backoff * 2).min(REGISTER_RETRY_MAX.min(period.max(backoff)));
            }
        }
    }

    fn resolve(&self, path: &str) -> Result<(ObjectRef, bool), WireError> {
        if let Some((reference, at)) = lock(&self.resolved).get(path)
            && at.elapsed() < self.resolve_ttl
        {
            return Ok((reference.clone(), true));
        }
        let reference = match self.naming(NamingCall::Resolve {
            path: path.to_string(),
        })? {
            Reply::Resolved(r) => r,
            other => {
                return Err(WireError::Internal(format!(
                    "the naming service answered a resolve with {other:?}"
                )));
            }
        };
        let mut cache = lock(&self.resolved);
        if cache.len() >= MAX_RESOLVED {
            cache.clear();
        }
        cache.insert(path.to_string(), (reference.clone(), Instant::now()));
        Ok((reference, false))
    }

    fn call_object(&self, reference: &ObjectRef, method: Method) -> Result<Reply, WireError> {
        let call = Call::Object {
            object: reference.name.clone(),
            method,
        };
        if reference.node == self.name {
            let creator = self
                .creator
                .upgrade()
                .ok_or_else(|| WireError::NotReady("the node is shutting down".into()))?;
            return creator.call(&local_session(&self.name), call);
        }
        let client = self
            .client
            .get()
            .ok_or_else(|| WireError::NotReady("the node is starting".into()))?;
        let address = reference.address.parse::<SocketAddr>().map_err(|_| {
            WireError::Remote(format!(
                "`{}` has an unusable address `{}`",
                reference.name, reference.address
            ))
        })?;
        client.call_at(address, call).map_err(WireError::from)
    }
}

impl Remote for Shared {
    fn call(&self, path: &str, method: Method) -> Result<Reply, WireError> {
        let (reference, cached) = self.resolve(path)?;
        match self.call_object(&reference, method.clone()) {
            // A cached entry may be stale (the object moved or went): resolve again, once.
            Err(WireError::UnknownName(_) | WireError::Remote(_)) if cached => {
                lock(&self.resolved).remove(path);
                let (reference, _) = self.resolve(path)?;
                self.call_object(&reference, method)
            }
            Err(e @ (WireError::UnknownName(_) | WireError::Remote(_))) => {
                lock(&self.resolved).remove(path);
                Err(e)
            }
            other => other,
        }
    }
}

/// What the node's server serves: the creator, plus naming bookkeeping and the hosted naming
/// service.
struct NodeService {
    shared: Arc<Shared>,
    creator: Arc<Creator>,
}

impl Service for NodeService {
    fn call(&self, session: &Session, call: Call) -> Result<Reply, WireError> {
        let shared = &self.shared;
        match call {
            Call::Naming(c) => match &shared.hosted {
                Some(service) => service.handle_for(session, c),
                None => Err(WireError::NoNamingService),
            },
            Call::NodeInfo => Ok(Reply::Node(NodeInfo {
                node: shared.name.clone(),
                software: env!("CARGO_PKG_VERSION").to_string(),
                hosts_naming: shared.hosted.is_some(),
                objects: self.creator.object_count(),
            })),
            Call::Creator(CreatorCall::Create { .. }) => {
                let _ops = lock(&shared.ops);
                let reply = self.creator.call(session, call)?;
                if let Reply::Object(info) = &reply
                    && let Err(e) = shared.bind(info)
                {
                    // Not reachable by name is not created: undo.
                    let undo = Call::Creator(CreatorCall::Destroy {
                        name: info.name.clone(),
                        force: true,
                    });
                    if let Err(u) = self.creator.call(session, undo) {
                        log::error!("node {}: cannot undo `{}`: {u}", shared.name, info.name);
                    }
                    return Err(e);
                }
                Ok(reply)
            }
            Call::Creator(CreatorCall::Destroy { ref name, .. }) => {
                let _ops = lock(&shared.ops);
                let info = self.creator.info(name);
                let reply = self.creator.call(session, call)?;
                if let Some(info) = info {
                    shared.unbind(&info);
                }
                Ok(reply)
            }
            other => self.creator.call(session, other),
        }
    }

    fn closed(&self, session: &Session) {
        self.creator.closed(session);
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
        check_name(&config.name).map_err(NodeError::BadName)?;
        let limits = config.naming_limits;
        if config.naming != NamingChoice::None
            && (config.lease < limits.min_lease.max(Duration::from_millis(10))
                || config.lease > limits.max_lease.min(Duration::from_secs(3600)))
        {
            return Err(NodeError::BadLease(config.lease));
        }
        let name = config.name.clone();
        let hosted = (config.naming == NamingChoice::Host)
            .then(|| Arc::new(NamingService::new(name.clone(), limits)));
        let remote_naming = match config.naming {
            NamingChoice::Remote(a) => Some(a),
            _ => None,
        };
        let mut creator_config = config.creator;
        creator_config.node = name.clone();
        let creator = Arc::new(Creator::new(creator_config));
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
        let advertised = config.advertise.unwrap_or_else(|| {
            let mut a = address;
            if a.ip().is_unspecified() {
                a.set_ip(IpAddr::V4(Ipv4Addr::LOCALHOST));
            }
            a.to_string()
        });
        let _ = shared.advertised.set(advertised);

        let mut client_config = ClientConfig::node(name.clone());
        client_config.secret = config.secret;
        client_config.timeout = config.call_timeout;
        let naming_address = remote_naming.unwrap_or(address);
        let _ = shared
            .client
            .set(Client::lazy(naming_address, client_config));

        // A silent naming service is waited for (the registration thread retries); a refusal
        // is final.
        match shared.register() {
            Ok(()) => {}
            Err(RpcError::Remote(refused)) if refusal_is_final(&refused) => {
                creator.shutdown();
                server.shutdown();
                return Err(match refused {
                    WireError::NameTaken(_) | WireError::BadName { .. } => {
                        NodeError::Registration(refused)
                    }
                    other => NodeError::NamingRefused {
                        address: naming_address,
                        cause: RpcError::Remote(other),
                    },
                });
            }
            // It does not prove the secret this node holds: nothing was sent, waiting cannot fix it.
            Err(cause @ RpcError::Unauthenticated(_)) => {
                creator.shutdown();
                server.shutdown();
                return Err(NodeError::NamingRefused {
                    address: naming_address,
                    cause,
                });
            }
            // Silent (said once by `lost_naming`) or busy: the registration thread retries.
            Err(_) => {}
        }
        let reaper = hosted.as_ref().and_then(|s| {
            s.start_reaper(Duration::from_millis(100))
                .map_err(|e| log::warn!("node {name}: no naming reaper thread: {e}"))
                .ok()
        });
        let renewer = if shared.uses_naming() {
            let (stop, rx) = mpsc::channel::<()>();
            let period = config.lease / 3;
            let renewing = shared.clone();
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
        } else {
            None
        };
        Ok(Node {
            shared,
            creator,
            server: Some(server),
            renewer,
            reaper,
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
        self.creator.shutdown();
        if unregister && self.shared.uses_naming() && self.shared.registered() {
            let _ops = lock(&self.shared.ops);
            match self.shared.naming(NamingCall::Unregister {
                node: self.shared.name.clone(),
            }) {
                Ok(_) | Err(WireError::UnknownName(_)) => {}
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

#[cfg(test)]
mod tests {
    use super::*;

    fn names(node: &Node, context: &str) -> Vec<String> {
        let tree = node.hosted_naming().unwrap().snapshot();
        tree.list(context)
            .unwrap()
            .iter()
            .map(|e| e.name().to_string())
            .collect()
    }

    #[test]
    fn created_objects_are_bound_and_destroyed_ones_unbound() {
        let node = Node::start(NodeConfig::new("lab-a", NamingChoice::Host)).unwrap();
        assert_eq!(names(&node, "/lab-a"), ["creator"]);
        let create = Call::Creator(CreatorCall::Create {
            kind: "sensor/virtual".into(),
            name: "ft".into(),
            config: String::new(),
        });
        assert!(matches!(node.call(create.clone()), Ok(Reply::Object(_))));
        assert!(matches!(node.call(create), Err(WireError::NameTaken(_))));
        let tree = node.hosted_naming().unwrap().snapshot();
        let r = tree.resolve("/lab-a/sensors/ft").unwrap();
        assert_eq!(
            (r.class, r.address.as_str()),
            (Class::Sensor, node.advertised())
        );
        // The node reaches its own objects through its Remote.
        assert!(matches!(
            node.remote().call("/lab-a/sensors/ft", Method::Describe),
            Ok(Reply::Object(_))
        ));
        assert!(matches!(
            node.remote().call("/lab-a/sensors/nope", Method::Describe),
            Err(WireError::UnknownName(_))
        ));
        let destroy = Call::Creator(CreatorCall::Destroy {
            name: "ft".into(),
            force: false,
        });
        node.call(destroy).unwrap();
        assert_eq!(names(&node, "/lab-a"), ["creator"]);
        assert!(matches!(
            node.call(Call::NodeInfo),
            Ok(Reply::Node(NodeInfo {
                hosts_naming: true,
                objects: 0,
                ..
            }))
        ));
        let naming = node.hosted_naming().unwrap().clone();
        node.shutdown();
        assert!(naming.snapshot().list("/").unwrap().is_empty());
    }

    #[test]
    fn bad_names_and_leases_are_refused() {
        let mut config = NodeConfig::new("no/slash", NamingChoice::None);
        assert!(matches!(
            Node::start(config.clone()),
            Err(NodeError::BadName(_))
        ));
        config.name = "ok".into();
        config.naming = NamingChoice::Host;
        config.lease = Duration::from_millis(1);
        assert!(matches!(Node::start(config), Err(NodeError::BadLease(_))));
    }
}
