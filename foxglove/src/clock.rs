//! Message times on the system's common clock: the monotonic clock of the naming service's
//! host, which a node's recordings stamp with too (so a recording and the live stream share
//! one time line).
//!
//! A tick's `time_ns` is on its node's clock. The gateway estimates, with [`Call::Time`] (the
//! four-timestamp exchange the nodes themselves use; the exchange with the least round trip of
//! [`EXCHANGES`] wins), its own clock's offset to the node's and to the naming host's; their
//! difference is the node's offset to the common clock. A node that hosts the naming service is
//! the common clock (offset zero, exactly), and so is a node on a simulated clock: its ticks
//! carry the simulated time, which nothing else agrees with, so it stays as it is. A node is
//! taken for simulated when its ticks' times are not its monotonic clock's (more than
//! [`SIMULATED_IF_APART`] apart), which a real-time tick always is to within its push latency.

use std::net::SocketAddr;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use penelope_protocol::client::Client;
use penelope_protocol::net::conn::RpcError;
use penelope_protocol::proto::{Call, Reply};

/// Exchanges per estimate.
pub const EXCHANGES: usize = 8;
/// A node whose ticks are this far from its own monotonic clock runs on a simulated clock.
pub const SIMULATED_IF_APART: Duration = Duration::from_secs(10);

/// This process's clock, ns from an arbitrary start (only differences and offsets against it
/// are used).
pub fn local_ns() -> i64 {
    static START: OnceLock<Instant> = OnceLock::new();
    let start = *START.get_or_init(Instant::now);
    i64::try_from(start.elapsed().as_nanos()).unwrap_or(i64::MAX)
}

/// The offset (their clock less ours, ns) and round trip of the exchange with the least round
/// trip among `exchanges` (`t1` sent and `t4` answered on our clock, `t2` taken and `t3` answered
/// on theirs); `None` when no exchange is plausible (an answer before its question).
pub fn best_offset(exchanges: &[(i64, i64, i64, i64)]) -> Option<(i64, i64)> {
    exchanges
        .iter()
        .filter(|(t1, t2, t3, t4)| t4 >= t1 && t3 >= t2)
        .map(|(t1, t2, t3, t4)| {
            let round_trip = (t4 - t1) - (t3 - t2);
            let offset = ((t2 - t1) + (t3 - t4)) / 2;
            (offset, round_trip.max(0))
        })
        .min_by_key(|(_, round_trip)| *round_trip)
}

/// The clock at `address` less this process's, ns, and the round trip it was measured over.
///
/// # Errors
/// The transport's, or [`RpcError::Protocol`] when no answer was a time.
pub fn offset_of(client: &Client, address: SocketAddr) -> Result<(i64, i64), RpcError> {
    let mut exchanges = Vec::with_capacity(EXCHANGES);
    for _ in 0..EXCHANGES {
        let t1 = local_ns();
        let reply = client.call_at(address, Call::Time)?;
        let t4 = local_ns();
        if let Reply::Time {
            received_ns,
            sent_ns,
        } = reply
        {
            exchanges.push((t1, received_ns, sent_ns, t4));
        }
    }
    best_offset(&exchanges).ok_or_else(|| RpcError::Protocol("no plausible time answer".into()))
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
    /// As [`offset_of`].
    pub fn estimate(
        client: &Client,
        node: SocketAddr,
        hosts_naming: bool,
    ) -> Result<Self, RpcError> {
        if hosts_naming {
            return Ok(NodeClock::Common);
        }
        let (node_less_local_ns, _) = offset_of(client, node)?;
        let (naming_less_local_ns, _) = offset_of(client, client.naming_address())?;
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
    fn the_exchange_with_the_least_round_trip_gives_the_offset_to_half_its_asymmetry() {
        // Theirs reads 5 s ahead; 30 µs each way, but the first exchange queued 2 ms going out.
        let ahead = 5_000_000_000i64;
        let mut ex = Vec::new();
        for k in 0..4i64 {
            let t1 = k * 1_000_000;
            let out = if k == 0 { 2_030_000 } else { 30_000 };
            let t2 = t1 + out + ahead;
            let t3 = t2 + 5_000;
            let t4 = t3 - ahead + 30_000;
            ex.push((t1, t2, t3, t4));
        }
        let (offset, rtt) = best_offset(&ex).unwrap();
        assert_eq!(offset, ahead);
        assert_eq!(rtt, 60_000);
        // An answer before its question is not an exchange.
        assert_eq!(best_offset(&[(10, 0, 0, 5)]), None);
    }

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
