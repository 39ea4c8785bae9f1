//! Message times on the system's common clock: the monotonic clock of the naming service's
//! host, which a node's recordings stamp with too (so a recording and the live stream share
//! one time line).
//!
//! A tick's `time_ns` is on its node's clock. The gateway estimates, with [`Call::Time`] (the
//! four-timestamp exchange the nodes themselves use, through the same filter:
//! [`offset_to`]), its own clock's offset to the node's and to the naming host's; their
//! difference is the node's offset to the common clock. A node that hosts the naming service is
//! the common clock (offset zero, exactly), and so is a node on a simulated clock: its ticks
//! carry the simulated time, which nothing else agrees with, so it stays as it is. A node is
//! taken for simulated when its ticks' times are not its monotonic clock's (more than
//! [`SIMULATED_IF_APART`] apart), which a real-time tick always is to within its push latency.

use std::net::SocketAddr;
use std::time::Duration;

use penelope_protocol::client::Client;
use penelope_protocol::client::clock::{monotonic_now_ns, offset_to};
use penelope_protocol::net::conn::RpcError;

#[cfg(doc)]
use penelope_protocol::proto::Call;

/// A node whose ticks are this far from its own monotonic clock runs on a simulated clock.
pub const SIMULATED_IF_APART: Duration = Duration::from_secs(10);

/// This host's monotonic clock, ns (what the offsets are measured against).
pub fn local_ns() -> i64 {
    i64::try_from(monotonic_now_ns()).unwrap_or(i64::MAX)
}

/// How a node's tick times become common times.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeClock {
    /// The node is the common clock (it hosts the naming service): times as they are.
    Common,
    /// A real-time node elsewhere: add `offset_ns` (the common clock less the node's).
    Offset {
        /// The common clock less the node's, ns.
        offset_ns: i64,
        /// The node's clock less this process's, ns (to tell simulated ticks apart).
        node_less_local_ns: i64,
    },
    /// The node runs on a simulated clock: its simulated times as they are.
    Simulated,
}

impl NodeClock {
    /// Estimates the clock of the node at `node` (`hosts_naming`: it serves the naming service).
    ///
    /// # Errors
    /// As [`offset_to`].
    pub fn estimate(
        client: &Client,
        node: SocketAddr,
        hosts_naming: bool,
    ) -> Result<Self, RpcError> {
        if hosts_naming {
            return Ok(NodeClock::Common);
        }
        let (node_less_local_ns, _) = offset_to(client, node)?;
        let (naming_less_local_ns, _) = offset_to(client, client.naming_address())?;
        Ok(NodeClock::Offset {
            offset_ns: naming_less_local_ns - node_less_local_ns,
            node_less_local_ns,
        })
    }

    /// What this clock becomes once a tick of the node, stamped `tick_ns` and received at
    /// `local_now_ns` on this process's clock, shows which clock the node runs on.
    pub fn seen_tick(self, tick_ns: u64, local_now_ns: i64) -> Self {
        match self {
            NodeClock::Offset {
                node_less_local_ns, ..
            } => {
                let node_now = local_now_ns.saturating_add(node_less_local_ns);
                let apart = (i64::try_from(tick_ns).unwrap_or(i64::MAX) - node_now).unsigned_abs();
                if apart > SIMULATED_IF_APART.as_nanos() as u64 {
                    NodeClock::Simulated
                } else {
                    self
                }
            }
            other => other,
        }
    }

    /// A node time on the common clock.
    pub fn to_common(self, node_ns: u64) -> u64 {
        match self {
            NodeClock::Offset { offset_ns, .. } => node_ns.saturating_add_signed(offset_ns),
            NodeClock::Common | NodeClock::Simulated => node_ns,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_far_from_the_nodes_monotonic_clock_are_simulated_times_kept_as_they_are() {
        let clock = NodeClock::Offset {
            offset_ns: 1_000,
            node_less_local_ns: 50_000_000_000,
        };
        // A real-time tick: the node's clock now, give or take push latency.
        let real = clock.seen_tick(50_100_000_000, 100_000_000);
        assert_eq!(real, clock);
        assert_eq!(real.to_common(7), 1_007);
        // A simulated clock 2 s into its run.
        let sim = clock.seen_tick(2_000_000_000, 100_000_000);
        assert_eq!(sim, NodeClock::Simulated);
        assert_eq!(sim.to_common(2_000_000_000), 2_000_000_000);
        assert_eq!(NodeClock::Common.to_common(9), 9);
    }
}
