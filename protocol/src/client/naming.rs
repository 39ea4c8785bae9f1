//! The naming service's proxy: one tree of contexts for the whole system, bound, resolved,
//! listed and walked by path.

use crate::net::conn::RpcError;
use crate::proto::{Call, CallError, NameEntry, NamingCall, ObjectRef, Reply, WireError};

use super::{Client, unexpected};

/// The deepest context [`NamingProxy::tree`] walks into.
pub const MAX_TREE_DEPTH: usize = 16;

/// The naming service (the paper's CORBA naming service): one tree of contexts for the system.
#[derive(Clone, Debug)]
pub struct NamingProxy {
    client: Client,
}

impl NamingProxy {
    /// The naming service `client` was made for.
    pub(super) fn new(client: Client) -> NamingProxy {
        NamingProxy { client }
    }

    fn call(&self, call: NamingCall) -> Result<Reply, RpcError> {
        self.client
            .call_at(self.client.naming_address(), Call::Naming(call))
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
