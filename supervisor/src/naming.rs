//! The naming service: one hierarchical tree of contexts for the whole system (the paper's CORBA
//! Naming Service, figure 5), with a lease per node.
//!
//! ```text
//! /
//! ├── lab-a/                  context of node `lab-a` (registered, lease 3 s)
//! │   ├── creator             -> ObjectRef { node: lab-a, address: 127.0.0.1:7301, .. }
//! │   ├── robots/
//! │   │   └── slave           -> ObjectRef { class: Robot, kind: robot/puma560, .. }
//! │   └── controllers/
//! │       └── pid             -> ObjectRef { class: Controller, .. }
//! └── lab-b/
//!     ├── creator
//!     └── sensors/
//!         └── ft              -> ObjectRef { class: Sensor, kind: sensor/virtual, .. }
//! ```
//!
//! Two layers:
//! - [`NamingTree`]: the pure data structure. Time is a parameter (`now`, a [`Duration`] since an
//!   epoch the caller picks), so leases are tested without sleeping.
//! - [`NamingService`]: the tree behind a mutex with a monotonic clock; expires lapsed leases before
//!   every call (and from an optional reaper thread), and serves [`NamingCall`]s. It implements
//!   [`Service`], so it can run alone (`penelope naming`); a node that hosts the naming service
//!   routes [`Call::Naming`] to it.
//!
//! # Rules
//! - Paths are absolute: `/` (the root) or `/c1/c2/...`, each component checked by
//!   [`check_name`], at most [`NamingLimits::max_depth`] components.
//! - [`NamingTree::bind`] creates the missing intermediate contexts; an existing binding is
//!   [`WireError::NameTaken`] unless `rebind`; a context is never replaced by an object.
//! - [`NamingTree::unbind`] removes one object and then every context above it that became empty,
//!   except a registered node's own context `/<node>` (and the root). So an empty context exists
//!   only as the root or as a registered node's context.
//! - A binding is owned by the node whose context it is in (`/<node>/...`). When the node's lease
//!   lapses ([`NamingTree::expire`]) or it unregisters, its whole context goes. Bindings outside
//!   a registered node's context belong to nobody and never expire.
//! - [`NamingTree::register`] starts (or restarts) a node: its context is created, or emptied if
//!   it exists (entries of a previous run are stale). A live node's name cannot be taken by a
//!   node at another address until its lease lapses.
//!
//! # Authorization
//! Calls that come over a connection go through [`NamingService::handle_for`], which checks the
//! session's [`Identity`] with [`authorize`] first:
//! - anyone may `Resolve` and `List`;
//! - a [`Role::Node`] session named `n` (its hello's name) may `Register`, `Renew` and
//!   `Unregister` only `n`, and `Bind` (rebind included) and `Unbind` only paths under `/n/`;
//! - a [`Role::Admin`] session may do everything;
//! - a [`Role::Reader`] session may not write the tree.
//!
//! Refusals are [`WireError::Forbidden`]. A node's own calls to the naming service it hosts do
//! not cross a connection and are not checked (it is the node).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, Weak};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::proto::{
    Call, NameEntry, NamingCall, NodeInfo, ObjectRef, Reply, Role, WireError, check_name,
};
use crate::service::{Identity, Service, Session};

/// Longest `address` of a node or of an [`ObjectRef`], bytes.
pub const MAX_ADDRESS_LEN: usize = 256;

/// Longest `kind` of an [`ObjectRef`], bytes.
pub const MAX_KIND_LEN: usize = 128;

/// Bounds of a naming tree (memory stays bounded whatever clients send).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NamingLimits {
    /// Object bindings in the whole tree.
    pub max_bindings: u32,
    /// Components of a path (`/a/b/c` has 3).
    pub max_depth: u32,
    /// Registered nodes.
    pub max_nodes: u32,
    /// Shortest lease a node may ask for.
    pub min_lease: Duration,
    /// Longest lease a node may ask for.
    pub max_lease: Duration,
}

impl Default for NamingLimits {
    fn default() -> Self {
        NamingLimits {
            max_bindings: 10_000,
            max_depth: 8,
            max_nodes: 256,
            min_lease: Duration::from_millis(10),
            max_lease: Duration::from_secs(3600),
        }
    }
}

/// A registered node, as [`NamingTree::nodes`] shows it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeLease {
    /// The node's name (its context `/<node>`).
    pub node: String,
    /// Where it answers (`host:port`).
    pub address: String,
    /// Its lease.
    pub lease: Duration,
    /// When the lease lapses, on the tree's time axis.
    pub deadline: Duration,
}

#[derive(Clone, Debug, Default, PartialEq)]
struct Context {
    entries: BTreeMap<String, Entry>,
}

#[derive(Clone, Debug, PartialEq)]
enum Entry {
    Context(Context),
    Object(ObjectRef),
}

impl Context {
    /// Object bindings in this context and below.
    fn count(&self) -> u32 {
        self.entries
            .values()
            .map(|e| match e {
                Entry::Context(c) => c.count(),
                Entry::Object(_) => 1,
            })
            .sum()
    }

    fn get(&self, comps: &[&str]) -> Option<&Entry> {
        let (first, rest) = comps.split_first()?;
        let entry = self.entries.get(*first)?;
        if rest.is_empty() {
            return Some(entry);
        }
        match entry {
            Entry::Context(c) => c.get(rest),
            Entry::Object(_) => None,
        }
    }

    fn context_mut(&mut self, comps: &[&str]) -> Option<&mut Context> {
        let Some((first, rest)) = comps.split_first() else {
            return Some(self);
        };
        match self.entries.get_mut(*first)? {
            Entry::Context(c) => c.context_mut(rest),
            Entry::Object(_) => None,
        }
    }
}

/// The naming tree: contexts, object bindings and node leases.
///
/// Time is passed in: every `now` is a [`Duration`] since an epoch of the caller's choice, the
/// same for every call on one tree.
#[derive(Clone, Debug)]
pub struct NamingTree {
    root: Context,
    nodes: BTreeMap<String, NodeLease>,
    bindings: u32,
    limits: NamingLimits,
}

impl Default for NamingTree {
    fn default() -> Self {
        NamingTree::new(NamingLimits::default())
    }
}

fn bad_name(path: &str, reason: impl Into<String>) -> WireError {
    WireError::BadName {
        name: path.chars().take(80).collect(),
        reason: reason.into(),
    }
}

fn join(comps: &[&str]) -> String {
    if comps.is_empty() {
        "/".to_string()
    } else {
        comps.iter().fold(String::new(), |mut s, c| {
            s.push('/');
            s.push_str(c);
            s
        })
    }
}

fn check_address(address: &str) -> Result<(), WireError> {
    if address.is_empty() || address.len() > MAX_ADDRESS_LEN {
        return Err(WireError::BadArgument(format!(
            "an address must have 1 to {MAX_ADDRESS_LEN} bytes"
        )));
    }
    Ok(())
}

fn check_reference(reference: &ObjectRef) -> Result<(), WireError> {
    check_name(&reference.node)?;
    check_name(&reference.name)?;
    check_address(&reference.address)?;
    if reference.kind.len() > MAX_KIND_LEN {
        return Err(WireError::BadArgument(format!(
            "a kind has at most {MAX_KIND_LEN} bytes"
        )));
    }
    Ok(())
}

impl NamingTree {
    /// An empty tree (only the root context) with `limits`.
    pub fn new(limits: NamingLimits) -> Self {
        NamingTree {
            root: Context::default(),
            nodes: BTreeMap::new(),
            bindings: 0,
            limits,
        }
    }

    /// The tree's limits.
    pub fn limits(&self) -> &NamingLimits {
        &self.limits
    }

    /// Object bindings in the whole tree.
    pub fn binding_count(&self) -> u32 {
        self.bindings
    }

    /// The registered nodes, by name.
    pub fn nodes(&self) -> Vec<NodeLease> {
        self.nodes.values().cloned().collect()
    }

    /// The registered node `node`, if any.
    pub fn node(&self, node: &str) -> Option<&NodeLease> {
        self.nodes.get(node)
    }

    /// Splits an absolute path into checked components (`/` gives none).
    ///
    /// # Errors
    /// [`WireError::BadName`]: not absolute, an empty component (`//`, trailing `/`), a component
    /// refused by [`check_name`], or deeper than [`NamingLimits::max_depth`].
    pub fn parse_path<'p>(&self, path: &'p str) -> Result<Vec<&'p str>, WireError> {
        let Some(rest) = path.strip_prefix('/') else {
            return Err(bad_name(path, "a path starts with `/`"));
        };
        if rest.is_empty() {
            return Ok(Vec::new());
        }
        let max = self.limits.max_depth as usize;
        let mut comps = Vec::new();
        for comp in rest.split('/') {
            if comps.len() == max {
                return Err(bad_name(path, format!("deeper than {max} components")));
            }
            if comp.is_empty() {
                return Err(bad_name(path, "empty component (`//` or a trailing `/`)"));
            }
            check_name(comp).map_err(|e| match e {
                WireError::BadName { reason, .. } => {
                    bad_name(path, format!("component `{comp}`: {reason}"))
                }
                other => other,
            })?;
            comps.push(comp);
        }
        Ok(comps)
    }

    /// Binds `path` to `reference`, creating the missing contexts above it.
    ///
    /// # Errors
    /// [`WireError::BadName`] for a bad path (or the root), [`WireError::BadArgument`] for an
    /// oversized reference, [`WireError::NameTaken`] if `path` is bound (and not `rebind`), is a
    /// context, or passes through an object, [`WireError::LimitReached`] at
    /// [`NamingLimits::max_bindings`]. Nothing changes on error.
    pub fn bind(
        &mut self,
        path: &str,
        reference: ObjectRef,
        rebind: bool,
    ) -> Result<(), WireError> {
        let comps = self.parse_path(path)?;
        let Some((last, parents)) = comps.split_last() else {
            return Err(bad_name(path, "the root cannot be bound"));
        };
        check_reference(&reference)?;
        // Check everything before changing anything.
        let mut ctx = Some(&self.root);
        for (i, comp) in parents.iter().enumerate() {
            match ctx.and_then(|c| c.entries.get(*comp)) {
                Some(Entry::Context(c)) => ctx = Some(c),
                Some(Entry::Object(_)) => return Err(WireError::NameTaken(join(&comps[..=i]))),
                None => ctx = None,
            }
        }
        let replacing = match ctx.and_then(|c| c.entries.get(*last)) {
            Some(Entry::Context(_)) => return Err(WireError::NameTaken(path.to_string())),
            Some(Entry::Object(_)) if !rebind => {
                return Err(WireError::NameTaken(path.to_string()));
            }
            Some(Entry::Object(_)) => true,
            None => false,
        };
        if !replacing && self.bindings >= self.limits.max_bindings {
            return Err(WireError::LimitReached {
                what: "naming bindings".into(),
                limit: self.limits.max_bindings,
            });
        }
        let mut ctx = &mut self.root;
        for comp in parents {
            let entry = ctx
                .entries
                .entry((*comp).to_string())
                .or_insert_with(|| Entry::Context(Context::default()));
            ctx = match entry {
                Entry::Context(c) => c,
                // Checked above: no object on the way.
                Entry::Object(_) => return Err(WireError::Internal("naming tree changed".into())),
            };
        }
        ctx.entries
            .insert((*last).to_string(), Entry::Object(reference));
        if !replacing {
            self.bindings += 1;
        }
        Ok(())
    }

    /// What `path` names.
    ///
    /// # Errors
    /// [`WireError::BadName`] for a bad path, [`WireError::UnknownName`] if nothing is bound
    /// there, [`WireError::BadArgument`] if it is a context (list it instead).
    pub fn resolve(&self, path: &str) -> Result<ObjectRef, WireError> {
        let comps = self.parse_path(path)?;
        match self.root.get(&comps) {
            Some(Entry::Object(r)) => Ok(r.clone()),
            Some(Entry::Context(_)) => Err(WireError::BadArgument(format!(
                "`{path}` is a context, not an object (list it)"
            ))),
            None if comps.is_empty() => Err(WireError::BadArgument(
                "`/` is the root context, not an object (list it)".into(),
            )),
            None => Err(WireError::UnknownName(path.to_string())),
        }
    }

    /// Removes the object bound at `path`, then every context above it left empty, except a
    /// registered node's own context. Returns the removed reference.
    ///
    /// # Errors
    /// [`WireError::BadName`] for a bad path, [`WireError::UnknownName`] if nothing is bound
    /// there, [`WireError::BadArgument`] if it is a context (contexts go away with their last
    /// entry, a node's with its registration).
    pub fn unbind(&mut self, path: &str) -> Result<ObjectRef, WireError> {
        let comps = self.parse_path(path)?;
        let Some((last, parents)) = comps.split_last() else {
            return Err(WireError::BadArgument("the root cannot be unbound".into()));
        };
        match self.root.get(&comps) {
            Some(Entry::Object(_)) => {}
            Some(Entry::Context(_)) => {
                return Err(WireError::BadArgument(format!(
                    "`{path}` is a context: it goes away with its last entry \
                     (or, for a node, when the node unregisters)"
                )));
            }
            None => return Err(WireError::UnknownName(path.to_string())),
        }
        let removed = self
            .root
            .context_mut(parents)
            .and_then(|c| c.entries.remove(*last));
        let Some(Entry::Object(reference)) = removed else {
            return Err(WireError::Internal("naming tree changed".into()));
        };
        self.bindings -= 1;
        // Prune the contexts left empty, deepest first.
        for k in (1..comps.len()).rev() {
            if k == 1 && self.nodes.contains_key(comps[0]) {
                break;
            }
            let empty = matches!(
                self.root.get(&comps[..k]),
                Some(Entry::Context(c)) if c.entries.is_empty()
            );
            if !empty {
                break;
            }
            if let Some(parent) = self.root.context_mut(&comps[..k - 1]) {
                parent.entries.remove(comps[k - 1]);
            }
        }
        Ok(reference)
    }

    /// The entries of the context at `path` (`/` for the root), sorted by name.
    ///
    /// # Errors
    /// [`WireError::BadName`] for a bad path, [`WireError::UnknownName`] if there is no such
    /// context, [`WireError::BadArgument`] if `path` is an object (resolve it instead).
    pub fn list(&self, path: &str) -> Result<Vec<NameEntry>, WireError> {
        let comps = self.parse_path(path)?;
        let ctx = if comps.is_empty() {
            &self.root
        } else {
            match self.root.get(&comps) {
                Some(Entry::Context(c)) => c,
                Some(Entry::Object(_)) => {
                    return Err(WireError::BadArgument(format!(
                        "`{path}` is an object, not a context (resolve it)"
                    )));
                }
                None => return Err(WireError::UnknownName(path.to_string())),
            }
        };
        Ok(ctx
            .entries
            .iter()
            .map(|(name, e)| match e {
                Entry::Context(_) => NameEntry::Context { name: name.clone() },
                Entry::Object(r) => NameEntry::Object {
                    name: name.clone(),
                    reference: r.clone(),
                },
            })
            .collect())
    }

    /// Registers node `node` answering at `address` with `lease`, at time `now`: its context
    /// `/<node>` is created, or emptied if it exists (a restarted node re-binds its objects).
    ///
    /// # Errors
    /// [`WireError::BadName`] for a bad node name, [`WireError::BadArgument`] for a bad address
    /// or a lease outside [`NamingLimits::min_lease`]..=[`NamingLimits::max_lease`],
    /// [`WireError::NameTaken`] if `/<node>` is an object or a live node of that name answers at
    /// another address, [`WireError::LimitReached`] at [`NamingLimits::max_nodes`].
    pub fn register(
        &mut self,
        node: &str,
        address: &str,
        lease: Duration,
        now: Duration,
    ) -> Result<(), WireError> {
        check_name(node)?;
        check_address(address)?;
        if lease < self.limits.min_lease || lease > self.limits.max_lease {
            return Err(WireError::BadArgument(format!(
                "a lease must be within {:?} and {:?}, not {lease:?}",
                self.limits.min_lease, self.limits.max_lease
            )));
        }
        match self.nodes.get(node) {
            Some(live) if live.address != address && live.deadline > now => {
                return Err(WireError::NameTaken(format!(
                    "/{node} (registered by {} whose lease runs {:?} more)",
                    live.address,
                    live.deadline.saturating_sub(now)
                )));
            }
            Some(_) => {}
            None if self.nodes.len() >= self.limits.max_nodes as usize => {
                return Err(WireError::LimitReached {
                    what: "naming nodes".into(),
                    limit: self.limits.max_nodes,
                });
            }
            None => {}
        }
        match self.root.entries.get_mut(node) {
            Some(Entry::Object(_)) => return Err(WireError::NameTaken(format!("/{node}"))),
            Some(Entry::Context(c)) => {
                self.bindings -= c.count();
                c.entries.clear();
            }
            None => {
                self.root
                    .entries
                    .insert(node.to_string(), Entry::Context(Context::default()));
            }
        }
        self.nodes.insert(
            node.to_string(),
            NodeLease {
                node: node.to_string(),
                address: address.to_string(),
                lease,
                deadline: now.saturating_add(lease),
            },
        );
        Ok(())
    }

    /// Renews the lease of `node` at time `now`.
    ///
    /// # Errors
    /// [`WireError::UnknownName`] if it is not registered (never was, or expired): the node
    /// registers again and re-binds its objects.
    pub fn renew(&mut self, node: &str, now: Duration) -> Result<(), WireError> {
        match self.nodes.get_mut(node) {
            Some(lease) => {
                lease.deadline = now.saturating_add(lease.lease);
                Ok(())
            }
            None => Err(WireError::UnknownName(format!("/{node}"))),
        }
    }

    /// Removes `node` and every entry of its context.
    ///
    /// # Errors
    /// [`WireError::UnknownName`] if it is not registered.
    pub fn unregister(&mut self, node: &str) -> Result<(), WireError> {
        if self.nodes.remove(node).is_none() {
            return Err(WireError::UnknownName(format!("/{node}")));
        }
        self.drop_context(node);
        Ok(())
    }

    fn drop_context(&mut self, node: &str) {
        if let Some(Entry::Context(c)) = self.root.entries.remove(node) {
            self.bindings -= c.count();
        }
    }

    /// Removes every node whose lease lapsed at `now` (deadline `<= now`) with all the entries of
    /// its context; returns their names.
    pub fn expire(&mut self, now: Duration) -> Vec<String> {
        let lapsed: Vec<String> = self
            .nodes
            .values()
            .filter(|l| l.deadline <= now)
            .map(|l| l.node.clone())
            .collect();
        for node in &lapsed {
            self.nodes.remove(node);
            self.drop_context(node);
        }
        lapsed
    }

    /// The earliest lease deadline, if any node is registered.
    pub fn next_deadline(&self) -> Option<Duration> {
        self.nodes.values().map(|l| l.deadline).min()
    }

    /// Serves one naming call at time `now` (without expiring first: see
    /// [`NamingService::handle`]).
    ///
    /// # Errors
    /// The call's typed error, as the methods above document.
    pub fn apply(&mut self, call: NamingCall, now: Duration) -> Result<Reply, WireError> {
        match call {
            NamingCall::Register {
                node,
                address,
                lease_ms,
            } => self
                .register(
                    &node,
                    &address,
                    Duration::from_millis(u64::from(lease_ms)),
                    now,
                )
                .map(|()| Reply::Unit),
            NamingCall::Renew { node } => self.renew(&node, now).map(|()| Reply::Unit),
            NamingCall::Unregister { node } => self.unregister(&node).map(|()| Reply::Unit),
            NamingCall::Bind {
                path,
                reference,
                rebind,
            } => self.bind(&path, reference, rebind).map(|()| Reply::Unit),
            NamingCall::Resolve { path } => self.resolve(&path).map(Reply::Resolved),
            NamingCall::Unbind { path } => self.unbind(&path).map(|_| Reply::Unit),
            NamingCall::List { context } => self.list(&context).map(Reply::Names),
        }
    }

    /// Checks the tree's invariants; `Err` says which one broke (for tests).
    ///
    /// # Errors
    /// A description of the first broken invariant: a binding count that disagrees with the tree,
    /// a registered node without its context, an empty context that is neither the root nor a
    /// registered node's, or a path deeper than the limit.
    pub fn check_invariants(&self) -> Result<(), String> {
        let counted = self.root.count();
        if counted != self.bindings {
            return Err(format!(
                "{counted} objects but a count of {}",
                self.bindings
            ));
        }
        if counted > self.limits.max_bindings {
            return Err(format!("{counted} objects over the limit"));
        }
        for node in self.nodes.keys() {
            if !matches!(self.root.entries.get(node), Some(Entry::Context(_))) {
                return Err(format!("registered node `{node}` has no context"));
            }
        }
        fn walk(tree: &NamingTree, ctx: &Context, path: &mut Vec<String>) -> Result<(), String> {
            if path.len() > tree.limits.max_depth as usize {
                return Err(format!("`/{}` is too deep", path.join("/")));
            }
            let protected =
                path.is_empty() || (path.len() == 1 && tree.nodes.contains_key(&path[0]));
            if ctx.entries.is_empty() && !protected {
                return Err(format!("empty context `/{}` lingers", path.join("/")));
            }
            for (name, e) in &ctx.entries {
                if let Entry::Context(c) = e {
                    path.push(name.clone());
                    walk(tree, c, path)?;
                    path.pop();
                }
            }
            Ok(())
        }
        walk(self, &self.root, &mut Vec::new())
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

    fn lock(&self) -> MutexGuard<'_, NamingTree> {
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
    pub fn handle(&self, call: NamingCall) -> Result<Reply, WireError> {
        let now = self.now();
        let mut tree = self.lock();
        for node in tree.expire(now) {
            log::info!("naming: lease of node `{node}` lapsed; its entries are removed");
        }
        tree.apply(call, now)
    }

    /// Serves one naming call of a connection's `session`, after [`authorize`] allowed it.
    ///
    /// # Errors
    /// [`WireError::Forbidden`] if the session's role may not make this call, else as
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
            Call::Creator(_) => Err(unsupported("creator calls")),
            Call::Object { .. } => Err(unsupported("object calls")),
            Call::Subscribe { .. } | Call::Unsubscribe { .. } => {
                Err(unsupported("telemetry subscriptions"))
            }
        }
    }
}

/// Whether a session of `identity`, named `client` in its hello, may make `call` (see the
/// module's rules).
///
/// # Errors
/// [`WireError::Forbidden`] saying what is refused and why.
pub fn authorize(identity: Identity, client: &str, call: &NamingCall) -> Result<(), WireError> {
    let own_node = |node: &str, what: &str| match identity.role {
        Role::Admin => Ok(()),
        Role::Node if node == client => Ok(()),
        Role::Node => Err(WireError::Forbidden(format!(
            "node `{client}` may {what} only itself, not `{node}`"
        ))),
        Role::Reader => Err(WireError::Forbidden(format!(
            "`{client}` is a reader: it may not {what} a node (connect as that node or with the \
             admin secret)"
        ))),
    };
    let own_path = |path: &str, what: &str| {
        let owner = path.strip_prefix('/').and_then(|p| p.split('/').next());
        match identity.role {
            Role::Admin => Ok(()),
            Role::Node if owner == Some(client) && path.len() > client.len() + 2 => Ok(()),
            Role::Node => Err(WireError::Forbidden(format!(
                "node `{client}` may {what} only under `/{client}/`, not `{path}`"
            ))),
            Role::Reader => Err(WireError::Forbidden(format!(
                "`{client}` is a reader: it may not {what} `{path}`"
            ))),
        }
    };
    match call {
        NamingCall::Resolve { .. } | NamingCall::List { .. } => Ok(()),
        NamingCall::Register { node, .. } => own_node(node, "register"),
        NamingCall::Renew { node } => own_node(node, "renew"),
        NamingCall::Unregister { node } => own_node(node, "unregister"),
        NamingCall::Bind { path, rebind, .. } => {
            own_path(path, if *rebind { "rebind" } else { "bind" })
        }
        NamingCall::Unbind { path } => own_path(path, "unbind"),
    }
}

fn unsupported(method: &str) -> WireError {
    WireError::Unsupported {
        kind: "naming service (run alone: it hosts no objects)".into(),
        method: method.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proto::Class;
    use proptest::prelude::*;

    fn r(node: &str, name: &str) -> ObjectRef {
        ObjectRef {
            node: node.into(),
            address: "127.0.0.1:7301".into(),
            name: name.into(),
            class: Class::Robot,
            kind: "robot/puma560".into(),
        }
    }

    const S: fn(u64) -> Duration = Duration::from_secs;

    #[test]
    fn bind_resolve_list_unbind() {
        let mut t = NamingTree::default();
        t.bind("/lab/robots/slave", r("lab", "slave"), false)
            .unwrap();
        assert_eq!(t.resolve("/lab/robots/slave").unwrap().name, "slave");
        assert_eq!(
            t.list("/").unwrap(),
            vec![NameEntry::Context { name: "lab".into() }]
        );
        assert_eq!(
            t.list("/lab").unwrap(),
            vec![NameEntry::Context {
                name: "robots".into()
            }]
        );
        assert!(matches!(
            t.bind("/lab/robots/slave", r("lab", "x"), false),
            Err(WireError::NameTaken(_))
        ));
        t.bind("/lab/robots/slave", r("lab", "x"), true).unwrap();
        assert_eq!(t.resolve("/lab/robots/slave").unwrap().name, "x");
        assert_eq!(t.binding_count(), 1);
        t.bind("/lab/robots/master", r("lab", "m"), false).unwrap();
        let names: Vec<_> = t
            .list("/lab/robots")
            .unwrap()
            .iter()
            .map(|e| e.name().to_string())
            .collect();
        assert_eq!(names, ["master", "slave"]);
        // Contexts and objects do not replace each other.
        assert!(matches!(
            t.bind("/lab/robots", r("lab", "x"), true),
            Err(WireError::NameTaken(_))
        ));
        assert!(matches!(
            t.bind("/lab/robots/slave/deeper", r("lab", "x"), true),
            Err(WireError::NameTaken(p)) if p == "/lab/robots/slave"
        ));
        assert!(matches!(t.resolve("/lab"), Err(WireError::BadArgument(_))));
        assert!(matches!(
            t.list("/lab/robots/slave"),
            Err(WireError::BadArgument(_))
        ));
        assert!(matches!(t.resolve("/nope"), Err(WireError::UnknownName(_))));
        assert!(matches!(t.unbind("/lab"), Err(WireError::BadArgument(_))));
        t.unbind("/lab/robots/slave").unwrap();
        assert!(t.list("/lab/robots").is_ok());
        t.unbind("/lab/robots/master").unwrap();
        // Unregistered contexts left empty go away.
        assert!(t.list("/").unwrap().is_empty());
        assert_eq!(t.binding_count(), 0);
        assert!(matches!(
            t.unbind("/lab/robots/master"),
            Err(WireError::UnknownName(_))
        ));
        t.check_invariants().unwrap();
    }

    #[test]
    fn paths_are_checked() {
        let t = NamingTree::default();
        for bad in [
            "", "lab", "/lab/", "//lab", "/lab//x", "/a b", "/../x", "/a/./b",
        ] {
            assert!(
                matches!(t.resolve(bad), Err(WireError::BadName { .. })),
                "{bad:?}"
            );
        }
        let deep = "/a".repeat(9);
        assert!(matches!(t.list(&deep), Err(WireError::BadName { .. })));
        assert!(t.parse_path(&"/a".repeat(8)).is_ok());
        let mut t = t;
        assert!(matches!(
            t.bind("/", r("a", "b"), true),
            Err(WireError::BadName { .. })
        ));
        let mut bad_ref = r("lab", "x");
        bad_ref.address = "x".repeat(MAX_ADDRESS_LEN + 1);
        assert!(matches!(
            t.bind("/a/b", bad_ref, false),
            Err(WireError::BadArgument(_))
        ));
        t.check_invariants().unwrap();
    }

    #[test]
    fn limits_refuse_without_changing_anything() {
        let mut t = NamingTree::new(NamingLimits {
            max_bindings: 2,
            max_nodes: 1,
            ..NamingLimits::default()
        });
        t.bind("/a/x", r("a", "x"), false).unwrap();
        t.bind("/a/y", r("a", "y"), false).unwrap();
        assert!(matches!(
            t.bind("/b/c/z", r("a", "z"), false),
            Err(WireError::LimitReached { limit: 2, .. })
        ));
        // A rebind is not a new binding.
        t.bind("/a/y", r("a", "y2"), true).unwrap();
        assert_eq!(t.list("/").unwrap().len(), 1, "no context was left behind");
        t.register("n1", "h:1", S(1), S(0)).unwrap();
        assert!(matches!(
            t.register("n2", "h:2", S(1), S(0)),
            Err(WireError::LimitReached { .. })
        ));
        assert!(matches!(
            t.register("n1", "h:1", Duration::from_millis(1), S(0)),
            Err(WireError::BadArgument(_))
        ));
        t.check_invariants().unwrap();
    }

    #[test]
    fn a_node_context_lives_with_its_lease() {
        let mut t = NamingTree::default();
        t.register("a", "127.0.0.1:1", S(3), S(0)).unwrap();
        t.register("b", "127.0.0.1:2", S(3), S(0)).unwrap();
        t.bind("/a/creator", r("a", "creator"), false).unwrap();
        t.bind("/a/robots/slave", r("a", "slave"), false).unwrap();
        t.bind("/b/sensors/ft", r("b", "ft"), false).unwrap();
        t.bind("/shared/thing", r("b", "thing"), false).unwrap();
        // A registered node's context survives its last unbind.
        t.unbind("/a/robots/slave").unwrap();
        t.unbind("/a/creator").unwrap();
        assert_eq!(t.list("/a").unwrap(), vec![]);
        t.bind("/a/robots/slave", r("a", "slave"), false).unwrap();
        // Renewals keep it alive.
        assert!(t.expire(S(2)).is_empty());
        t.renew("a", S(2)).unwrap();
        assert_eq!(t.expire(S(3)), vec!["b".to_string()]);
        assert!(matches!(
            t.resolve("/b/sensors/ft"),
            Err(WireError::UnknownName(_))
        ));
        assert!(matches!(t.renew("b", S(3)), Err(WireError::UnknownName(_))));
        // Bindings outside a node context belong to nobody.
        assert!(t.resolve("/shared/thing").is_ok());
        assert_eq!(t.expire(S(5)), vec!["a".to_string()]);
        assert_eq!(
            t.list("/").unwrap(),
            vec![NameEntry::Context {
                name: "shared".into()
            }]
        );
        assert_eq!(t.binding_count(), 1);
        t.check_invariants().unwrap();
    }

    #[test]
    fn registering_again_starts_afresh_and_names_are_not_stolen() {
        let mut t = NamingTree::default();
        t.register("a", "h:1", S(3), S(0)).unwrap();
        t.bind("/a/robots/slave", r("a", "slave"), false).unwrap();
        assert!(matches!(
            t.register("a", "h:2", S(3), S(1)),
            Err(WireError::NameTaken(_))
        ));
        t.register("a", "h:1", S(3), S(1)).unwrap();
        assert_eq!(t.list("/a").unwrap(), vec![]);
        assert_eq!(t.binding_count(), 0);
        // After the lease lapsed, another address may take the name.
        t.register("a", "h:2", S(3), S(4)).unwrap();
        assert_eq!(t.node("a").unwrap().address, "h:2");
        t.bind("/c", r("a", "c"), false).unwrap();
        assert!(matches!(
            t.register("c", "h:3", S(3), S(4)),
            Err(WireError::NameTaken(_))
        ));
        t.unregister("a").unwrap();
        assert!(matches!(t.unregister("a"), Err(WireError::UnknownName(_))));
        t.check_invariants().unwrap();
    }

    #[test]
    fn the_service_serves_naming_calls_and_refuses_the_rest() {
        let s = NamingService::new("naming", NamingLimits::default());
        s.handle(NamingCall::Register {
            node: "a".into(),
            address: "h:1".into(),
            lease_ms: 20,
        })
        .unwrap();
        s.handle(NamingCall::Bind {
            path: "/a/creator".into(),
            reference: r("a", "creator"),
            rebind: false,
        })
        .unwrap();
        assert!(matches!(
            s.handle(NamingCall::Resolve {
                path: "/a/creator".into()
            }),
            Ok(Reply::Resolved(_))
        ));
        std::thread::sleep(Duration::from_millis(40));
        assert!(matches!(
            s.handle(NamingCall::Resolve {
                path: "/a/creator".into()
            }),
            Err(WireError::UnknownName(_))
        ));
        let (outbox, _rx) = crate::service::Outbox::bounded(1);
        let session = Session {
            id: 1,
            peer: "127.0.0.1:1".parse().unwrap(),
            client: "t".into(),
            identity: crate::service::Identity::LOCAL_NODE,
            outbox,
        };
        assert!(matches!(
            s.call(&session, Call::NodeInfo),
            Ok(Reply::Node(NodeInfo {
                hosts_naming: true,
                ..
            }))
        ));
        assert!(matches!(
            s.call(&session, Call::Creator(crate::proto::CreatorCall::Kinds)),
            Err(WireError::Unsupported { .. })
        ));
    }

    #[test]
    fn authorization_follows_the_role_and_the_own_context() {
        let node = Identity {
            role: Role::Node,
            proven: true,
        };
        let reader = Identity {
            role: Role::Reader,
            proven: true,
        };
        let admin = Identity {
            role: Role::Admin,
            proven: true,
        };
        let bind = |path: &str| NamingCall::Bind {
            path: path.into(),
            reference: r("a", "x"),
            rebind: true,
        };
        let unbind = |path: &str| NamingCall::Unbind { path: path.into() };
        let unregister = |n: &str| NamingCall::Unregister { node: n.into() };
        let list = NamingCall::List {
            context: "/b".into(),
        };
        for who in [node, reader, admin] {
            assert!(authorize(who, "a", &list).is_ok());
        }
        assert!(authorize(node, "a", &bind("/a/robots/x")).is_ok());
        assert!(authorize(node, "a", &unbind("/a/x")).is_ok());
        assert!(authorize(node, "a", &unregister("a")).is_ok());
        for call in [
            bind("/b/robots/x"),
            bind("/ab/x"),
            bind("/a"),
            bind("a/x"),
            bind("/"),
            unbind("/b/x"),
            unregister("b"),
        ] {
            assert!(
                matches!(authorize(node, "a", &call), Err(WireError::Forbidden(_))),
                "{call:?}"
            );
            assert!(matches!(
                authorize(reader, "a", &call),
                Err(WireError::Forbidden(_))
            ));
            assert!(authorize(admin, "a", &call).is_ok());
        }
    }

    #[test]
    fn the_reaper_expires_without_calls() {
        let s = Arc::new(NamingService::new("naming", NamingLimits::default()));
        s.handle(NamingCall::Register {
            node: "a".into(),
            address: "h:1".into(),
            lease_ms: 10,
        })
        .unwrap();
        let reaper = s.start_reaper(Duration::from_millis(5)).unwrap();
        let t0 = Instant::now();
        while s.lock().node("a").is_some() && t0.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(s.lock().node("a").is_none());
        reaper.stop();
    }

    #[derive(Clone, Debug)]
    enum Op {
        Bind(Vec<u8>, bool),
        Unbind(Vec<u8>),
        Register(u8, u8),
        Renew(u8),
        Unregister(u8),
        Advance(u8),
    }

    const NAMES: [&str; 4] = ["a", "b", "c", "d"];

    fn path_of(comps: &[u8]) -> String {
        join(
            &comps
                .iter()
                .map(|c| NAMES[*c as usize % 4])
                .collect::<Vec<_>>(),
        )
    }

    fn op() -> impl Strategy<Value = Op> {
        let comps = prop::collection::vec(0u8..4, 1..5);
        prop_oneof![
            4 => (comps.clone(), any::<bool>()).prop_map(|(c, r)| Op::Bind(c, r)),
            3 => comps.prop_map(Op::Unbind),
            2 => (0u8..4, 0u8..2).prop_map(|(n, a)| Op::Register(n, a)),
            2 => (0u8..4).prop_map(Op::Renew),
            1 => (0u8..4).prop_map(Op::Unregister),
            2 => (0u8..5).prop_map(Op::Advance),
        ]
    }

    proptest! {
        #[test]
        fn random_operations_keep_the_tree_consistent(ops in prop::collection::vec(op(), 1..60)) {
            let mut t = NamingTree::new(NamingLimits {
                max_bindings: 12,
                max_depth: 4,
                max_nodes: 3,
                ..NamingLimits::default()
            });
            let mut now = Duration::ZERO;
            for op in ops {
                match op {
                    Op::Bind(c, rebind) => {
                        let _ = t.bind(&path_of(&c), r("a", "x"), rebind);
                    }
                    Op::Unbind(c) => {
                        let _ = t.unbind(&path_of(&c));
                    }
                    Op::Register(n, a) => {
                        let _ = t.register(NAMES[n as usize], &format!("h:{a}"), S(3), now);
                    }
                    Op::Renew(n) => {
                        let _ = t.renew(NAMES[n as usize], now);
                    }
                    Op::Unregister(n) => {
                        let _ = t.unregister(NAMES[n as usize]);
                    }
                    Op::Advance(s) => {
                        now += S(u64::from(s));
                        for node in t.expire(now) {
                            let path = format!("/{node}");
                            prop_assert!(t.node(&node).is_none(), "{} still registered", path);
                        }
                    }
                }
                if let Err(e) = t.check_invariants() {
                    prop_assert!(false, "{}", e);
                }
                // Every resolvable path lists in its parent.
                for comps in all_paths(4) {
                    let path = path_of(&comps);
                    if let Ok(reference) = t.resolve(&path) {
                        let parent = path_of(&comps[..comps.len() - 1]);
                        let name = NAMES[*comps.last().unwrap() as usize];
                        let listed = t.list(&parent).unwrap();
                        let entry = NameEntry::Object { name: name.into(), reference };
                        prop_assert!(listed.contains(&entry), "{} not listed in {}", path, parent);
                    }
                }
                // No node outlives its lease.
                for l in t.nodes() {
                    prop_assert!(l.deadline > now, "{} outlived its lease", l.node);
                }
            }
        }
    }

    fn all_paths(depth: usize) -> Vec<Vec<u8>> {
        let mut out: Vec<Vec<u8>> = Vec::new();
        let mut layer: Vec<Vec<u8>> = vec![vec![]];
        for _ in 0..depth {
            let mut next = Vec::new();
            for p in &layer {
                for c in 0..4u8 {
                    let mut q = p.clone();
                    q.push(c);
                    next.push(q);
                }
            }
            out.extend(next.iter().cloned());
            layer = next;
        }
        out
    }
}
