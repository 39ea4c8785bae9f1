//! Free loopback ports.
//!
//! The port is free when asked; a server the test starts binds it a moment later. Tests bind
//! only loopback, so the window is a race with other tests on this machine alone.

use std::net::{SocketAddr, TcpListener, UdpSocket};

/// A loopback TCP address nobody listens on (now).
pub fn free_tcp_addr() -> SocketAddr {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("bind a loopback TCP port")
}

/// A loopback TCP port nobody listens on (now).
pub fn free_tcp_port() -> u16 {
    free_tcp_addr().port()
}

/// A loopback UDP port nobody has bound (now): for data-plane endpoints and emulated sensors.
pub fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .expect("bind a loopback UDP port")
        .port()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_ports_are_on_loopback_and_bindable() {
        // A port found free may be taken by another test's socket before it is bound here (the
        // helpers cannot hold it for the caller): one of a few tries must bind.
        let tcp = (0..10).find_map(|_| {
            let a = free_tcp_addr();
            assert!(a.ip().is_loopback());
            TcpListener::bind(a).ok()
        });
        assert!(tcp.is_some(), "no free TCP port bound in 10 tries");
        let udp = (0..10).find_map(|_| UdpSocket::bind(("127.0.0.1", free_udp_port())).ok());
        assert!(udp.is_some(), "no free UDP port bound in 10 tries");
        assert_ne!(free_tcp_port(), 0);
    }
}
