#![doc = include_str!("../README.md")]
//!
//! # A tour
//!
//! The protocol it speaks (the IDL, frames, Noise sessions, the server a node runs its
//! [`Service`](penelope_protocol::service::Service) behind, the client) is the crate below,
//! [`penelope_protocol`].
//!
//! - [`runs`]: a system file's teleoperation task run for a duration through the node runtime,
//!   on either clock, recorded tick by tick, and its report (the demo).
//! - [`objects`]: the creator and the objects it makes (robots, boards, sensors, controllers,
//!   trajectories), their lifecycle and their real-time loops.
//! - [`naming`]: the naming service (a tree of contexts with leases per node).
//! - [`node`]: a node: creator, objects and optionally the naming service behind one server.
//! - [`system`]: the system file: every object, its configuration, relations and node.
//! - [`dataplane`]: the data plane between nodes: authenticated UDP streams of samples, and
//!   each link's clock estimate.
//! - [`zenoh_bridge`]: a node's telemetry, events and links on Zenoh, its object tree as a
//!   queryable, and operator poses from Zenoh into a teleoperation channel (feature `zenoh`).
#![warn(missing_docs)]

pub mod common_clock;
pub mod dataplane;
pub mod naming;
pub mod node;
pub mod objects;
pub mod runs;
pub mod system;
pub mod zenoh_bridge;
