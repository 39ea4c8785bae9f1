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
//! - [`FrameStream`]: a camera's frames, on the common clock, on its own connection;
//!   [`LinkStream`]: the link records of a channel linked to another node, likewise.
//! - [`clock`]: the system's common clock on this client's host ([`clock::CommonClockView`]),
//!   for views that compare a frame's capture instant with the instant they display it.
//! - [`sync`]: which force and pose sample belongs to a camera frame, and how far the video is
//!   behind the hand (the alignment the web page, the Foxglove gateway and `experiment sync` use).
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

pub mod clock;
mod estop;
mod naming;
mod node;
pub mod proxy;
pub mod sync;
pub mod telemetry;

use std::collections::HashMap;
use std::net::{SocketAddr, ToSocketAddrs};
use std::sync::{Arc, Mutex, PoisonError};

use crate::net::conn::{ClientConfig, Connection, RpcError};
use crate::proto::{
    Call, CallError, Class, Method, NameEntry, ObjectRef, ProtocolError, Reply, StopReport,
    WireError,
};

pub use estop::{EStopIncomplete, estop_reports};
pub use naming::{MAX_TREE_DEPTH, NamingProxy, join_path};
pub use node::NodeProxy;
pub use proxy::{
    BoardProxy, ControllerProxy, Lifecycle, ObjectHandle, ObjectProxy, RobotDescription,
    RobotProxy, SensorProxy, Setpoints, TrajectoryProxy, TypedProxy,
};
pub use telemetry::{FrameStream, LinkStream, Streamed, Subscription, TelemetryStream};

/// One node's answer to [`Client::estop_all`]: its name, and its report or why it was not
/// reached.
pub type NodeStop = (String, Result<StopReport, RpcError>);

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
    /// Set by [`Client::close`]: every later call is refused.
    closed: std::sync::atomic::AtomicBool,
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
                closed: std::sync::atomic::AtomicBool::new(false),
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
        NamingProxy::new(self.clone())
    }

    /// The node `node` (its creator, resolved at `/<node>/creator`).
    ///
    /// # Errors
    /// [`CallError::UnknownName`] when no such node is registered; transport errors.
    pub fn node(&self, node: &str) -> Result<NodeProxy, RpcError> {
        let path = crate::proto::object_path(node, Class::Creator, "");
        let reference = self.resolve(&path)?;
        let address = parse_address(&reference)?;
        Ok(NodeProxy::new(self.clone(), reference, address))
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
        let reference = ObjectRef {
            node: info.node.clone(),
            address: address.to_string(),
            name: String::new(),
            class: Class::Creator,
            kind: "creator".into(),
        };
        Ok(NodeProxy::new(self.clone(), reference, address))
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
        self.check_open()?;
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
        self.check_open()?;
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

    /// Opens a subscription to the frames of the camera at `path` (`sensor/sim-camera`,
    /// `sensor/camera`) on a connection of its own: one frame in `decimation` (0 is taken as 1).
    ///
    /// # Errors
    /// [`CallError::UnknownName`], [`CallError::WrongClass`] for an object that is not a
    /// sensor, the node's refusal of a sensor that is not a camera or not running, or a
    /// transport error.
    pub fn watch_camera(&self, path: &str, decimation: u32) -> Result<FrameStream, RpcError> {
        let reference = self.locate(path)?;
        FrameStream::open(&reference, &self.inner.config, decimation)
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

    /// Closes every cached connection (of this client and of its clones and proxies, which
    /// share them) and refuses every later call with an [`RpcError::Io`] of kind
    /// `NotConnected`. Idempotent. Open telemetry subscriptions have connections of their own
    /// and end when dropped.
    pub fn close(&self) {
        self.inner
            .closed
            .store(true, std::sync::atomic::Ordering::SeqCst);
        let slots: Vec<Slot> = lock(&self.inner.pool).drain().map(|(_, s)| s).collect();
        for slot in slots {
            lock(&slot).take();
        }
    }

    /// Whether [`Client::close`] was called.
    pub fn is_closed(&self) -> bool {
        self.inner.closed.load(std::sync::atomic::Ordering::SeqCst)
    }

    fn check_open(&self) -> Result<(), RpcError> {
        if self.is_closed() {
            return Err(RpcError::Io(std::io::Error::new(
                std::io::ErrorKind::NotConnected,
                "the client was closed",
            )));
        }
        Ok(())
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
