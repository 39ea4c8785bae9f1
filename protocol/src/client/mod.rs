//! The client: reach any object of the system by its naming path, without knowing where it
//! lives, through typed proxies that read like the local objects.
//!
//! ```no_run
//! use penelope_hal::NamedPose;
//! use penelope_protocol::client::{Client, Lifecycle};
//! use penelope_protocol::net::conn::ClientConfig;
//!
//! # fn main() -> Result<(), penelope_protocol::net::conn::RpcError> {
//! let client = Client::connect("127.0.0.1:7300".parse().unwrap(), ClientConfig::new("me"))?;
//! let node = client.node("lab-a")?;
//! node.create("robot/puma560", "slave", "")?;
//! let robot = client.robot("/lab-a/robots/slave")?;
//! robot.configure()?;
//! let q = robot.named_pose(NamedPose::Work)?;
//! let pose = robot.forward_kinematics(Some(&q))?;
//! println!("the tool is at {}", pose.translation.vector);
//! # Ok(()) }
//! ```
//!
//! # Layers
//! - [`Client`]: the naming service's address, a cache of one [`Connection`] per node address
//!   (reconnected once when a cached connection turns out broken), and [`Client::call`] of any
//!   [`Method`] by path.
//! - [`NamingProxy`] (bind, resolve, unbind, list, and a recursive [`NamingProxy::tree`]) and
//!   [`NodeProxy`] (a node's creator: kinds, list, create, destroy).
//! - The typed proxies in [`proxy`]: [`RobotProxy`], [`BoardProxy`], [`SensorProxy`],
//!   [`ControllerProxy`], [`TrajectoryProxy`], and [`ObjectProxy`] for an object of any class.
//!   Every one has the lifecycle methods of [`Lifecycle`].
//! - [`TelemetryStream`]: the telemetry of a running loop on its own connection;
//!   [`LinkStream`]: the link records of a channel linked to another node, likewise.
//!
//! # Errors
//! Everything returns [`RpcError`], the error of the transport, so that the client, the nodes'
//! own remote calls and the benchmarks share one type and one `From<RpcError> for WireError`:
//! [`RpcError::Remote`] carries the node's typed [`WireError`] (and the errors this client finds
//! before sending: a proxy of the wrong class is [`CallError::WrongClass`], a NaN argument
//! [`CallError::BadArgument`], exactly what the node would have answered); a reply of another
//! variant than the method's is [`RpcError::Protocol`], never a panic; the others are transport
//! failures.
//!
//! # Retries
//! A call on a cached connection that fails in transport (the node restarted, the socket was
//! closed) is sent once more on a new connection. A request that reached the node before the
//! connection broke may thus run twice: harmless for queries and transitions, and a `create`
//! that ran twice answers [`CallError::NameTaken`]. A timeout is never retried.

pub mod proxy;
pub mod telemetry;

use std::collections::HashMap;
use std::net::{SocketAddr, ToSocketAddrs};
use std::sync::{Arc, Mutex, PoisonError};

use crate::net::conn::{ClientConfig, Connection, RpcError};
use crate::proto::{
    Call, CallError, Class, CreatorCall, KindInfo, Method, NameEntry, NamingCall, NodeInfo,
    ObjectInfo, ObjectRef, ProtocolError, Reply, StopReport, WireError,
};

pub use proxy::{
    BoardProxy, ControllerProxy, Lifecycle, ObjectHandle, ObjectProxy, RobotDescription,
    RobotProxy, SensorProxy, TrajectoryProxy, TypedProxy,
};
pub use telemetry::{LinkStream, Streamed, Subscription, TelemetryStream};

/// One node's answer to [`Client::estop_all`]: its name, and its report or why it was not
/// reached.
pub type NodeStop = (String, Result<StopReport, RpcError>);

/// The deepest context [`NamingProxy::tree`] walks into.
pub const MAX_TREE_DEPTH: usize = 16;

/// One cached connection (empty until first used, or after it broke).
type Slot = Arc<Mutex<Option<Connection>>>;

/// A naming-aware client. Cheap to clone (the clones share the connections); usable from several
/// threads at once (calls to one node are serialized on its connection, calls to different nodes
/// run in parallel).
#[derive(Clone, Debug)]
pub struct Client {
    inner: Arc<Inner>,
}

#[derive(Debug)]
struct Inner {
    naming: SocketAddr,
    config: ClientConfig,
    pool: Mutex<HashMap<SocketAddr, Slot>>,
}

impl Client {
    /// A client of the naming service at `naming`; connects to it at once (so an unreachable or
    /// unauthenticated naming service is reported here).
    ///
    /// # Errors
    /// The transport's [`RpcError`] (connection refused, authentication failed, ...).
    pub fn connect(naming: SocketAddr, config: ClientConfig) -> Result<Client, RpcError> {
        let client = Client::lazy(naming, config);
        let slot = client.slot(naming);
        let mut conn = lock(&slot);
        *conn = Some(Connection::connect(naming, &client.inner.config)?);
        drop(conn);
        Ok(client)
    }

    /// A client of the naming service at `naming` that connects on its first call (for a
    /// process that must start before the naming service answers, such as a node).
    pub fn lazy(naming: SocketAddr, config: ClientConfig) -> Client {
        Client {
            inner: Arc::new(Inner {
                naming,
                config,
                pool: Mutex::new(HashMap::new()),
            }),
        }
    }

    /// The naming service's address.
    pub fn naming_address(&self) -> SocketAddr {
        self.inner.naming
    }

    /// The configuration the connections are opened with.
    pub fn config(&self) -> &ClientConfig {
        &self.inner.config
    }

    /// The naming service.
    pub fn naming(&self) -> NamingProxy {
        NamingProxy {
            client: self.clone(),
        }
    }

    /// The node `node` (its creator, resolved at `/<node>/creator`).
    ///
    /// # Errors
    /// [`CallError::UnknownName`] when no such node is registered; transport errors.
    pub fn node(&self, node: &str) -> Result<NodeProxy, RpcError> {
        let path = crate::proto::object_path(node, Class::Creator, "");
        let reference = self.resolve(&path)?;
        let address = parse_address(&reference)?;
        Ok(NodeProxy {
            client: self.clone(),
            reference,
            address,
        })
    }

    /// The node answering at `address`, without the naming service.
    ///
    /// # Errors
    /// Transport errors, or a reply that is not [`Reply::Node`].
    pub fn node_at(&self, address: SocketAddr) -> Result<NodeProxy, RpcError> {
        let info = match self.call_at(address, Call::NodeInfo)? {
            Reply::Node(info) => info,
            other => return Err(unexpected("node info", &other)),
        };
        Ok(NodeProxy {
            client: self.clone(),
            reference: ObjectRef {
                node: info.node.clone(),
                address: address.to_string(),
                name: String::new(),
                class: Class::Creator,
                kind: "creator".into(),
            },
            address,
        })
    }

    /// The nodes registered in the naming service (the contexts under `/` that hold a creator).
    ///
    /// # Errors
    /// Transport errors.
    pub fn nodes(&self) -> Result<Vec<NodeProxy>, RpcError> {
        let mut nodes = Vec::new();
        for entry in self.naming().list("/")? {
            if let NameEntry::Context { name } = entry {
                match self.node(&name) {
                    Ok(node) => nodes.push(node),
                    Err(RpcError::Remote(WireError::Call(CallError::UnknownName(_)))) => {}
                    Err(e) => return Err(e),
                }
            }
        }
        Ok(nodes)
    }

    /// What the naming `path` names.
    ///
    /// # Errors
    /// [`CallError::UnknownName`] when nothing is bound there; transport errors.
    pub fn resolve(&self, path: &str) -> Result<ObjectRef, RpcError> {
        self.naming().resolve(path)
    }

    /// The object named by `spec`: a naming path (`/lab-a/robots/slave`), or the shorthand
    /// `NODE/NAME` (`lab-a/slave`), looked up in that node's creator (names are unique on a node,
    /// so the shorthand is never ambiguous).
    ///
    /// # Errors
    /// [`CallError::UnknownName`] when there is no such object; [`CallError::BadName`] for a
    /// spec of neither form; transport errors.
    pub fn locate(&self, spec: &str) -> Result<ObjectRef, RpcError> {
        if spec.starts_with('/') {
            return self.resolve(spec);
        }
        let Some((node, name)) = spec.split_once('/') else {
            return Err(RpcError::Remote(WireError::Call(CallError::BadName {
                name: spec.chars().take(80).collect(),
                reason: "expected a naming path such as /lab-a/robots/slave, or NODE/NAME".into(),
            })));
        };
        let node = self.node(node)?;
        node.list()?
            .into_iter()
            .find(|o| o.name == name)
            .map(|o| node.reference_of(&o))
            .ok_or_else(|| {
                RpcError::Remote(WireError::Call(CallError::UnknownName(spec.to_string())))
            })
    }

    /// Calls `method` on the object at the naming `path`.
    ///
    /// # Errors
    /// The object's own error ([`RpcError::Remote`]), [`CallError::UnknownName`] when nothing is
    /// bound at `path`, or a transport error.
    pub fn call(&self, path: &str, method: Method) -> Result<Reply, RpcError> {
        let reference = self.resolve(path)?;
        self.call_ref(&reference, method)
    }

    /// Calls `method` on the object `reference` names (no naming lookup).
    ///
    /// # Errors
    /// As [`Client::call`].
    pub fn call_ref(&self, reference: &ObjectRef, method: Method) -> Result<Reply, RpcError> {
        let address = parse_address(reference)?;
        self.call_at(
            address,
            Call::Object {
                object: reference.name.clone(),
                method,
            },
        )
    }

    /// Sends one raw `call` to the node at `address` on the cached connection, opening it if
    /// needed and reopening it once if it turns out broken.
    ///
    /// # Errors
    /// The node's error ([`RpcError::Remote`]) or a transport error.
    pub fn call_at(&self, address: SocketAddr, call: Call) -> Result<Reply, RpcError> {
        let slot = self.slot(address);
        let mut conn = lock(&slot);
        if conn.as_ref().is_some_and(|c| !c.is_usable()) {
            *conn = None;
        }
        if let Some(c) = conn.as_mut() {
            match c.call(call.clone()) {
                Ok(reply) => return Ok(reply),
                Err(e) => {
                    let usable = c.is_usable();
                    if usable || !retryable(&e) {
                        if !usable {
                            *conn = None;
                        }
                        return Err(e);
                    }
                    *conn = None;
                }
            }
        }
        let c = conn.insert(Connection::connect(address, &self.inner.config)?);
        let result = c.call(call);
        if !c.is_usable() {
            *conn = None;
        }
        result
    }

    /// Sends one `call` on a connection of its own, opened for it and closed after: an e-stop
    /// must not wait behind another call of this client on the cached connection (calls to one
    /// node are serialized there, and one may be slow).
    ///
    /// # Errors
    /// The node's error ([`RpcError::Remote`]) or a transport error.
    pub fn call_alone(&self, address: SocketAddr, call: Call) -> Result<Reply, RpcError> {
        Connection::connect(address, &self.inner.config)?.call(call)
    }

    /// Latches the e-stop of every loop on every node in the naming tree, the nodes asked at
    /// once (one connection and one round trip each, in parallel), like a console's red button.
    /// Returns each node's answer or its error, by node name; a node that cannot be reached
    /// is in the list with its error, never skipped silently.
    ///
    /// # Errors
    /// Transport errors reaching the naming service (the list of nodes).
    pub fn estop_all(&self) -> Result<Vec<NodeStop>, RpcError> {
        let mut nodes = Vec::new();
        let mut unreachable = Vec::new();
        for entry in self.naming().list("/")? {
            if let NameEntry::Context { name } = entry {
                match self.node(&name) {
                    Ok(node) => nodes.push(node),
                    Err(RpcError::Remote(WireError::Call(CallError::UnknownName(_)))) => {}
                    Err(e) => unreachable.push((name, Err(e))),
                }
            }
        }
        let mut answers: Vec<NodeStop> = std::thread::scope(|s| {
            let asked: Vec<_> = nodes
                .iter()
                .map(|n| (n.name().to_string(), s.spawn(move || n.estop())))
                .collect();
            asked
                .into_iter()
                .map(|(name, t)| {
                    let answer = t.join().unwrap_or_else(|_| {
                        Err(RpcError::Remote(WireError::Call(CallError::Internal(
                            "the e-stop thread panicked".into(),
                        ))))
                    });
                    (name, answer)
                })
                .collect()
        });
        answers.extend(unreachable);
        Ok(answers)
    }

    /// Opens a telemetry subscription to the object at `path` (a controller, or a robot driven by
    /// an active controller) on a connection of its own, one tick in `decimation` (0 is taken
    /// as 1).
    ///
    /// # Errors
    /// [`CallError::UnknownName`], the node's refusal (not running, too many subscriptions), or
    /// a transport error.
    pub fn subscribe(&self, path: &str, decimation: u32) -> Result<TelemetryStream, RpcError> {
        let reference = self.locate(path)?;
        TelemetryStream::open(&reference, &self.inner.config, decimation)
    }

    /// Opens a subscription to the link statistics of the `trajectory/teleop` channel at
    /// `path` (its end on that node, linked to another node) on a connection of its own: one
    /// record every 100 ms times `decimation` (0 is taken as 1).
    ///
    /// # Errors
    /// [`CallError::UnknownName`], [`CallError::WrongClass`] for an object that is not a
    /// trajectory, [`CallError::NoLink`] for a channel with both ends on one node,
    /// [`CallError::NotReady`] for a channel not configured, or a transport error.
    pub fn watch_link(&self, path: &str, decimation: u32) -> Result<LinkStream, RpcError> {
        let reference = self.locate(path)?;
        LinkStream::open(&reference, &self.inner.config, decimation)
    }

    /// A proxy of class `P` for the object at `path` (a naming path or `NODE/NAME`), after
    /// checking its class.
    ///
    /// # Errors
    /// [`CallError::WrongClass`] when the object is of another class, and those of
    /// [`Client::locate`].
    pub fn proxy<P: TypedProxy>(&self, path: &str) -> Result<P, RpcError> {
        let reference = self.locate(path)?;
        P::from_handle(ObjectHandle::new(self.clone(), reference)?)
    }

    /// The object at `path`, whatever its class (for lifecycle transitions and `describe`).
    ///
    /// # Errors
    /// As [`Client::locate`].
    pub fn object(&self, path: &str) -> Result<ObjectProxy, RpcError> {
        self.proxy(path)
    }

    /// The robot at `path`.
    ///
    /// # Errors
    /// As [`Client::proxy`].
    pub fn robot(&self, path: &str) -> Result<RobotProxy, RpcError> {
        self.proxy(path)
    }

    /// The board at `path`.
    ///
    /// # Errors
    /// As [`Client::proxy`].
    pub fn board(&self, path: &str) -> Result<BoardProxy, RpcError> {
        self.proxy(path)
    }

    /// The sensor at `path`.
    ///
    /// # Errors
    /// As [`Client::proxy`].
    pub fn sensor(&self, path: &str) -> Result<SensorProxy, RpcError> {
        self.proxy(path)
    }

    /// The controller at `path`.
    ///
    /// # Errors
    /// As [`Client::proxy`].
    pub fn controller(&self, path: &str) -> Result<ControllerProxy, RpcError> {
        self.proxy(path)
    }

    /// The trajectory at `path`.
    ///
    /// # Errors
    /// As [`Client::proxy`].
    pub fn trajectory(&self, path: &str) -> Result<TrajectoryProxy, RpcError> {
        self.proxy(path)
    }

    fn slot(&self, address: SocketAddr) -> Slot {
        lock(&self.inner.pool).entry(address).or_default().clone()
    }
}

/// Locks `m`, going on after a panic of another holder (the data is a connection or a map of
/// them: at worst a connection in an unknown state, which the next failure replaces).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Whether a failure that broke a reused connection is worth one more try on a new one: a
/// transport failure, or the node's notice that it closed the connection for being idle (sent
/// before our request was read).
fn retryable(e: &RpcError) -> bool {
    matches!(
        e,
        RpcError::Io(_)
            | RpcError::Frame(_)
            | RpcError::Remote(WireError::Protocol(ProtocolError::Timeout(_)))
    )
}

/// The socket address of a naming entry.
fn parse_address(reference: &ObjectRef) -> Result<SocketAddr, RpcError> {
    reference
        .address
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| {
            RpcError::Protocol(format!(
                "`{}` on node `{}` has an unusable address `{}`",
                reference.name, reference.node, reference.address
            ))
        })
}

/// The error for a reply of another variant than expected.
pub(crate) fn unexpected(expected: &str, reply: &Reply) -> RpcError {
    let text = format!("{reply:?}");
    let variant: String = text
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    RpcError::Protocol(format!("expected {expected} in the reply, got {variant}"))
}

/// The naming service (the paper's CORBA naming service): one tree of contexts for the system.
#[derive(Clone, Debug)]
pub struct NamingProxy {
    client: Client,
}

impl NamingProxy {
    fn call(&self, call: NamingCall) -> Result<Reply, RpcError> {
        self.client
            .call_at(self.client.inner.naming, Call::Naming(call))
    }

    fn unit(&self, call: NamingCall) -> Result<(), RpcError> {
        match self.call(call)? {
            Reply::Unit => Ok(()),
            other => Err(unexpected("nothing", &other)),
        }
    }

    /// Binds the absolute `path` to `reference` (creating the contexts on the way); with
    /// `rebind`, replaces an existing binding.
    ///
    /// # Errors
    /// [`CallError::NameTaken`] if bound and not `rebind`, [`CallError::BadName`], transport
    /// errors.
    pub fn bind(&self, path: &str, reference: ObjectRef, rebind: bool) -> Result<(), RpcError> {
        self.unit(NamingCall::Bind {
            path: path.to_string(),
            reference,
            rebind,
        })
    }

    /// What `path` names.
    ///
    /// # Errors
    /// [`CallError::UnknownName`] when nothing is bound there; transport errors.
    pub fn resolve(&self, path: &str) -> Result<ObjectRef, RpcError> {
        match self.call(NamingCall::Resolve {
            path: path.to_string(),
        })? {
            Reply::Resolved(r) => Ok(r),
            other => Err(unexpected("a naming entry", &other)),
        }
    }

    /// Removes the binding at `path` (and the contexts it leaves empty).
    ///
    /// # Errors
    /// [`CallError::UnknownName`] when nothing is bound there; transport errors.
    pub fn unbind(&self, path: &str) -> Result<(), RpcError> {
        self.unit(NamingCall::Unbind {
            path: path.to_string(),
        })
    }

    /// The entries of the context `context` (`/` for the root).
    ///
    /// # Errors
    /// [`CallError::UnknownName`] for no such context; transport errors.
    pub fn list(&self, context: &str) -> Result<Vec<NameEntry>, RpcError> {
        match self.call(NamingCall::List {
            context: context.to_string(),
        })? {
            Reply::Names(names) => Ok(names),
            other => Err(unexpected("names", &other)),
        }
    }

    /// Every entry under `context`, depth first, as `(absolute path, depth, entry)` (depth 0 for
    /// the entries of `context` itself), down to [`MAX_TREE_DEPTH`] levels.
    ///
    /// # Errors
    /// As [`NamingProxy::list`]. A context that disappears during the walk is skipped.
    pub fn tree(&self, context: &str) -> Result<Vec<(String, usize, NameEntry)>, RpcError> {
        let mut out = Vec::new();
        self.walk(context, 0, &mut out)?;
        Ok(out)
    }

    fn walk(
        &self,
        context: &str,
        depth: usize,
        out: &mut Vec<(String, usize, NameEntry)>,
    ) -> Result<(), RpcError> {
        let entries = match self.list(context) {
            Ok(e) => e,
            Err(RpcError::Remote(WireError::Call(CallError::UnknownName(_)))) if depth > 0 => {
                return Ok(());
            }
            Err(e) => return Err(e),
        };
        for entry in entries {
            let path = join_path(context, entry.name());
            let sub = matches!(entry, NameEntry::Context { .. });
            out.push((path.clone(), depth, entry));
            if sub && depth + 1 < MAX_TREE_DEPTH {
                self.walk(&path, depth + 1, out)?;
            }
        }
        Ok(())
    }
}

/// `context/name` with exactly one `/` between.
pub fn join_path(context: &str, name: &str) -> String {
    let base = context.trim_end_matches('/');
    format!("{base}/{name}")
}

/// One node, through its creator (the paper's `creatorImpl`): the kinds it can make, its objects,
/// create and destroy.
#[derive(Clone, Debug)]
pub struct NodeProxy {
    client: Client,
    reference: ObjectRef,
    address: SocketAddr,
}

impl NodeProxy {
    /// The node's name.
    #[allow(clippy::misnamed_getters)] // the creator's reference: its node is the name we want
    pub fn name(&self) -> &str {
        &self.reference.node
    }

    /// Where the node answers.
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    fn creator(&self, call: CreatorCall) -> Result<Reply, RpcError> {
        self.client.call_at(self.address, Call::Creator(call))
    }

    /// The node's identity.
    ///
    /// # Errors
    /// Transport errors.
    pub fn info(&self) -> Result<NodeInfo, RpcError> {
        match self.client.call_at(self.address, Call::NodeInfo)? {
            Reply::Node(info) => Ok(info),
            other => Err(unexpected("node info", &other)),
        }
    }

    /// The kinds this node can create, with their configuration keys.
    ///
    /// # Errors
    /// Transport errors.
    pub fn kinds(&self) -> Result<Vec<KindInfo>, RpcError> {
        match self.creator(CreatorCall::Kinds)? {
            Reply::Kinds(k) => Ok(k),
            other => Err(unexpected("kinds", &other)),
        }
    }

    /// The objects of this node.
    ///
    /// # Errors
    /// Transport errors.
    pub fn list(&self) -> Result<Vec<ObjectInfo>, RpcError> {
        match self.creator(CreatorCall::List)? {
            Reply::Objects(o) => Ok(o),
            other => Err(unexpected("objects", &other)),
        }
    }

    /// Makes an object of `kind` (`robot/puma560`) named `name`, configured by `config` (TOML
    /// text, `""` for the defaults). It starts `unconfigured` and is bound in the naming tree at
    /// `/<node>/<class context>/<name>`.
    ///
    /// # Errors
    /// [`CallError::UnknownKind`], [`CallError::NameTaken`], [`CallError::BadName`],
    /// [`CallError::BadConfig`], [`CallError::LimitReached`], transport errors.
    pub fn create(&self, kind: &str, name: &str, config: &str) -> Result<ObjectInfo, RpcError> {
        match self.creator(CreatorCall::Create {
            kind: kind.to_string(),
            name: name.to_string(),
            config: config.to_string(),
        })? {
            Reply::Object(info) => Ok(info),
            other => Err(unexpected("the new object", &other)),
        }
    }

    /// [`NodeProxy::create`], then a proxy of class `P` for the new object, such as
    /// `node.create_as::<RobotProxy>("robot/puma560", "slave", "")`.
    ///
    /// # Errors
    /// Those of [`NodeProxy::create`]; [`CallError::WrongClass`] when `kind` is not of `P`'s
    /// class (checked before anything is created).
    pub fn create_as<P: TypedProxy>(
        &self,
        kind: &str,
        name: &str,
        config: &str,
    ) -> Result<P, RpcError> {
        let class = kind.split('/').next().and_then(Class::parse);
        if let (Some(expected), Some(found)) = (P::CLASS, class)
            && expected != found
        {
            return Err(RpcError::Remote(WireError::Call(CallError::WrongClass {
                name: name.to_string(),
                expected,
                found,
            })));
        }
        let info = self.create(kind, name, config)?;
        P::from_handle(ObjectHandle::new(
            self.client.clone(),
            self.reference_of(&info),
        )?)
    }

    /// A proxy of class `P` for the object `name` of this node (no naming lookup).
    ///
    /// # Errors
    /// [`CallError::UnknownName`], [`CallError::WrongClass`], transport errors.
    pub fn object<P: TypedProxy>(&self, name: &str) -> Result<P, RpcError> {
        let info = self
            .list()?
            .into_iter()
            .find(|o| o.name == name)
            .ok_or_else(|| {
                RpcError::Remote(WireError::Call(CallError::UnknownName(name.to_string())))
            })?;
        P::from_handle(ObjectHandle::new(
            self.client.clone(),
            self.reference_of(&info),
        )?)
    }

    /// Removes the object `name` and its naming entry. Refused with [`CallError::InUse`] while
    /// an active object depends on it, unless `force`: then those are stopped safely first.
    ///
    /// # Errors
    /// [`CallError::UnknownName`], [`CallError::InUse`], transport errors.
    pub fn destroy(&self, name: &str, force: bool) -> Result<(), RpcError> {
        match self.creator(CreatorCall::Destroy {
            name: name.to_string(),
            force,
        })? {
            Reply::Unit | Reply::Object(_) => Ok(()),
            other => Err(unexpected("nothing", &other)),
        }
    }

    /// Moves the node's simulated clock on by `by`, stepping its active loops; returns the
    /// clock's new time.
    ///
    /// # Errors
    /// [`CallError::NotReady`] on a node clocked in real time; transport errors.
    pub fn advance(&self, by: std::time::Duration) -> Result<std::time::Duration, RpcError> {
        match self.creator(CreatorCall::Advance {
            seconds: by.as_secs_f64(),
        })? {
            Reply::Duration(Some(t)) => Ok(std::time::Duration::from_secs_f64(t.max(0.0))),
            other => Err(unexpected("a time", &other)),
        }
    }

    /// Starts recording `objects` (none: every controller and linked channel) to the new MCAP
    /// file `name` (a plain file name) in the node's recordings directory; returns the
    /// controllers and channels recorded.
    ///
    /// # Errors
    /// What [`CreatorCall::RecordStart`] lists; transport errors.
    pub fn record_start(
        &self,
        name: &str,
        objects: &[String],
    ) -> Result<(Vec<String>, Vec<String>), RpcError> {
        self.record_start_at(name, objects)
            .map(|(_, controllers, links)| (controllers, links))
    }

    /// As [`record_start`](Self::record_start), with the file's path on the node's host first.
    ///
    /// # Errors
    /// What [`CreatorCall::RecordStart`] lists; transport errors.
    pub fn record_start_at(
        &self,
        name: &str,
        objects: &[String],
    ) -> Result<(String, Vec<String>, Vec<String>), RpcError> {
        match self.creator(CreatorCall::RecordStart {
            path: name.to_string(),
            objects: objects.to_vec(),
        })? {
            Reply::Recording {
                path,
                controllers,
                links,
            } => Ok((path, controllers, links)),
            other => Err(unexpected("a recording", &other)),
        }
    }

    /// As [`record_start_at`](Self::record_start_at), drawing the recorded robots in 3D at
    /// `scene_hz` of tick time ([`CreatorCall::RecordStartScene`]).
    ///
    /// # Errors
    /// What [`CreatorCall::RecordStartScene`] lists; transport errors.
    pub fn record_start_scene(
        &self,
        name: &str,
        objects: &[String],
        scene_hz: f64,
    ) -> Result<(String, Vec<String>, Vec<String>), RpcError> {
        match self.creator(CreatorCall::RecordStartScene {
            path: name.to_string(),
            objects: objects.to_vec(),
            scene_hz,
        })? {
            Reply::Recording {
                path,
                controllers,
                links,
            } => Ok((path, controllers, links)),
            other => Err(unexpected("a recording", &other)),
        }
    }

    /// Ends the node's recording: its file and the ticks written.
    ///
    /// # Errors
    /// What [`CreatorCall::RecordStop`] lists; transport errors.
    pub fn record_stop(&self) -> Result<(String, u64), RpcError> {
        match self.creator(CreatorCall::RecordStop)? {
            Reply::Recorded { path, ticks } => Ok((path, ticks)),
            other => Err(unexpected("a finished recording", &other)),
        }
    }

    /// Applies the system file `text` to this node: the objects it places here are created,
    /// related, configured and activated by the node, or none is kept. Returns the objects
    /// created, in creation order.
    ///
    /// # Errors
    /// What [`CreatorCall::ApplySystem`] lists; transport errors.
    pub fn apply_system(&self, text: &str) -> Result<Vec<ObjectInfo>, RpcError> {
        match self.creator(CreatorCall::ApplySystem {
            text: text.to_string(),
        })? {
            Reply::Objects(o) => Ok(o),
            other => Err(unexpected("the objects created", &other)),
        }
    }

    /// Latches the e-stop of every loop running on this node, on a connection of its own
    /// ([`Client::call_alone`]): the node answers without waiting for any other call. Returns
    /// which loops latched it before the answer and which had yet to tick.
    ///
    /// # Errors
    /// Transport errors.
    pub fn estop(&self) -> Result<StopReport, RpcError> {
        match self
            .client
            .call_alone(self.address, Call::Creator(CreatorCall::EStop))?
        {
            Reply::Stopped(report) => Ok(report),
            other => Err(unexpected("an e-stop report", &other)),
        }
    }

    /// The reference of one of this node's objects.
    pub fn reference_of(&self, info: &ObjectInfo) -> ObjectRef {
        ObjectRef {
            node: self.reference.node.clone(),
            address: self.reference.address.clone(),
            name: info.name.clone(),
            class: info.class,
            kind: info.kind.clone(),
        }
    }

    /// The naming path of one of this node's objects.
    pub fn path_of(&self, info: &ObjectInfo) -> String {
        crate::proto::object_path(&self.reference.node, info.class, &info.name)
    }
}
