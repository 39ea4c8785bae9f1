//! A reader's end of a sensor stream: subscribes (with its probe, if it has one), renews, and
//! keeps the newest sample. Used by a controller's sensor feed thread, and by anyone who wants
//! to watch a sensor; every call is non-blocking and does a bounded amount of work.

use std::io;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};

use penelope_hal::{Frame, Wrench};

use super::{Probe, ProbeMsg, RENEW_EVERY, SENSOR_SAMPLES, SENSOR_SUBSCRIPTIONS, SensorDatagram};
use crate::dataplane::endpoint::{Endpoint, EndpointStats, RECEIVE_BURST};
use crate::dataplane::frame::{DatagramKey, DirectedKeys, Header};
use crate::dataplane::stream::{StreamReceiver, StreamSender, StreamStats, Verdict};

/// One sample of a sensor stream as a reader takes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WrenchSample {
    /// The publisher's session (a restarted publisher draws a new one).
    pub session: u64,
    /// Its sequence number in the session: the same for every reader.
    pub sequence: u64,
    /// When it was measured, ns on the sensor node's clock.
    pub measured_ns: i64,
    /// The wrench, base frame, N and N·m.
    pub wrench: Wrench,
}

/// What a subscriber counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SubscriberStats {
    /// Subscriptions sent (renewals and probes).
    pub subscriptions: u64,
    /// The socket's counters.
    pub endpoint: EndpointStats,
    /// The sample stream's counters (accepted, late, duplicates, missed).
    pub stream: StreamStats,
    /// Datagrams from an address other than the publisher's.
    pub strangers: u64,
    /// Samples whose wrench was not finite, or datagrams that were not samples.
    pub unexpected: u64,
}

/// A reader subscribed to one sensor's publisher.
pub struct SensorSubscriber {
    endpoint: Endpoint,
    publisher: SocketAddr,
    subscriptions: StreamSender,
    samples: StreamReceiver,
    /// When the last subscription went out, ns on this node's clock.
    last_sent_ns: Option<i64>,
    stats: SubscriberStats,
}

impl std::fmt::Debug for SensorSubscriber {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SensorSubscriber")
            .field("publisher", &self.publisher)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

impl SensorSubscriber {
    /// A reader of the sensor published at `publisher`, on a new endpoint (any free port, on
    /// loopback when the publisher is on loopback, else on every interface), keyed with `key`.
    /// Nothing is sent until the first [`poll`](Self::poll).
    ///
    /// # Errors
    /// The operating system's, from binding.
    pub fn connect(publisher: SocketAddr, key: Option<DatagramKey>) -> io::Result<Self> {
        let keys = key.map(|k| DirectedKeys {
            send: k.clone(),
            receive: k,
        });
        SensorSubscriber::connect_directed(publisher, keys)
    }

    /// As [`connect`](Self::connect), with the keys of this sensor's directions
    /// ([`sensor_reader_keys`](super::sensor_reader_keys)).
    ///
    /// # Errors
    /// The operating system's, from binding.
    pub fn connect_directed(publisher: SocketAddr, keys: Option<DirectedKeys>) -> io::Result<Self> {
        let ip: IpAddr = match (publisher.ip().is_loopback(), publisher.is_ipv4()) {
            (true, true) => Ipv4Addr::LOCALHOST.into(),
            (true, false) => Ipv6Addr::LOCALHOST.into(),
            (false, true) => Ipv4Addr::UNSPECIFIED.into(),
            (false, false) => Ipv6Addr::UNSPECIFIED.into(),
        };
        let endpoint = Endpoint::bind_directed(SocketAddr::new(ip, 0), keys)?;
        Ok(SensorSubscriber {
            endpoint,
            publisher,
            subscriptions: StreamSender::new(SENSOR_SUBSCRIPTIONS),
            samples: StreamReceiver::new(SENSOR_SAMPLES),
            last_sent_ns: None,
            stats: SubscriberStats::default(),
        })
    }

    /// The publisher's address.
    pub fn publisher(&self) -> SocketAddr {
        self.publisher
    }

    /// At `now_ns` (this node's clock): sends a subscription carrying `probe` when there is one,
    /// or, without a probe, when the last went out [`RENEW_EVERY`] ago; then returns the newest
    /// sample that arrived since the last call, if any.
    ///
    /// # Real-time
    /// At most one non-blocking `sendto` and [`RECEIVE_BURST`] non-blocking `recvfrom`; no
    /// allocation. Not called from a control thread.
    pub fn poll(&mut self, now_ns: i64, probe: Option<&Probe>) -> Option<WrenchSample> {
        let renew_ns = i64::try_from(RENEW_EVERY.as_nanos()).unwrap_or(i64::MAX);
        let due = self
            .last_sent_ns
            .is_none_or(|t| now_ns.saturating_sub(t) >= renew_ns);
        if probe.is_some() || due {
            let datagram = SensorDatagram::Subscribe {
                probe: probe.map(ProbeMsg::from),
            };
            let header = self.subscriptions.next(now_ns);
            // A refused send is counted by the endpoint; the next poll sends again.
            let _ = self.endpoint.send(&header, &datagram, self.publisher);
            self.stats.subscriptions += 1;
            self.last_sent_ns = Some(now_ns);
        }
        self.take_newest()
    }

    /// The newest sample that arrived since the last call, if any (no subscription sent).
    pub fn take_newest(&mut self) -> Option<WrenchSample> {
        let mut newest = None;
        for _ in 0..RECEIVE_BURST {
            let Some((from, header, datagram)) = self.endpoint.receive::<SensorDatagram>() else {
                break;
            };
            if from != self.publisher {
                self.stats.strangers += 1;
                continue;
            }
            if let Some(s) = self.sample(&header, datagram) {
                newest = Some(s);
            }
        }
        newest
    }

    /// The sample in `datagram`, if it is a finite one and the newest.
    fn sample(&mut self, header: &Header, datagram: SensorDatagram) -> Option<WrenchSample> {
        let SensorDatagram::Sample { wrench } = datagram else {
            self.stats.unexpected += 1;
            return None;
        };
        let Ok(wrench) = wrench.to_wrench(Frame::Base) else {
            self.stats.unexpected += 1;
            return None;
        };
        (self.samples.offer(header) == Verdict::Accepted).then_some(WrenchSample {
            session: header.session,
            sequence: header.sequence,
            measured_ns: header.sent_ns,
            wrench,
        })
    }

    /// The counters.
    pub fn stats(&self) -> SubscriberStats {
        SubscriberStats {
            endpoint: self.endpoint.stats(),
            stream: self.samples.stats(),
            ..self.stats
        }
    }
}

impl Drop for SensorSubscriber {
    /// Tells the publisher at once (else it drops this reader after its timeout).
    fn drop(&mut self) {
        let header = self.subscriptions.next(self.last_sent_ns.unwrap_or(0));
        let _ = self
            .endpoint
            .send(&header, &SensorDatagram::Unsubscribe, self.publisher);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataplane::sensor_stream::SensorPublisher;
    use crate::dataplane::sensor_stream::publisher::Measure;
    use nalgebra::Vector3;
    use std::net::UdpSocket;
    use std::time::{Duration, Instant};

    fn loopback(key: Option<DatagramKey>) -> Endpoint {
        Endpoint::bind("127.0.0.1:0".parse().unwrap(), key).unwrap()
    }

    /// A wall at z = 0.5 m, 1000 N/m: the wrench is (0, 0, 1000 (0.5 - z)) below it.
    fn wall() -> Measure {
        Box::new(|probe: Option<&Probe>| {
            let z = probe.map_or(1.0, |p| p.pose.translation.vector.z);
            Some(Wrench {
                force: Vector3::new(0.0, 0.0, (1000.0 * (0.5 - z)).max(0.0)),
                torque: Vector3::zeros(),
                frame: Frame::Base,
            })
        })
    }

    fn now() -> i64 {
        super::super::nanos(penelope_rt_core::clock::MonotonicClock::read())
    }

    /// Polls until `done` holds, at most 5 s (a bound, not a timing claim).
    fn poll_until(
        sub: &mut SensorSubscriber,
        probe: Option<&Probe>,
        mut done: impl FnMut(&WrenchSample) -> bool,
    ) -> WrenchSample {
        let deadline = Instant::now() + Duration::from_secs(5);
        loop {
            if let Some(s) = sub.poll(now(), probe)
                && done(&s)
            {
                return s;
            }
            assert!(
                Instant::now() < deadline,
                "no such sample: {:?}",
                sub.stats()
            );
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    #[test]
    fn a_probing_reader_gets_the_wall_and_forgeries_and_nan_probes_are_refused() {
        let key = DatagramKey::from_secret(b"lab");
        let publisher = SensorPublisher::start(
            "wall",
            loopback(Some(key.clone())),
            Duration::from_millis(1),
            wall(),
        )
        .unwrap();
        let mut reader = SensorSubscriber::connect(publisher.address(), Some(key)).unwrap();
        let probe = Probe {
            pose: penelope_hal::Pose::translation(0.0, 0.0, 0.49),
            velocity: Vector3::zeros(),
        };
        let s = poll_until(&mut reader, Some(&probe), |s| s.wrench.force.z > 0.0);
        assert!((s.wrench.force.z - 10.0).abs() < 1e-9, "{s:?}");

        // A forged subscription (another system's key), garbage, and a NaN probe from a
        // member: refused and counted, and the publisher keeps serving.
        let forger = SensorSubscriber::connect(
            publisher.address(),
            Some(DatagramKey::from_secret(b"not the lab")),
        );
        let mut forger = forger.unwrap();
        forger.poll(now(), Some(&probe));
        let raw = UdpSocket::bind("127.0.0.1:0").unwrap();
        raw.send_to(b"\x02garbage", publisher.address()).unwrap();
        let mut member = loopback(Some(DatagramKey::from_secret(b"lab")));
        let nan = SensorDatagram::Subscribe {
            probe: Some(ProbeMsg {
                velocity: [f64::NAN, 0.0, 0.0],
                ..ProbeMsg::from(&probe)
            }),
        };
        member
            .send(
                &StreamSender::new(SENSOR_SUBSCRIPTIONS).next(0),
                &nan,
                publisher.address(),
            )
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(5);
        while publisher.stats().refused() < 3 {
            assert!(Instant::now() < deadline, "{:?}", publisher.stats());
            std::thread::sleep(Duration::from_millis(1));
        }
        let stats = publisher.stats();
        assert_eq!(
            (
                stats.endpoint.bad_tag,
                stats.endpoint.malformed,
                stats.bad_probes
            ),
            (1, 1, 1),
            "{stats:?}"
        );
        assert_eq!(stats.subscribers, 1, "only the genuine reader: {stats:?}");
        let before = reader.stats().stream.accepted;
        poll_until(&mut reader, Some(&probe), |_| true);
        assert!(reader.stats().stream.accepted > before);
        // The forger got nothing.
        assert_eq!(forger.take_newest(), None);
    }
}
