//! What the end of a channel linked to another node shows outside its communication thread:
//! its counters (newest wins) and every datagram of its two streams (what it sent, what it
//! took), the latter through a ring the thread pushes into without waiting, for a recorder.

use std::sync::{Arc, Mutex};

use penelope_hal::Reference;
use penelope_rt_core::cell::ArcLatestReader;
use penelope_rt_core::ring::{ArcConsumer, ArcProducer};
use penelope_rt_core::teleop::{PortEnergy, WaveSample};
use serde::{Deserialize, Serialize};

use crate::dataplane::endpoint::EndpointStats;
use crate::dataplane::faults::FaultCounters;
use crate::dataplane::frame::StreamId;
use crate::dataplane::histogram::TripHistogram;
use crate::dataplane::stream::StreamStats;

/// The stream of the master's samples to the slave.
pub const MASTER_TO_SLAVE: StreamId = StreamId(1);
/// The stream of the slave's samples to the master.
pub const SLAVE_TO_MASTER: StreamId = StreamId(2);

/// What an end's data-plane link counted.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ChannelLinkStats {
    /// The link is lost.
    pub down: bool,
    /// Times it was lost.
    pub losses: u64,
    /// Times it came back.
    pub restorations: u64,
    /// The socket's counters.
    pub endpoint: EndpointStats,
    /// The incoming stream's counters.
    pub stream: StreamStats,
    /// Datagrams from another address than the peer's.
    pub strangers: u64,
    /// The other node's clock minus this node's, ns, as heartbeats estimate it.
    pub clock_offset_ns: Option<i64>,
    /// The heartbeats' round trip, ns, of the exchange the offset comes from (the other
    /// side's turnaround excluded).
    pub round_trip_ns: Option<i64>,
    /// The one-way delay estimate, ns: half the round trip.
    pub one_way_delay_ns: Option<i64>,
    /// The jitter of the offset estimate, ns (RMS of the kept exchanges' offsets around it).
    pub jitter_ns: Option<i64>,
    /// How long before this end last looked for datagrams the other side's last one arrived,
    /// ns (`None` before the first).
    pub last_heard_ns: Option<i64>,
    /// The share of heartbeats not answered.
    pub heartbeat_loss: f64,
    /// The samples' one-way trips, ns: arrival (the kernel's stamp on real time) less the
    /// sender's send time on the common clock (before the offset is known, as sent: right
    /// when both nodes share a clock, as on one machine).
    pub one_way: TripHistogram,
    /// What the injected faults did to what this end sent, if faults are configured.
    pub faults: Option<FaultCounters>,
}

impl ChannelLinkStats {
    /// As a client sees it, read at `time_ns` (the node's clock).
    pub fn record(&self, time_ns: u64) -> penelope_protocol::proto::LinkRecord {
        let s = &self.stream;
        let trips = self.one_way.count();
        penelope_protocol::proto::LinkRecord {
            time_ns,
            down: self.down,
            losses: self.losses,
            restorations: self.restorations,
            samples_taken: s.accepted,
            samples_dropped: s.duplicate + s.late + s.stale_session,
            samples_missed: s.missed,
            refused: self.refused(),
            clock_offset_ns: self.clock_offset_ns,
            round_trip_ns: self.round_trip_ns,
            one_way_delay_ns: self.one_way_delay_ns,
            jitter_ns: self.jitter_ns,
            last_heard_ns: self.last_heard_ns,
            heartbeat_loss: self.heartbeat_loss,
            trips,
            trip_p50_ns: self.one_way.quantile(0.5),
            trip_p99_ns: self.one_way.quantile(0.99),
            trip_max_ns: (trips > 0).then(|| self.one_way.max_ns()),
        }
    }

    /// Datagrams refused: bad tag, wrong authentication, another data-plane version,
    /// malformed, or from a stranger.
    pub fn refused(&self) -> u64 {
        let e = self.endpoint;
        e.bad_tag + e.wrong_authentication + e.wrong_version + e.malformed + self.strangers
    }
}

/// Datagrams the ring between a communication thread and a recorder holds: two a
/// communication tick (one sent, one taken) at 500 Hz make 1,000 a second, and a recorder
/// drains every 50 ms, so a second's worth leaves it a twentyfold margin.
pub const DATAGRAM_RING_LEN: usize = 1024;

/// The communication thread's half of the datagram ring.
pub type DatagramTap = ArcProducer<StreamDatagram, DATAGRAM_RING_LEN>;

/// One of a channel's two data-plane streams, by what it carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StreamName {
    /// The master's samples (tool pose, clutch) to the slave.
    MasterToSlave,
    /// The slave's samples (tool pose, sensed wrench) to the master.
    SlaveToMaster,
}

impl StreamName {
    /// The stream of data-plane stream `id` (`None` for the heartbeats).
    pub fn of(id: StreamId) -> Option<StreamName> {
        match id {
            MASTER_TO_SLAVE => Some(StreamName::MasterToSlave),
            SLAVE_TO_MASTER => Some(StreamName::SlaveToMaster),
            _ => None,
        }
    }

    /// Its name in topics: `master-to-slave`, `slave-to-master`.
    pub fn as_str(self) -> &'static str {
        match self {
            StreamName::MasterToSlave => "master-to-slave",
            StreamName::SlaveToMaster => "slave-to-master",
        }
    }
}

/// One sample of a data-plane stream as this end handled it: sent (its `arrived_ns` and
/// `one_way_ns` are `None`) or taken (accepted by the newest-wins receiver: a duplicate, late
/// or stale datagram is only counted, in the link's statistics).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StreamDatagram {
    /// Its stream.
    pub stream: StreamName,
    /// When this end sent or took it, ns on this node's clock (the recording's log time).
    pub time_ns: u64,
    /// The sender's sequence number (in its session).
    pub sequence: u64,
    /// The send time in its header, ns: on the receiver's clock as the sender estimated it
    /// (the data plane's common clock of the link), or on the sender's before an estimate.
    pub sent_ns: i64,
    /// A taken sample's arrival, ns on this node's clock (the kernel's receive stamp on the
    /// real clock).
    pub arrived_ns: Option<i64>,
    /// A taken sample's one-way trip, ns: its arrival less its send time on this node's clock.
    pub one_way_ns: Option<i64>,
    /// The master's clutch button.
    pub clutch: bool,
    /// The sample: a pose, or a pose with the sensed wrench.
    pub reference: Reference,
    /// A wave-variable law's wave, if the channel's law sends one.
    pub wave: Option<WaveSample>,
    /// A two-port law's energy counters, if the channel's law sends them.
    pub energy: Option<PortEnergy>,
}

/// Where the counters and datagrams of a channel's link to another node are read from outside
/// the real-time threads (it locks): a recorder, a telemetry pump, the Zenoh bridge.
#[derive(Clone)]
pub struct LinkSource {
    stats: Arc<Mutex<ArcLatestReader<ChannelLinkStats>>>,
    datagrams: Arc<Mutex<ArcConsumer<StreamDatagram, DATAGRAM_RING_LEN>>>,
}

impl LinkSource {
    /// The reading halves of a link's counters cell and datagram ring.
    pub(crate) fn new(
        stats: ArcLatestReader<ChannelLinkStats>,
        datagrams: ArcConsumer<StreamDatagram, DATAGRAM_RING_LEN>,
    ) -> Self {
        LinkSource {
            stats: Arc::new(Mutex::new(stats)),
            datagrams: Arc::new(Mutex::new(datagrams)),
        }
    }

    /// The newest counters (`None` before the link's first communication tick).
    pub fn latest(&self) -> Option<ChannelLinkStats> {
        self.stats.lock().ok()?.latest()
    }

    /// Whether both read the same link (a channel configured anew has a new link, and so a
    /// new source).
    pub fn same_link(&self, other: &LinkSource) -> bool {
        Arc::ptr_eq(&self.stats, &other.stats)
    }

    /// Hands every datagram the ring holds, oldest first, to `each`. The ring has one reader:
    /// a recorder, which starts by discarding what is there (see [`skip_datagrams`]).
    ///
    /// [`skip_datagrams`]: Self::skip_datagrams
    pub fn drain_datagrams(&self, mut each: impl FnMut(StreamDatagram)) {
        if let Ok(mut ring) = self.datagrams.lock() {
            while let Some(d) = ring.pop() {
                each(d);
            }
        }
    }

    /// Discards what the ring holds (what was sent and taken before a recording began, and
    /// what filled it while nobody read it); returns the ring's drop count, from which the
    /// recording's own losses are counted.
    pub fn skip_datagrams(&self) -> u64 {
        let Ok(mut ring) = self.datagrams.lock() else {
            return 0;
        };
        while ring.pop().is_some() {}
        ring.dropped() as u64
    }

    /// Datagrams the ring refused because it was full, ever (wrapping at `usize`).
    pub fn datagrams_dropped(&self) -> u64 {
        self.datagrams.lock().map_or(0, |r| r.dropped() as u64)
    }
}
