//! The data plane between nodes: UDP streams of stamped samples (teleoperation references
//! forward, wrenches back, sensor readings), beside the TCP request plane of `net`.
//!
//! - [`frame`]: the datagram (header, payload, optional authentication tag);
//! - [`stream`]: numbering on the sending side, newest-wins on the receiving side;
//! - [`endpoint`]: a non-blocking UDP socket that sends and receives frames and counts what it
//!   refused;
//! - [`sensor_stream`]: a force sensor published by its node to any number of readers;
//! - the common clock of a link, estimated from four-timestamp heartbeats, is
//!   [`penelope_protocol::link_clock`] (clients estimate theirs with it too);
//! - [`end_clock`]: the times an end stamps (the tick's on a simulated clock, the real clock's
//!   and the kernel's receive stamps on real time), with an injectable offset;
//! - [`histogram`]: fixed-size latency histograms (the samples' one-way trips);
//! - [`faults`]: seeded link faults (delay, jitter, loss, duplication, reordering, outages),
//!   because these machines have no netem.

pub mod end_clock;
pub mod endpoint;
pub mod faults;
pub mod frame;
pub mod histogram;
pub mod sensor_stream;
pub mod stream;
