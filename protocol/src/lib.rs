#![doc = include_str!("../README.md")]
//!
//! # A tour, in data-path order
//!
//! - [`proto`]: the IDL, the single definition of every message on the wire: the hellos, the
//!   calls and their replies, the telemetry and link records, and the wire error.
//! - [`net::frame`]: a message as a length-prefixed postcard frame on a byte stream, and the
//!   incremental decoder that reads frames without trusting their lengths.
//! - [`net::auth`]: the shared secret, the Noise handshake that proves it both ways, and the
//!   sealed frames of an authenticated session.
//! - [`net::limits`]: the bounds a server keeps under attack (connections, rates, sizes).
//! - [`service`]: the seam between the transport and what a node serves: a [`service::Service`]
//!   answers a call of a [`service::Session`] and streams through its outbox.
//! - [`net::server`]: a node's TCP server: accepts, authenticates and serves connections.
//! - [`net::conn`]: the client side of one connection: requests, pipelining, subscriptions.
//! - [`client`]: the naming-aware client and the typed proxies of remote objects (robots,
//!   boards, sensors, controllers, trajectories), and their telemetry and link streams.
//! - [`link_clock`]: another host's clock estimated from four-timestamp exchanges (the data
//!   plane's heartbeats, [`proto::Call::Time`]), as NTP's clock filter does it.
#![warn(missing_docs)]

pub mod client;
pub mod link_clock;
pub mod net;
pub mod proto;
pub mod service;
