//! The naming service: the [`NamingTree`] behind a mutex on a monotonic clock, its lease reaper
//! thread, and the [`Service`] it is when it runs alone (`penelope naming`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, Weak};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::{NamingLimits, NamingTree, authorize};
use penelope_protocol::proto::{Call, CallError, NamingCall, NodeInfo, Reply, WireError};
use penelope_protocol::service::{Service, Session};

/// How long the naming service waits for a node's previous address to accept a connection
/// before taking its registration as stale (a live node's kernel accepts at once, even when the
/// node is busy).
pub const STALE_PROBE_TIMEOUT: Duration = Duration::from_millis(300);

/// Whether something accepts a TCP connection at `address` within [`STALE_PROBE_TIMEOUT`]. An
/// address that is not `ip:port` cannot be probed without a name look-up: taken as alive.
fn answers(address: &str) -> bool {
    match address.parse::<std::net::SocketAddr>() {
        Ok(a) => std::net::TcpStream::connect_timeout(&a, STALE_PROBE_TIMEOUT).is_ok(),
        Err(_) => true,
    }
}

/// The naming service: a [`NamingTree`] behind a mutex, on a monotonic clock.
///
/// Leases are checked lazily before every call ([`NamingService::handle`]) and, when
/// [`NamingService::start_reaper`] runs, periodically.
#[derive(Debug)]
pub struct NamingService {
    name: String,
    epoch: Instant,
    tree: Mutex<NamingTree>,
}

impl NamingService {
    /// A service named `name` (what [`Call::NodeInfo`] answers) with an empty tree.
    pub fn new(name: impl Into<String>, limits: NamingLimits) -> Self {
        NamingService {
            name: name.into(),
            epoch: Instant::now(),
            tree: Mutex::new(NamingTree::new(limits)),
        }
    }

    /// The service's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Time on the service's clock (since it was made).
    pub fn now(&self) -> Duration {
        self.epoch.elapsed()
    }

    pub(super) fn lock(&self) -> MutexGuard<'_, NamingTree> {
        // The tree is consistent between calls (every method checks before it changes), so a
        // panic elsewhere while holding the lock leaves nothing half-done.
        self.tree.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Expires the lapsed leases now; returns the expired nodes.
    pub fn expire_now(&self) -> Vec<String> {
        let now = self.now();
        let expired = self.lock().expire(now);
        for node in &expired {
            log::info!("naming: lease of node `{node}` lapsed; its entries are removed");
        }
        expired
    }

    /// Serves one naming call (lapsed leases are expired first).
    ///
    /// # Errors
    /// The call's typed error (see [`NamingTree`]).
    ///
    /// A node registering while its name is held by a live lease at another address takes the
    /// name back when nothing answers at that address any more (the holder is its own previous
    /// run, killed before it could unregister): the address is probed with one TCP connection
    /// ([`STALE_PROBE_TIMEOUT`]), outside the tree's lock, and the stale entry is replaced. A
    /// holder that accepts the connection is alive, and the name stays taken.
    pub fn handle(&self, call: NamingCall) -> Result<Reply, WireError> {
        let now = self.now();
        let holder = {
            let mut tree = self.lock();
            for node in tree.expire(now) {
                log::info!("naming: lease of node `{node}` lapsed; its entries are removed");
            }
            let taken_from = match &call {
                NamingCall::Register { node, address, .. } => tree
                    .node(node)
                    .filter(|l| &l.address != address && l.deadline > now)
                    .map(|l| l.address.clone()),
                _ => None,
            };
            match taken_from {
                None => return tree.apply(call, now),
                Some(holder) => holder,
            }
        };
        let NamingCall::Register { node, address, .. } = &call else {
            return Err(WireError::Call(CallError::Internal(
                "naming: register expected".into(),
            )));
        };
        if answers(&holder) {
            return self.lock().apply(call, self.now());
        }
        let mut tree = self.lock();
        // Still the same stale holder (nobody re-registered meanwhile): its entries go.
        if tree.node(node).is_some_and(|l| l.address == holder) {
            let _ = tree.unregister(node);
            log::warn!(
                "naming: node `{node}` registers from {address} while its previous registration \
                 at {holder} no longer answers: the stale entry is replaced"
            );
        }
        tree.apply(call, self.now())
    }

    /// Serves one naming call of a connection's `session`, after [`authorize`] allowed it.
    ///
    /// # Errors
    /// [`CallError::Forbidden`] if the session's role may not make this call, else as
    /// [`handle`](Self::handle).
    pub fn handle_for(&self, session: &Session, call: NamingCall) -> Result<Reply, WireError> {
        authorize(session.identity, &session.client, &call)?;
        self.handle(call)
    }

    /// A copy of the tree now (after expiring lapsed leases), for inspection.
    pub fn snapshot(&self) -> NamingTree {
        let now = self.now();
        let mut tree = self.lock();
        tree.expire(now);
        tree.clone()
    }

    /// Starts a thread that expires lapsed leases every `period`; it stops when the returned
    /// [`Reaper`] is stopped or dropped, or when the service is dropped.
    ///
    /// # Errors
    /// The OS error if the thread cannot be spawned.
    pub fn start_reaper(self: &Arc<Self>, period: Duration) -> std::io::Result<Reaper> {
        let service: Weak<NamingService> = Arc::downgrade(self);
        let stop = Arc::new((Mutex::new(false), std::sync::Condvar::new()));
        let stop2 = stop.clone();
        let handle = std::thread::Builder::new()
            .name("naming-reaper".into())
            .spawn(move || {
                let (lock, cvar) = &*stop2;
                let mut stopped = lock.lock().unwrap_or_else(|p| p.into_inner());
                loop {
                    let (guard, _) = cvar
                        .wait_timeout(stopped, period)
                        .unwrap_or_else(|p| p.into_inner());
                    stopped = guard;
                    if *stopped {
                        return;
                    }
                    match service.upgrade() {
                        Some(s) => {
                            s.expire_now();
                        }
                        None => return,
                    }
                }
            })?;
        Ok(Reaper {
            stop,
            handle: Some(handle),
            stopped: AtomicBool::new(false),
        })
    }
}

/// The reaper thread of a [`NamingService`]; stops (and is joined) on [`Reaper::stop`] or drop.
#[derive(Debug)]
pub struct Reaper {
    stop: Arc<(Mutex<bool>, std::sync::Condvar)>,
    handle: Option<JoinHandle<()>>,
    stopped: AtomicBool,
}

impl Reaper {
    /// Stops the thread and waits for it.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        if self.stopped.swap(true, Ordering::AcqRel) {
            return;
        }
        let (lock, cvar) = &*self.stop;
        *lock.lock().unwrap_or_else(|p| p.into_inner()) = true;
        cvar.notify_all();
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

impl Drop for Reaper {
    fn drop(&mut self) {
        self.halt();
    }
}

impl Service for NamingService {
    fn call(&self, session: &Session, call: Call) -> Result<Reply, WireError> {
        match call {
            Call::Ping { payload } => Ok(Reply::Pong(payload)),
            Call::NodeInfo => Ok(Reply::Node(NodeInfo {
                node: self.name.clone(),
                software: env!("CARGO_PKG_VERSION").to_string(),
                hosts_naming: true,
                objects: 0,
            })),
            Call::Naming(c) => self.handle_for(session, c),
            Call::Time => Ok(penelope_runtime::common_clock::time_reply()),
            Call::Creator(_) => Err(unsupported("creator calls")),
            Call::Object { .. } => Err(unsupported("object calls")),
            Call::Subscribe { .. } | Call::Unsubscribe { .. } => {
                Err(unsupported("telemetry subscriptions"))
            }
        }
    }
}

fn unsupported(method: &str) -> WireError {
    WireError::Call(CallError::Unsupported {
        kind: "naming service (run alone: it hosts no objects)".into(),
        method: method.into(),
    })
}
