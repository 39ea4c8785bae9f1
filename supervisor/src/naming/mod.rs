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
//!   [`CallError::NameTaken`] unless `rebind`; a context is never replaced by an object.
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
//! Refusals are [`CallError::Forbidden`]. A node's own calls to the naming service it hosts do
//! not cross a connection and are not checked (it is the node).

#[cfg(doc)]
use penelope_protocol::proto::CallError;
#[cfg(doc)]
use std::time::Duration;

#[cfg(doc)]
use penelope_protocol::proto::{Call, NamingCall, Role, WireError, check_name};
#[cfg(doc)]
use penelope_protocol::service::{Identity, Service};

mod authorize;
mod service;
#[cfg(test)]
mod tests;
mod tree;

pub use authorize::authorize;
pub use service::{NamingService, Reaper, STALE_PROBE_TIMEOUT};
pub use tree::{MAX_ADDRESS_LEN, MAX_KIND_LEN, NamingLimits, NamingTree, NodeLease};
