//! A node's data-plane socket: UDP, non-blocking, sending and receiving whole frames and
//! counting every datagram it refused. Meant for communication threads: no call blocks, and a
//! receive call does a bounded amount of work.

use std::io;
use std::net::{SocketAddr, UdpSocket};

use serde::Serialize;
use serde::de::DeserializeOwned;

use super::frame::{DatagramKey, FrameError, Header, MAX_DATAGRAM, decode, encode};

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
    /// Datagrams of another version, kind or shape, or too long.
    pub malformed: u64,
}

impl EndpointStats {
    fn refuse(&mut self, e: FrameError) {
        match e {
            FrameError::BadTag => self.bad_tag += 1,
            FrameError::Authentication(..) => self.wrong_authentication += 1,
            _ => self.malformed += 1,
        }
    }
}

/// Why a frame was not sent.
#[derive(Debug, thiserror::Error)]
pub enum SendError {
    /// It does not fit a datagram.
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// The operating system refused it.
    #[error("send: {0}")]
    Io(#[from] io::Error),
}

/// A bound data-plane socket and the key its system's datagrams carry (none without a secret).
pub struct Endpoint {
    socket: UdpSocket,
    key: Option<DatagramKey>,
    buf: Box<[u8; MAX_DATAGRAM]>,
    stats: EndpointStats,
}

impl std::fmt::Debug for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Endpoint")
            .field("local", &self.socket.local_addr().ok())
            .field("authenticated", &self.key.is_some())
            .field("stats", &self.stats)
            .finish()
    }
}

impl Endpoint {
    /// Binds `addr` (port 0: any free port), non-blocking; datagrams are tagged and checked
    /// with `key` when given.
    ///
    /// # Errors
    /// The operating system's, from binding.
    pub fn bind(addr: SocketAddr, key: Option<DatagramKey>) -> io::Result<Self> {
        let socket = UdpSocket::bind(addr)?;
        socket.set_nonblocking(true)?;
        Ok(Endpoint {
            socket,
            key,
            buf: Box::new([0; MAX_DATAGRAM]),
            stats: EndpointStats::default(),
        })
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
        let n = encode(header, payload, self.key.as_ref(), &mut self.buf[..])?;
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
        for _ in 0..RECEIVE_BURST {
            let (n, from) = match self.socket.recv_from(&mut self.buf[..]) {
                Ok(x) => x,
                // Would block: nothing waiting. Other errors (an ICMP refusal reported on this
                // socket) say nothing about the next datagram: stop for this call.
                Err(_) => return None,
            };
            match decode::<P>(&self.buf[..n], self.key.as_ref()) {
                Ok((header, payload)) => {
                    self.stats.received += 1;
                    return Some((from, header, payload));
                }
                Err(e) => self.stats.refuse(e),
            }
        }
        None
    }

    /// The counters.
    pub fn stats(&self) -> EndpointStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataplane::frame::StreamId;
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
