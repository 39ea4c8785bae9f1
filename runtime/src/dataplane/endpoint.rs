//! A node's data-plane socket: UDP, non-blocking, sending and receiving whole frames and
//! counting every datagram it refused. Meant for communication threads: no call blocks, and a
//! receive call does a bounded amount of work.

use std::io;
use std::net::{SocketAddr, UdpSocket};

use serde::Serialize;
use serde::de::DeserializeOwned;

use super::frame::{
    DatagramError, DatagramKey, DirectedKeys, Header, MAX_DATAGRAM, decode, encode,
};

/// At most this many queued datagrams are read by one [`Endpoint::receive`] call.
pub const RECEIVE_BURST: usize = 64;

/// What an endpoint counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EndpointStats {
    /// Datagrams sent.
    pub sent: u64,
    /// Sends the operating system refused (buffer full, no route).
    pub send_errors: u64,
    /// Datagrams that opened and decoded.
    pub received: u64,
    /// Datagrams whose tag did not verify.
    pub bad_tag: u64,
    /// Datagrams tagged when this end has no key, or untagged when it has one.
    pub wrong_authentication: u64,
    /// Datagrams of another kind or shape, or too long.
    pub malformed: u64,
    /// Datagrams of another data-plane version: the other node runs another build, and the
    /// two will exchange nothing until both run the same one.
    pub wrong_version: u64,
    /// The version those datagrams carried (the last one heard).
    pub other_version: Option<u8>,
}

impl EndpointStats {
    fn refuse(&mut self, e: DatagramError) {
        match e {
            DatagramError::BadTag => self.bad_tag += 1,
            DatagramError::Authentication(..) => self.wrong_authentication += 1,
            DatagramError::Version(v) => {
                self.wrong_version += 1;
                self.other_version = Some(v);
            }
            _ => self.malformed += 1,
        }
    }
}

/// Why a frame was not sent.
#[derive(Debug, thiserror::Error)]
pub enum SendError {
    /// It does not fit a datagram.
    #[error(transparent)]
    Frame(#[from] DatagramError),
    /// The operating system refused it.
    #[error("send: {0}")]
    Io(#[from] io::Error),
}

/// A bound data-plane socket and the keys its datagrams carry (none without a secret): one
/// for what it sends, one for what it takes (the same for a system-wide stream).
pub struct Endpoint {
    socket: UdpSocket,
    keys: Option<DirectedKeys>,
    buf: Box<[u8; MAX_DATAGRAM]>,
    stats: EndpointStats,
    /// Room for a receive timestamp's control message, once
    /// [`enable_receive_timestamps`](Endpoint::enable_receive_timestamps) asked the kernel for
    /// them.
    control: Option<Box<ControlBuffer>>,
}

/// Room for the control messages of one `recvmsg` (a `SCM_TIMESTAMPNS` needs 32 bytes on
/// 64-bit Linux); aligned as a `cmsghdr` must be.
#[repr(C, align(8))]
pub struct ControlBuffer([u8; 64]);

impl Default for ControlBuffer {
    fn default() -> Self {
        ControlBuffer([0; 64])
    }
}

/// Asks the kernel to stamp every datagram `socket` receives with its arrival time
/// (`SO_TIMESTAMPNS`, read by [`receive_with_stamp`]).
///
/// # Errors
/// The operating system's, from `setsockopt`.
pub fn enable_kernel_stamps(socket: &UdpSocket) -> io::Result<()> {
    use nix::sys::socket::{setsockopt, sockopt::ReceiveTimestampns};
    setsockopt(socket, ReceiveTimestampns, &true).map_err(io::Error::from)
}

/// One datagram from `socket` into `buf`: its length, its sender, and when the kernel received
/// it (ns on `CLOCK_REALTIME`; `None` unless [`enable_kernel_stamps`] was called).
///
/// # Errors
/// The operating system's (`WouldBlock` on a non-blocking socket with nothing waiting).
///
/// # Real-time
/// One `recvmsg`; no allocation.
pub fn receive_with_stamp(
    socket: &UdpSocket,
    buf: &mut [u8],
    control: &mut ControlBuffer,
) -> io::Result<(usize, SocketAddr, Option<i64>)> {
    use nix::sys::socket::{ControlMessageOwned, MsgFlags, SockaddrStorage, recvmsg};
    use std::os::fd::AsRawFd;
    let mut iov = [io::IoSliceMut::new(buf)];
    let msg = recvmsg::<SockaddrStorage>(
        socket.as_raw_fd(),
        &mut iov,
        Some(&mut control.0[..]),
        MsgFlags::empty(),
    )
    .map_err(io::Error::from)?;
    let from = msg.address.and_then(|a| {
        if let Some(v4) = a.as_sockaddr_in() {
            Some(SocketAddr::V4((*v4).into()))
        } else {
            a.as_sockaddr_in6().map(|v6| SocketAddr::V6((*v6).into()))
        }
    });
    let Some(from) = from else {
        return Err(io::Error::other("a datagram without an IP sender"));
    };
    let stamp = msg.cmsgs().ok().and_then(|mut c| {
        c.find_map(|m| match m {
            ControlMessageOwned::ScmTimestampns(t) => t
                .tv_sec()
                .checked_mul(1_000_000_000)
                .and_then(|s| s.checked_add(t.tv_nsec())),
            _ => None,
        })
    });
    Ok((msg.bytes, from, stamp))
}

/// A datagram that opened and decoded, with its sender and, when the endpoint asked the kernel
/// for them, its receive time.
#[derive(Clone, Copy, Debug)]
pub struct Received<P> {
    /// Who sent it.
    pub from: SocketAddr,
    /// Its header.
    pub header: Header,
    /// Its payload.
    pub payload: P,
    /// When the kernel received it, ns on `CLOCK_REALTIME` (`SO_TIMESTAMPNS`); `None` without
    /// receive timestamps.
    pub kernel_realtime_ns: Option<i64>,
}

impl std::fmt::Debug for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Endpoint")
            .field("local", &self.socket.local_addr().ok())
            .field("authenticated", &self.keys.is_some())
            .field("stats", &self.stats)
            .finish()
    }
}

impl std::os::fd::AsFd for Endpoint {
    /// The socket's descriptor (a communication thread waits on it for an urgent sample).
    fn as_fd(&self) -> std::os::fd::BorrowedFd<'_> {
        self.socket.as_fd()
    }
}

impl Endpoint {
    /// Binds `addr` (port 0: any free port), non-blocking; datagrams are tagged and checked
    /// with `key` when given.
    ///
    /// # Errors
    /// The operating system's, from binding.
    pub fn bind(addr: SocketAddr, key: Option<DatagramKey>) -> io::Result<Self> {
        let keys = key.map(|k| DirectedKeys {
            send: k.clone(),
            receive: k,
        });
        Endpoint::bind_directed(addr, keys)
    }

    /// Binds `addr` as [`bind`](Self::bind) does, for one end of a channel: what it sends is
    /// tagged with `keys.send`, what it takes must verify under `keys.receive`
    /// ([`DatagramKey::directed`]).
    ///
    /// # Errors
    /// The operating system's, from binding.
    pub fn bind_directed(addr: SocketAddr, keys: Option<DirectedKeys>) -> io::Result<Self> {
        let socket = UdpSocket::bind(addr)?;
        socket.set_nonblocking(true)?;
        Ok(Endpoint {
            socket,
            keys,
            buf: Box::new([0; MAX_DATAGRAM]),
            stats: EndpointStats::default(),
            control: None,
        })
    }

    /// Asks the kernel to stamp every datagram with its receive time (`SO_TIMESTAMPNS`), which
    /// [`receive_stamped`](Self::receive_stamped) then returns: the arrival time without the
    /// delay between arrival and the communication thread's next tick.
    ///
    /// # Errors
    /// The operating system's, from `setsockopt`.
    pub fn enable_receive_timestamps(&mut self) -> io::Result<()> {
        enable_kernel_stamps(&self.socket)?;
        self.control = Some(Box::default());
        Ok(())
    }

    /// The address it is bound to.
    ///
    /// # Errors
    /// The operating system's.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Sends one frame to `to`.
    ///
    /// # Errors
    /// [`SendError`]; counted as a send error when the operating system refused it.
    ///
    /// # Real-time
    /// No allocation for fixed-size payloads; one non-blocking `sendto`.
    pub fn send<P: Serialize>(
        &mut self,
        header: &Header,
        payload: &P,
        to: SocketAddr,
    ) -> Result<(), SendError> {
        let key = self.keys.as_ref().map(|k| &k.send);
        let n = encode(header, payload, key, &mut self.buf[..])?;
        match self.socket.send_to(&self.buf[..n], to) {
            Ok(_) => {
                self.stats.sent += 1;
                Ok(())
            }
            Err(e) => {
                self.stats.send_errors += 1;
                Err(SendError::Io(e))
            }
        }
    }

    /// The next datagram waiting that opens and decodes as a `P`, with its sender; `None` when
    /// nothing valid is waiting. Refused datagrams are counted and skipped, at most
    /// [`RECEIVE_BURST`] per call.
    ///
    /// # Real-time
    /// Bounded: at most [`RECEIVE_BURST`] non-blocking `recvfrom` calls; no allocation for
    /// fixed-size payloads.
    pub fn receive<P: DeserializeOwned>(&mut self) -> Option<(SocketAddr, Header, P)> {
        self.receive_stamped()
            .map(|r: Received<P>| (r.from, r.header, r.payload))
    }

    /// As [`receive`](Self::receive), with the kernel's receive time of the datagram when
    /// [`enable_receive_timestamps`](Self::enable_receive_timestamps) asked for it.
    ///
    /// # Real-time
    /// Bounded: at most [`RECEIVE_BURST`] non-blocking `recvfrom` or `recvmsg` calls; no
    /// allocation for fixed-size payloads.
    pub fn receive_stamped<P: DeserializeOwned>(&mut self) -> Option<Received<P>> {
        for _ in 0..RECEIVE_BURST {
            // Would block: nothing waiting. Other errors (an ICMP refusal reported on this
            // socket) say nothing about the next datagram: stop for this call.
            let (n, from, kernel_realtime_ns) = self.receive_raw().ok()?;
            let key = self.keys.as_ref().map(|k| &k.receive);
            match decode::<P>(&self.buf[..n], key) {
                Ok((header, payload)) => {
                    self.stats.received += 1;
                    return Some(Received {
                        from,
                        header,
                        payload,
                        kernel_realtime_ns,
                    });
                }
                Err(e) => self.stats.refuse(e),
            }
        }
        None
    }

    /// One datagram into the buffer: its length, sender and kernel receive time (if asked for).
    fn receive_raw(&mut self) -> io::Result<(usize, SocketAddr, Option<i64>)> {
        let Some(control) = self.control.as_mut() else {
            let (n, from) = self.socket.recv_from(&mut self.buf[..])?;
            return Ok((n, from, None));
        };
        receive_with_stamp(&self.socket, &mut self.buf[..], control)
    }

    /// The counters.
    pub fn stats(&self) -> EndpointStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataplane::frame::{DATAPLANE_VERSION, StreamId};
    use crate::dataplane::stream::{StreamReceiver, StreamSender, Verdict};
    use std::time::{Duration, Instant};

    type Sample = [f64; 6];

    fn loopback(key: Option<DatagramKey>) -> Endpoint {
        Endpoint::bind("127.0.0.1:0".parse().unwrap(), key).unwrap()
    }

    /// Receives the next valid frame, waiting at most two seconds (a bound, not a timing
    /// claim: on loopback it is there at once).
    fn next(e: &mut Endpoint) -> Option<(SocketAddr, Header, Sample)> {
        let deadline = Instant::now() + Duration::from_secs(2);
        loop {
            if let Some(x) = e.receive() {
                return Some(x);
            }
            if Instant::now() > deadline {
                return None;
            }
            std::thread::yield_now();
        }
    }

    #[test]
    fn authenticated_frames_cross_loopback_and_forgeries_and_replays_do_not() {
        let key = DatagramKey::from_secret(b"lab");
        let (mut a, mut b) = (loopback(Some(key.clone())), loopback(Some(key)));
        let to = b.local_addr().unwrap();
        let mut tx = StreamSender::new(StreamId(1));
        let mut rx = StreamReceiver::new(StreamId(1));
        for i in 0..500 {
            let sample = [i as f64; 6];
            a.send(&tx.next(i * 1_000_000), &sample, to).unwrap();
            let (from, h, got) = next(&mut b).expect("a datagram on loopback");
            assert_eq!(from, a.local_addr().unwrap());
            assert_eq!(rx.offer(&h), Verdict::Accepted);
            assert_eq!(got, sample);
        }

        // Raw bytes from outside: an altered datagram, an untagged one, garbage, and a replay
        // of a genuine datagram.
        let raw = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut buf = [0u8; MAX_DATAGRAM];
        let genuine_key = DatagramKey::from_secret(b"lab");
        let old = tx.next(1);
        let n = encode(&old, &[9.0f64; 6], Some(&genuine_key), &mut buf).unwrap();
        let mut altered = buf;
        altered[5] ^= 1;
        raw.send_to(&altered[..n], to).unwrap();
        let mut plain_buf = [0u8; MAX_DATAGRAM];
        let plain = encode(&old, &[9.0f64; 6], None, &mut plain_buf).unwrap();
        raw.send_to(&plain_buf[..plain], to).unwrap();
        raw.send_to(b"not a datagram", to).unwrap();
        raw.send_to(&buf[..n], to).unwrap(); // genuine: accepted as newest
        raw.send_to(&buf[..n], to).unwrap(); // the same again: a replay
        let (_, h, _) = next(&mut b).unwrap();
        assert_eq!(rx.offer(&h), Verdict::Accepted);
        let (_, h, _) = next(&mut b).unwrap();
        assert_eq!(rx.offer(&h), Verdict::Duplicate);
        let s = b.stats();
        assert_eq!(
            (s.bad_tag, s.wrong_authentication, s.malformed, s.received),
            (1, 1, 1, 502)
        );
        // Another build's datagram (another data-plane version), genuine otherwise: counted
        // apart, with the version it spoke, so a lab can see why the link stays down.
        let mut other = tx.next(2);
        other.version = DATAPLANE_VERSION + 1;
        let n = encode(&other, &[1.0f64; 6], Some(&genuine_key), &mut buf).unwrap();
        raw.send_to(&buf[..n], to).unwrap();
        raw.send_to(&buf[..n], to).unwrap();
        let deadline = Instant::now() + Duration::from_secs(2);
        while b.stats().wrong_version < 2 && Instant::now() < deadline {
            let _ = b.receive::<[f64; 6]>();
            std::thread::yield_now();
        }
        let s = b.stats();
        assert_eq!(
            (s.wrong_version, s.other_version, s.malformed),
            (2, Some(DATAPLANE_VERSION + 1), 1)
        );
    }

    #[test]
    fn an_unkeyed_end_refuses_tagged_datagrams_and_nothing_waiting_is_none() {
        let mut plain = loopback(None);
        let mut keyed = loopback(Some(DatagramKey::from_secret(b"x")));
        assert!(plain.receive::<Sample>().is_none());
        let to = plain.local_addr().unwrap();
        keyed
            .send(&StreamSender::new(StreamId(2)).next(0), &[0.0f64; 6], to)
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(2);
        while plain.stats().wrong_authentication == 0 && Instant::now() < deadline {
            assert!(plain.receive::<Sample>().is_none());
        }
        assert_eq!(plain.stats().wrong_authentication, 1);
    }
}
