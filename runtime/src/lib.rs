//! Penelope's node runtime: what a node is made of below its server. The creator makes objects by
//! kind and name, wires them by configuration, and runs the real-time loops of the active
//! controllers; the data plane carries a teleoperation channel's samples between nodes on a
//! common clock; recordings keep every tick. The node above (`penelope-supervisor`, not a
//! dependency) serves the creator over the protocol and hosts the naming service and the
//! bridges; nothing here knows about either.
//!
//! # A tour, in data-path order
//!
//! - [`objects::kinds`]: every kind (robot, board, sensor, controller, trajectory) and its
//!   typed configuration.
//! - [`objects`]: the [`Creator`](objects::Creator) and its registry: objects by name, their
//!   relations and lifecycles; activating a controller builds its loop.
//! - [`objects::runtime`]: what runs while a controller is active: the control thread
//!   (SCHED_FIFO), the communication thread (trajectory or teleoperation link to the reference
//!   cell), the sensor feed, the telemetry pump; ticks leave the loop through bounded streams.
//! - [`objects::teleop`] and its siblings: a teleoperation channel's ends and the halves of the
//!   bilateral laws; [`objects::bridged`]: the channels a bridge feeds from outside the node.
//! - [`dataplane`]: authenticated UDP streams of samples between nodes, with fault injection
//!   and each link's clock estimate.
//! - [`common_clock`]: the system's one time line, which every node's recordings are on.
//! - [`objects::recording`]: every tick, event and link statistic of a node to an MCAP file
//!   (the creator's `record` call, `penelope node --record`), and read back.
#![warn(missing_docs)]

pub mod common_clock;
pub mod dataplane;
pub mod objects;
