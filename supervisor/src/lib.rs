#![doc = include_str!("../README.md")]
//!
//! # A tour
//!
//! Two crates lie below: the protocol it speaks ([`penelope_protocol`]: the IDL, frames, Noise
//! sessions, the server a node runs its [`Service`](penelope_protocol::service::Service)
//! behind, the client), and the runtime it serves ([`penelope_runtime`]: the creator, the
//! objects and their real-time loops, the data plane, the common clock, recordings).
//!
//! - [`system`]: the system file: every object, its configuration, relations and node.
//! - [`node`]: a node: the runtime's creator and optionally the naming service behind one
//!   server, and its link to the naming service of the system.
//! - [`naming`]: the naming service (a tree of contexts with leases per node).
//! - [`zenoh_bridge`]: a node's telemetry, events and links on Zenoh, its object tree as a
//!   queryable, and operator poses from Zenoh into a teleoperation channel (feature `zenoh`);
//!   it uses the creator's public API and is never stored in it.
//! - [`runs`]: a system file's teleoperation task run for a duration through a node, on either
//!   clock, recorded tick by tick, and its report (the demo).
#![warn(missing_docs)]

pub mod naming;
pub mod node;
pub mod ros2;
pub mod runs;
pub mod system;
pub mod zenoh_bridge;
