//! The sensor node's side of a sensor stream: one endpoint and one thread (normal priority: it
//! is not a control thread) that takes subscriptions and probes, measures the sensor every
//! period at the newest probe, and sends the same sample to every subscriber.

use std::io;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use penelope_hal::Wrench;
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, latest};
use penelope_rt_core::clock::MonotonicClock;

use super::{
    MAX_SUBSCRIBERS, Probe, SENSOR_SAMPLES, SENSOR_SUBSCRIPTIONS, SUBSCRIBER_TIMEOUT,
    SensorDatagram, SubscriberTable, nanos,
};
use crate::dataplane::endpoint::{Endpoint, EndpointStats, RECEIVE_BURST};
use crate::dataplane::stream::StreamSender;
use penelope_protocol::proto::WrenchMsg;

/// How a publisher measures its sensor: at the newest probe, or, when no subscriber sent one,
/// as it is (`None`). `None` back: no measurement this period (nothing is sent).
pub type Measure = Box<dyn FnMut(Option<&Probe>) -> Option<Wrench> + Send>;

/// What a publisher counted (for `describe`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PublisherStats {
    /// Subscribers now.
    pub subscribers: usize,
    /// Samples measured and sent (each to every subscriber).
    pub samples: u64,
    /// Probes taken from subscriptions.
    pub probes: u64,
    /// Probes refused: a NaN, an infinity, or a pose that is not a rotation.
    pub bad_probes: u64,
    /// Subscriptions refused because the table was full.
    pub refused_full: u64,
    /// Subscriptions refused as not newer than the subscriber's last (replays).
    pub refused_stale: u64,
    /// Datagrams of the wrong direction or stream (a sample sent to the publisher).
    pub unexpected: u64,
    /// Subscribers dropped for silence.
    pub expired: u64,
    /// Measurements that failed or were not finite (nothing sent).
    pub failed_measurements: u64,
    /// The endpoint's counters: bad tags, wrong authentication, malformed datagrams.
    pub endpoint: EndpointStats,
}

impl PublisherStats {
    /// Datagrams refused, whatever the reason.
    pub fn refused(&self) -> u64 {
        let e = self.endpoint;
        e.bad_tag
            + e.wrong_authentication
            + e.wrong_version
            + e.malformed
            + self.bad_probes
            + self.refused_full
            + self.refused_stale
            + self.unexpected
    }
}

/// A running publisher: its thread stops and is joined when this is dropped.
pub struct SensorPublisher {
    address: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    stats: Mutex<ArcLatestReader<PublisherStats>>,
}

impl std::fmt::Debug for SensorPublisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SensorPublisher")
            .field("address", &self.address)
            .finish_non_exhaustive()
    }
}

impl SensorPublisher {
    /// Serves the sensor that `measure` reads from `endpoint` (bound on the sensor's node),
    /// measuring and sending every `period`; `name` names the thread.
    ///
    /// # Errors
    /// The operating system's, from reading the endpoint's address or starting the thread.
    pub fn start(
        name: &str,
        endpoint: Endpoint,
        period: Duration,
        measure: Measure,
    ) -> io::Result<Self> {
        let address = endpoint.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let (writer, reader) = latest();
        let mut serving = Serving {
            endpoint,
            table: SubscriberTable::new(MAX_SUBSCRIBERS, SUBSCRIBER_TIMEOUT),
            samples: StreamSender::new(SENSOR_SAMPLES),
            measure,
            stats: PublisherStats::default(),
            out: writer,
        };
        let thread = {
            let stop = stop.clone();
            std::thread::Builder::new()
                .name(format!("publish-{name}"))
                .spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        std::thread::sleep(period);
                        serving.step(nanos(MonotonicClock::read()));
                    }
                })?
        };
        Ok(SensorPublisher {
            address,
            stop,
            thread: Some(thread),
            stats: Mutex::new(reader),
        })
    }

    /// The address it serves (readers send their subscriptions here).
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// The newest counters (zero before the first period).
    pub fn stats(&self) -> PublisherStats {
        self.stats
            .lock()
            .ok()
            .and_then(|mut r| r.latest())
            .unwrap_or_default()
    }
}

impl Drop for SensorPublisher {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// What the publisher thread holds.
struct Serving {
    endpoint: Endpoint,
    table: SubscriberTable,
    samples: StreamSender,
    measure: Measure,
    stats: PublisherStats,
    out: ArcLatestWriter<PublisherStats>,
}

impl Serving {
    /// One period at `now_ns`: takes what arrived, drops the silent, measures and sends to
    /// everyone, publishes the counters.
    fn step(&mut self, now_ns: i64) {
        self.take_datagrams(now_ns);
        self.table.expire(now_ns);
        if !self.table.is_empty() {
            let probe = self.table.newest_probe();
            match (self.measure)(probe.as_ref()) {
                Some(w) if w.is_finite() => {
                    let header = self.samples.next(now_ns);
                    let datagram = SensorDatagram::Sample {
                        wrench: WrenchMsg::from(&w),
                    };
                    // The same datagram, one sequence number, to every subscriber: all readers
                    // see the same samples. A refused send is counted by the endpoint.
                    let to: Vec<SocketAddr> = self.table.addresses().collect();
                    for addr in to {
                        let _ = self.endpoint.send(&header, &datagram, addr);
                    }
                    self.stats.samples += 1;
                }
                _ => self.stats.failed_measurements += 1,
            }
        }
        self.stats.subscribers = self.table.len();
        self.stats.probes = self.table.probes_taken();
        self.stats.refused_full = self.table.refused_full();
        self.stats.refused_stale = self.table.refused_stale();
        self.stats.expired = self.table.expired();
        self.stats.endpoint = self.endpoint.stats();
        self.out.write(self.stats);
    }

    /// Takes at most a few bursts of datagrams (bounded work per period, whatever arrives).
    fn take_datagrams(&mut self, now_ns: i64) {
        for _ in 0..4 * RECEIVE_BURST {
            let Some((from, header, datagram)) = self.endpoint.receive::<SensorDatagram>() else {
                break;
            };
            if header.stream != SENSOR_SUBSCRIPTIONS {
                self.stats.unexpected += 1;
                continue;
            }
            match datagram {
                SensorDatagram::Subscribe { probe } => {
                    let probe = match probe.map(|p| p.to_probe()) {
                        Some(None) => {
                            self.stats.bad_probes += 1;
                            continue;
                        }
                        Some(Some(p)) => Some(p),
                        None => None,
                    };
                    // Refusals are counted by the table.
                    let _ = self.table.subscribe(from, &header, probe, now_ns);
                }
                SensorDatagram::Unsubscribe => {
                    self.table.unsubscribe(from, &header);
                }
                SensorDatagram::Sample { .. } => self.stats.unexpected += 1,
            }
        }
    }
}
