//! The naming tree: the pure data structure of contexts, object bindings and node leases, with
//! its limits. Time is a parameter, so everything here is tested without sleeping or locking.

use std::collections::BTreeMap;
use std::time::Duration;

#[cfg(doc)]
use super::NamingService;
use penelope_protocol::proto::{
    CallError, NameEntry, NamingCall, ObjectRef, Reply, WireError, check_name,
};

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
    WireError::Call(CallError::BadName {
        name: path.chars().take(80).collect(),
        reason: reason.into(),
    })
}

pub(super) fn join(comps: &[&str]) -> String {
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
        return Err(WireError::Call(CallError::BadArgument(format!(
            "an address must have 1 to {MAX_ADDRESS_LEN} bytes"
        ))));
    }
    Ok(())
}

fn check_reference(reference: &ObjectRef) -> Result<(), WireError> {
    check_name(&reference.node)?;
    check_name(&reference.name)?;
    check_address(&reference.address)?;
    if reference.kind.len() > MAX_KIND_LEN {
        return Err(WireError::Call(CallError::BadArgument(format!(
            "a kind has at most {MAX_KIND_LEN} bytes"
        ))));
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
    /// [`CallError::BadName`]: not absolute, an empty component (`//`, trailing `/`), a component
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
                WireError::Call(CallError::BadName { reason, .. }) => {
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
    /// [`CallError::BadName`] for a bad path (or the root), [`CallError::BadArgument`] for an
    /// oversized reference, [`CallError::NameTaken`] if `path` is bound (and not `rebind`), is a
    /// context, or passes through an object, [`CallError::LimitReached`] at
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
                Some(Entry::Object(_)) => {
                    return Err(WireError::Call(CallError::NameTaken(join(&comps[..=i]))));
                }
                None => ctx = None,
            }
        }
        let replacing = match ctx.and_then(|c| c.entries.get(*last)) {
            Some(Entry::Context(_)) => {
                return Err(WireError::Call(CallError::NameTaken(path.to_string())));
            }
            Some(Entry::Object(_)) if !rebind => {
                return Err(WireError::Call(CallError::NameTaken(path.to_string())));
            }
            Some(Entry::Object(_)) => true,
            None => false,
        };
        if !replacing && self.bindings >= self.limits.max_bindings {
            return Err(WireError::Call(CallError::LimitReached {
                what: "naming bindings".into(),
                limit: self.limits.max_bindings,
            }));
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
                Entry::Object(_) => {
                    return Err(WireError::Call(CallError::Internal(
                        "naming tree changed".into(),
                    )));
                }
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
    /// [`CallError::BadName`] for a bad path, [`CallError::UnknownName`] if nothing is bound
    /// there, [`CallError::BadArgument`] if it is a context (list it instead).
    pub fn resolve(&self, path: &str) -> Result<ObjectRef, WireError> {
        let comps = self.parse_path(path)?;
        match self.root.get(&comps) {
            Some(Entry::Object(r)) => Ok(r.clone()),
            Some(Entry::Context(_)) => Err(WireError::Call(CallError::BadArgument(format!(
                "`{path}` is a context, not an object (list it)"
            )))),
            None if comps.is_empty() => Err(WireError::Call(CallError::BadArgument(
                "`/` is the root context, not an object (list it)".into(),
            ))),
            None => Err(WireError::Call(CallError::UnknownName(path.to_string()))),
        }
    }

    /// Removes the object bound at `path`, then every context above it left empty, except a
    /// registered node's own context. Returns the removed reference.
    ///
    /// # Errors
    /// [`CallError::BadName`] for a bad path, [`CallError::UnknownName`] if nothing is bound
    /// there, [`CallError::BadArgument`] if it is a context (contexts go away with their last
    /// entry, a node's with its registration).
    pub fn unbind(&mut self, path: &str) -> Result<ObjectRef, WireError> {
        let comps = self.parse_path(path)?;
        let Some((last, parents)) = comps.split_last() else {
            return Err(WireError::Call(CallError::BadArgument(
                "the root cannot be unbound".into(),
            )));
        };
        match self.root.get(&comps) {
            Some(Entry::Object(_)) => {}
            Some(Entry::Context(_)) => {
                return Err(WireError::Call(CallError::BadArgument(format!(
                    "`{path}` is a context: it goes away with its last entry \
                     (or, for a node, when the node unregisters)"
                ))));
            }
            None => return Err(WireError::Call(CallError::UnknownName(path.to_string()))),
        }
        let removed = self
            .root
            .context_mut(parents)
            .and_then(|c| c.entries.remove(*last));
        let Some(Entry::Object(reference)) = removed else {
            return Err(WireError::Call(CallError::Internal(
                "naming tree changed".into(),
            )));
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
    /// [`CallError::BadName`] for a bad path, [`CallError::UnknownName`] if there is no such
    /// context, [`CallError::BadArgument`] if `path` is an object (resolve it instead).
    pub fn list(&self, path: &str) -> Result<Vec<NameEntry>, WireError> {
        let comps = self.parse_path(path)?;
        let ctx = if comps.is_empty() {
            &self.root
        } else {
            match self.root.get(&comps) {
                Some(Entry::Context(c)) => c,
                Some(Entry::Object(_)) => {
                    return Err(WireError::Call(CallError::BadArgument(format!(
                        "`{path}` is an object, not a context (resolve it)"
                    ))));
                }
                None => return Err(WireError::Call(CallError::UnknownName(path.to_string()))),
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
    /// [`CallError::BadName`] for a bad node name, [`CallError::BadArgument`] for a bad address
    /// or a lease outside [`NamingLimits::min_lease`]..=[`NamingLimits::max_lease`],
    /// [`CallError::NameTaken`] if `/<node>` is an object or a live node of that name answers at
    /// another address, [`CallError::LimitReached`] at [`NamingLimits::max_nodes`].
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
            return Err(WireError::Call(CallError::BadArgument(format!(
                "a lease must be within {:?} and {:?}, not {lease:?}",
                self.limits.min_lease, self.limits.max_lease
            ))));
        }
        match self.nodes.get(node) {
            Some(live) if live.address != address && live.deadline > now => {
                return Err(WireError::Call(CallError::NameTaken(format!(
                    "/{node} (registered by {} whose lease runs {:?} more)",
                    live.address,
                    live.deadline.saturating_sub(now)
                ))));
            }
            Some(_) => {}
            None if self.nodes.len() >= self.limits.max_nodes as usize => {
                return Err(WireError::Call(CallError::LimitReached {
                    what: "naming nodes".into(),
                    limit: self.limits.max_nodes,
                }));
            }
            None => {}
        }
        match self.root.entries.get_mut(node) {
            Some(Entry::Object(_)) => {
                return Err(WireError::Call(CallError::NameTaken(format!("/{node}"))));
            }
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
    /// [`CallError::UnknownName`] if it is not registered (never was, or expired): the node
    /// registers again and re-binds its objects.
    pub fn renew(&mut self, node: &str, now: Duration) -> Result<(), WireError> {
        match self.nodes.get_mut(node) {
            Some(lease) => {
                lease.deadline = now.saturating_add(lease.lease);
                Ok(())
            }
            None => Err(WireError::Call(CallError::UnknownName(format!("/{node}")))),
        }
    }

    /// Removes `node` and every entry of its context.
    ///
    /// # Errors
    /// [`CallError::UnknownName`] if it is not registered.
    pub fn unregister(&mut self, node: &str) -> Result<(), WireError> {
        if self.nodes.remove(node).is_none() {
            return Err(WireError::Call(CallError::UnknownName(format!("/{node}"))));
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
