//! Free loopback ports.
//!
//! A port is free when asked; the server a test starts binds it a moment later, so the port
//! must not be taken in between. A port the kernel picks for `bind(port 0)` is the wrong kind:
//! it comes from the ephemeral range, where every other socket on the machine that binds port 0
//! or connects out draws its own port, and on a busy machine one of them took a data plane's port
//! in that window ("Address already in use"). So the ports handed out here lie *below* the
//! ephemeral range, which the kernel never hands out by itself; within a process a counter never
//! hands out the same port twice, and processes start at different places (by process id). Each
//! port is checked bindable before it is handed out.

use std::net::{Ipv4Addr, SocketAddr, TcpListener, UdpSocket};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicU32, Ordering};

/// The kernel's ephemeral range when it cannot be read (Linux's default).
const DEFAULT_EPHEMERAL_LOW: u16 = 32768;
/// The lowest port handed out: above the well-known and most registered services' ports.
const LOWEST: u16 = 10_000;
/// Candidates tried before giving up (a machine whose whole range is bound is broken).
const TRIES: u32 = 1000;

/// The ports handed out: `[LOWEST, start of the ephemeral range)`.
fn range() -> (u16, u16) {
    static RANGE: OnceLock<(u16, u16)> = OnceLock::new();
    *RANGE.get_or_init(|| {
        let low = std::fs::read_to_string("/proc/sys/net/ipv4/ip_local_port_range")
            .ok()
            .and_then(|s| s.split_whitespace().next()?.parse::<u16>().ok())
            .unwrap_or(DEFAULT_EPHEMERAL_LOW);
        (LOWEST, low.max(LOWEST + 1024))
    })
}

/// The next candidate port of this process.
fn next_candidate() -> u16 {
    static NEXT: OnceLock<AtomicU32> = OnceLock::new();
    let (low, high) = range();
    let span = u32::from(high - low);
    // Spread processes over the range so two test processes rarely walk the same ports.
    let next = NEXT.get_or_init(|| AtomicU32::new(std::process::id().wrapping_mul(7919) % span));
    let offset = next.fetch_add(1, Ordering::Relaxed) % span;
    low + u16::try_from(offset).expect("the offset is below the span")
}

/// A free port below the ephemeral range, checked with `bindable`.
fn free_port(bindable: impl Fn(SocketAddr) -> bool) -> u16 {
    (0..TRIES)
        .map(|_| next_candidate())
        .find(|&port| bindable(SocketAddr::from((Ipv4Addr::LOCALHOST, port))))
        .unwrap_or_else(|| panic!("no free loopback port in {TRIES} tries"))
}

/// A loopback TCP address nobody listens on (now), below the ephemeral range.
pub fn free_tcp_addr() -> SocketAddr {
    SocketAddr::from((Ipv4Addr::LOCALHOST, free_tcp_port()))
}

/// A loopback TCP port nobody listens on (now), below the ephemeral range.
pub fn free_tcp_port() -> u16 {
    free_port(|a| TcpListener::bind(a).is_ok())
}

/// A loopback UDP port nobody has bound (now), below the ephemeral range: for data-plane
/// endpoints and emulated sensors.
pub fn free_udp_port() -> u16 {
    free_port(|a| UdpSocket::bind(a).is_ok())
}

/// A loopback UDP address nobody has bound (now), below the ephemeral range.
pub fn free_udp_addr() -> SocketAddr {
    SocketAddr::from((Ipv4Addr::LOCALHOST, free_udp_port()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_ports_are_on_loopback_bindable_and_outside_the_ephemeral_range() {
        let (_, ephemeral_low) = range();
        let a = free_tcp_addr();
        assert!(a.ip().is_loopback());
        assert!(a.port() >= LOWEST && a.port() < ephemeral_low, "{a}");
        let _listener = TcpListener::bind(a).expect("the TCP port is free");
        let u = free_udp_port();
        assert!(u >= LOWEST && u < ephemeral_low, "{u}");
        let _socket = UdpSocket::bind(("127.0.0.1", u)).expect("the UDP port is free");
    }

    #[test]
    fn a_process_never_hands_out_the_same_port_twice_in_a_row() {
        let ports: Vec<u16> = (0..100).map(|_| free_udp_port()).collect();
        let mut distinct = ports.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), ports.len(), "{ports:?}");
    }

    #[test]
    fn a_bound_port_is_never_handed_out() {
        let held = UdpSocket::bind(free_udp_addr()).unwrap();
        let held_port = held.local_addr().unwrap().port();
        let (low, high) = range();
        // A whole walk of the range: the held port is skipped when it comes round.
        for _ in 0..=u32::from(high - low) {
            assert_ne!(free_udp_port(), held_port);
        }
    }
}
