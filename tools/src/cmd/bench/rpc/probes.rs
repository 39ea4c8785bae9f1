//! The three round trips: a remote call, a raw TCP echo and an ICMP echo, each timed in this
//! process with [`Instant`] around one request and its answer.

use std::io::{Read, Write};
use std::net::{Ipv4Addr, Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::mpsc::sync_channel;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use penelope_protocol::net::conn::{ClientConfig, Connection};
use penelope_protocol::net::server::{Server, ServerConfig};
use penelope_protocol::proto::{Call, CallError, Reply, WireError};
use penelope_protocol::service::{Service, Session};
use socket2::{Domain, Protocol, SockAddr, Socket, Type};

/// Which round trip.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProbeKind {
    /// `Call::Ping` through a node server and a client `Connection`.
    Rpc,
    /// The same with the shared secret: a Noise handshake first, every frame sealed
    /// (ChaCha20-Poly1305) both ways.
    SealedRpc,
    /// The payload echoed by a plain TCP server thread.
    Tcp,
    /// The payload echoed by a TCP server that hands it to a writer thread (the node server's
    /// reader/writer structure, without the protocol).
    TcpHandoff,
    /// ICMP echo request and reply.
    Icmp,
}

impl ProbeKind {
    /// The name in tables, JSON and plots.
    pub fn name(self) -> &'static str {
        match self {
            ProbeKind::Rpc => "rpc",
            ProbeKind::SealedRpc => "sealed rpc",
            ProbeKind::Tcp => "tcp echo",
            ProbeKind::TcpHandoff => "tcp echo+handoff",
            ProbeKind::Icmp => "icmp echo",
        }
    }
}

/// One way of making a round trip, ready to be timed.
pub enum Probe {
    /// The remote call.
    Rpc(Box<RpcProbe>),
    /// A TCP echo (plain or with a writer-thread handoff).
    Tcp(TcpProbe),
    /// The ICMP echo.
    Icmp(IcmpProbe),
}

impl Probe {
    /// Which probe this is.
    pub fn kind(&self) -> ProbeKind {
        match self {
            Probe::Rpc(r) if r.sealed => ProbeKind::SealedRpc,
            Probe::Rpc(_) => ProbeKind::Rpc,
            Probe::Tcp(t) if t.handoff => ProbeKind::TcpHandoff,
            Probe::Tcp(_) => ProbeKind::Tcp,
            Probe::Icmp(_) => ProbeKind::Icmp,
        }
    }

    /// One timed round trip, ns.
    ///
    /// # Errors
    /// The transport's failure or a wrong echo.
    pub fn round_trip(&mut self) -> anyhow::Result<u64> {
        match self {
            Probe::Rpc(p) => p.round_trip(),
            Probe::Tcp(p) => p.round_trip(),
            Probe::Icmp(p) => p.round_trip(),
        }
    }
}

/// The node side of the remote-call probe: serves `Call::Ping` and nothing else.
struct PingService;

impl Service for PingService {
    fn call(&self, _session: &Session, call: Call) -> Result<Reply, WireError> {
        match call {
            Call::Ping { payload } => Ok(Reply::Pong(payload)),
            other => Err(WireError::Call(CallError::Unsupported {
                kind: "bench/ping".into(),
                method: format!("{other:?}").chars().take(40).collect(),
            })),
        }
    }
}

/// A node server on loopback and one client connection to it.
pub struct RpcProbe {
    server: Option<Server>,
    conn: Connection,
    payload: Vec<u8>,
    sealed: bool,
}

/// The shared secret of the sealed probe (32 random-looking bytes, as a deployment's).
const BENCH_SECRET: &[u8] = b"penelope-bench-rpc-sealed-secret";

impl RpcProbe {
    /// Starts the server (its rate limit raised out of the way) and connects; `sealed`: both
    /// with a shared secret, so the connection handshakes and seals every frame.
    ///
    /// # Errors
    /// When the server does not start or the connection fails.
    pub fn start(payload: &[u8], sealed: bool) -> anyhow::Result<Self> {
        let mut config = ServerConfig::new("bench");
        config.max_requests_per_s = 100_000_000;
        let mut client = ClientConfig::new("bench-rpc");
        if sealed {
            config.secret = Some(BENCH_SECRET.to_vec().into());
            client.secret = Some(BENCH_SECRET.to_vec().into());
        }
        let server = Server::bind(
            SocketAddr::from((Ipv4Addr::LOCALHOST, 0)),
            config,
            Arc::new(PingService),
        )
        .context("starting the node server")?;
        let conn = Connection::connect(server.local_addr(), &client)
            .context("connecting to the node server")?;
        let mut probe = RpcProbe {
            server: Some(server),
            conn,
            payload: payload.to_vec(),
            sealed,
        };
        probe.round_trip().context("first remote call")?;
        Ok(probe)
    }

    fn round_trip(&mut self) -> anyhow::Result<u64> {
        let t0 = Instant::now();
        let reply = self.conn.call(Call::Ping {
            payload: self.payload.clone(),
        });
        let dt = t0.elapsed();
        match reply.context("remote call")? {
            Reply::Pong(p) if p == self.payload => Ok(dt.as_nanos() as u64),
            other => bail!("the node answered Ping with {other:?}"),
        }
    }

    /// Calls made during about `length` (and the exact time taken): one call at a time, or
    /// `batch` calls pipelined with `call_many` (`batch` > 1).
    ///
    /// # Errors
    /// A failed call.
    pub fn throughput(
        &mut self,
        length: Duration,
        batch: usize,
    ) -> anyhow::Result<(u64, Duration)> {
        let t0 = Instant::now();
        let mut calls = 0u64;
        while t0.elapsed() < length {
            if batch <= 1 {
                self.round_trip()?;
                calls += 1;
            } else {
                let many = (0..batch)
                    .map(|_| Call::Ping {
                        payload: self.payload.clone(),
                    })
                    .collect();
                let replies = self.conn.call_many(many).context("pipelined calls")?;
                if replies.len() != batch {
                    bail!("{} answers to {batch} pipelined calls", replies.len());
                }
                for r in replies {
                    match r {
                        Ok(Reply::Pong(p)) if p == self.payload => {}
                        other => bail!("a pipelined Ping was answered with {other:?}"),
                    }
                }
                calls += batch as u64;
            }
        }
        Ok((calls, t0.elapsed()))
    }
}

impl Drop for RpcProbe {
    fn drop(&mut self) {
        if let Some(server) = self.server.take() {
            server.shutdown();
        }
    }
}

/// A TCP echo server thread on loopback and one client stream to it.
pub struct TcpProbe {
    stream: TcpStream,
    payload: Vec<u8>,
    buf: Vec<u8>,
    handoff: bool,
    server: Option<JoinHandle<()>>,
}

impl TcpProbe {
    /// Starts the echo server and connects (TCP_NODELAY on both ends, blocking sockets). With
    /// `handoff`, the server's reading thread passes each chunk to a second thread that writes
    /// it, as the node server's reader and writer threads do.
    ///
    /// # Errors
    /// Socket failures.
    pub fn start(payload: &[u8], handoff: bool) -> anyhow::Result<Self> {
        let listener = TcpListener::bind((Ipv4Addr::LOCALHOST, 0)).context("echo server bind")?;
        let addr = listener.local_addr()?;
        let server = std::thread::Builder::new()
            .name("bench-echo".into())
            .spawn(move || {
                if let Ok((s, _)) = listener.accept() {
                    let _ = s.set_nodelay(true);
                    if handoff {
                        echo_handoff(s);
                    } else {
                        echo(s);
                    }
                }
            })?;
        let stream = TcpStream::connect(addr).context("echo client connect")?;
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(Duration::from_secs(5)))?;
        let mut probe = TcpProbe {
            stream,
            payload: payload.to_vec(),
            buf: vec![0; payload.len()],
            handoff,
            server: Some(server),
        };
        probe.round_trip().context("first echo")?;
        Ok(probe)
    }

    fn round_trip(&mut self) -> anyhow::Result<u64> {
        let t0 = Instant::now();
        self.stream.write_all(&self.payload)?;
        self.stream.read_exact(&mut self.buf)?;
        let dt = t0.elapsed();
        if self.buf != self.payload {
            bail!("the TCP echo came back changed");
        }
        Ok(dt.as_nanos() as u64)
    }

    /// Echoes made during about `length` (and the exact time taken): one at a time, or `batch`
    /// payloads written at once and then read back.
    ///
    /// # Errors
    /// Socket failures.
    pub fn throughput(
        &mut self,
        length: Duration,
        batch: usize,
    ) -> anyhow::Result<(u64, Duration)> {
        let many = self.payload.repeat(batch.max(1));
        let mut back = vec![0; many.len()];
        let t0 = Instant::now();
        let mut echoes = 0u64;
        while t0.elapsed() < length {
            self.stream.write_all(&many)?;
            self.stream.read_exact(&mut back)?;
            echoes += batch.max(1) as u64;
        }
        if back != many {
            bail!("the TCP echo came back changed");
        }
        Ok((echoes, t0.elapsed()))
    }
}

impl Drop for TcpProbe {
    fn drop(&mut self) {
        let _ = self.stream.shutdown(Shutdown::Both);
        if let Some(t) = self.server.take() {
            let _ = t.join();
        }
    }
}

/// Echoes everything read, in the reading thread.
fn echo(mut s: TcpStream) {
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        match s.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => {
                if s.write_all(&buf[..n]).is_err() {
                    return;
                }
            }
        }
    }
}

/// Echoes everything read through a bounded channel to a writer thread.
fn echo_handoff(mut s: TcpStream) {
    let Ok(mut w) = s.try_clone() else { return };
    let (tx, rx) = sync_channel::<Vec<u8>>(256);
    let writer = std::thread::spawn(move || {
        while let Ok(chunk) = rx.recv() {
            if w.write_all(&chunk).is_err() {
                return;
            }
        }
    });
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        match s.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => {
                if tx.send(buf[..n].to_vec()).is_err() {
                    break;
                }
            }
        }
    }
    drop(tx);
    let _ = writer.join();
}

/// ICMP echo to 127.0.0.1 from this process: a datagram ICMP socket where
/// `net.ipv4.ping_group_range` allows it, else a raw socket (root or `CAP_NET_RAW`).
pub struct IcmpProbe {
    socket: Socket,
    raw: bool,
    id: u16,
    seq: u16,
    payload: Vec<u8>,
    packet: Vec<u8>,
    buf: Vec<u8>,
    /// Echo requests that got no reply within the timeout.
    pub lost: u64,
}

impl IcmpProbe {
    /// Opens the socket.
    ///
    /// # Errors
    /// When neither kind of ICMP socket may be opened, saying how to allow it.
    pub fn start(payload: &[u8]) -> anyhow::Result<Self> {
        let (socket, raw) = match Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::ICMPV4)) {
            Ok(s) => (s, false),
            Err(dgram) => match Socket::new(Domain::IPV4, Type::RAW, Some(Protocol::ICMPV4)) {
                Ok(s) => (s, true),
                Err(raw) => bail!(
                    "cannot open an ICMP socket (datagram: {dgram}; raw: {raw}). Run as root, \
                     give the binary CAP_NET_RAW (`sudo setcap cap_net_raw+ep $(which penelope)`), \
                     or allow your group in net.ipv4.ping_group_range; or pass --no-ping"
                ),
            },
        };
        let target = SockAddr::from(SocketAddr::from((Ipv4Addr::LOCALHOST, 0)));
        socket.connect(&target).context("ICMP socket connect")?;
        socket.set_read_timeout(Some(Duration::from_secs(1)))?;
        let mut probe = IcmpProbe {
            socket,
            raw,
            id: (std::process::id() & 0xffff) as u16,
            seq: 0,
            payload: payload.to_vec(),
            packet: Vec::with_capacity(8 + payload.len()),
            buf: vec![0; 65_536],
            lost: 0,
        };
        if let Err(e) = probe.round_trip() {
            bail!(
                "no ICMP echo reply from 127.0.0.1 ({e:#}); is net.ipv4.icmp_echo_ignore_all set?"
            );
        }
        Ok(probe)
    }

    /// Whether this is a raw socket (else a datagram ICMP socket).
    pub fn is_raw(&self) -> bool {
        self.raw
    }

    fn round_trip(&mut self) -> anyhow::Result<u64> {
        // Lost echoes (never seen on loopback unless the kernel drops them) are retried a few
        // times and counted; persistent loss is an error.
        for _ in 0..5 {
            self.seq = self.seq.wrapping_add(1);
            echo_request(&mut self.packet, self.id, self.seq, &self.payload);
            let t0 = Instant::now();
            self.socket.send(&self.packet).context("ICMP send")?;
            loop {
                let n = match (&self.socket).read(&mut self.buf) {
                    Ok(n) => n,
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                        ) =>
                    {
                        self.lost += 1;
                        break;
                    }
                    Err(e) => return Err(e).context("ICMP receive"),
                };
                if let Some(reply) = parse_echo_reply(&self.buf[..n], self.raw) {
                    // A datagram socket's id is the kernel's, not ours: match the sequence only.
                    if reply.seq == self.seq && (!self.raw || reply.id == self.id) {
                        let dt = t0.elapsed();
                        if reply.data != self.payload.as_slice() {
                            bail!("the ICMP echo came back changed");
                        }
                        return Ok(dt.as_nanos() as u64);
                    }
                }
            }
        }
        bail!("five ICMP echo requests in a row got no reply")
    }
}

/// An ICMP echo reply as parsed.
#[derive(Debug, PartialEq, Eq)]
pub struct EchoReply<'a> {
    /// Identifier.
    pub id: u16,
    /// Sequence number.
    pub seq: u16,
    /// Data after the 8-byte ICMP header.
    pub data: &'a [u8],
}

/// Writes an ICMP echo request (type 8) with its checksum into `packet`.
pub fn echo_request(packet: &mut Vec<u8>, id: u16, seq: u16, data: &[u8]) {
    packet.clear();
    packet.extend_from_slice(&[8, 0, 0, 0]);
    packet.extend_from_slice(&id.to_be_bytes());
    packet.extend_from_slice(&seq.to_be_bytes());
    packet.extend_from_slice(data);
    let sum = checksum(packet);
    packet[2..4].copy_from_slice(&sum.to_be_bytes());
}

/// The Internet checksum (RFC 1071) of `bytes`.
pub fn checksum(bytes: &[u8]) -> u16 {
    let mut sum: u32 = bytes
        .chunks(2)
        .map(|c| u32::from(u16::from_be_bytes([c[0], *c.get(1).unwrap_or(&0)])))
        .sum();
    while sum > 0xffff {
        sum = (sum & 0xffff) + (sum >> 16);
    }
    !(sum as u16)
}

/// An echo reply (type 0) in `bytes` (starting with the IPv4 header when `with_ip_header`), or
/// `None` for anything else.
pub fn parse_echo_reply(bytes: &[u8], with_ip_header: bool) -> Option<EchoReply<'_>> {
    let icmp = if with_ip_header {
        let first = *bytes.first()?;
        if first >> 4 != 4 {
            return None;
        }
        bytes.get(usize::from(first & 0x0f) * 4..)?
    } else {
        bytes
    };
    if icmp.len() < 8 || icmp[0] != 0 || icmp[1] != 0 {
        return None;
    }
    Some(EchoReply {
        id: u16::from_be_bytes([icmp[4], icmp[5]]),
        seq: u16::from_be_bytes([icmp[6], icmp[7]]),
        data: &icmp[8..],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn echo_requests_carry_a_valid_checksum_and_replies_parse() {
        let mut p = Vec::new();
        echo_request(&mut p, 0x1234, 7, b"abc");
        assert_eq!(&p[..2], &[8, 0]);
        assert_eq!(&p[4..8], &[0x12, 0x34, 0, 7]);
        // A packet including its own checksum sums to zero.
        assert_eq!(checksum(&p), 0);
        // RFC 1071's example words 0001 f203 f4f5 f6f7 sum to ddf2, checksum 220d.
        assert_eq!(
            checksum(&[0x00, 0x01, 0xf2, 0x03, 0xf4, 0xf5, 0xf6, 0xf7]),
            0x220d
        );

        let mut reply = p.clone();
        reply[0] = 0;
        let parsed = parse_echo_reply(&reply, false).unwrap();
        assert_eq!(
            (parsed.id, parsed.seq, parsed.data),
            (0x1234, 7, &b"abc"[..])
        );
        let mut with_ip = vec![0x45u8; 1];
        with_ip.extend_from_slice(&[0; 19]);
        with_ip.extend_from_slice(&reply);
        assert_eq!(parse_echo_reply(&with_ip, true), Some(parsed));
        // Our own request (type 8), a short packet and a non-IPv4 header are not replies.
        assert_eq!(parse_echo_reply(&p, false), None);
        assert_eq!(parse_echo_reply(&reply[..5], false), None);
        assert_eq!(parse_echo_reply(&reply, true), None);
        assert_eq!(parse_echo_reply(&[], true), None);
    }
}
