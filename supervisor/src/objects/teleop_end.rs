//! The two ends of a `trajectory/teleop` channel and how samples cross between them: through a
//! pair of lock-free cells when both robots are on this node, or over the data plane (UDP, one
//! stream per direction, newest wins) when the other robot is on another node. Either way the
//! communication thread that holds the end does the I/O; the control thread never does.

use std::net::SocketAddr;

use penelope_hal::{Reference, Timestamp};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Fresh, latest};
use penelope_rt_core::teleop::TeleopSample;

use crate::dataplane::endpoint::{Endpoint, EndpointStats, RECEIVE_BURST};
use crate::dataplane::frame::StreamId;
use crate::dataplane::stream::{StreamReceiver, StreamSender, StreamStats, Verdict};

/// The stream of the master's samples to the slave.
pub const MASTER_TO_SLAVE: StreamId = StreamId(1);
/// The stream of the slave's samples to the master.
pub const SLAVE_TO_MASTER: StreamId = StreamId(2);

/// Which side of a channel a loop runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// Sends the master's tool pose and clutch; receives the slave's pose and wrench.
    Master,
    /// Sends the slave's tool pose and sensed wrench; receives the master's pose and clutch.
    Slave,
}

impl Side {
    /// The streams this side sends on and receives from.
    fn streams(self) -> (StreamId, StreamId) {
        match self {
            Side::Master => (MASTER_TO_SLAVE, SLAVE_TO_MASTER),
            Side::Slave => (SLAVE_TO_MASTER, MASTER_TO_SLAVE),
        }
    }
}

/// What a sample carries on the data plane (the header carries sequence and send time).
type WireSample = (bool, Reference);

/// One side's end of the channel.
pub struct TeleopEnd {
    /// Its side.
    pub side: Side,
    transport: Transport,
    /// The sequence number of the last sample sent: kept with the end, so that a loop
    /// re-activated on it goes on numbering and the other side (newest wins) takes its samples.
    sent: u64,
}

enum Transport {
    /// Both ends on this node.
    Cells {
        send: ArcLatestWriter<TeleopSample>,
        receive: ArcLatestReader<TeleopSample>,
    },
    /// The other end on another node.
    DataPlane(Box<RemoteLink>),
}

/// The data-plane link of an end whose other end is on another node.
struct RemoteLink {
    endpoint: Endpoint,
    peer: SocketAddr,
    sender: StreamSender,
    receiver: StreamReceiver,
    /// Samples taken so far: the channel's sequence numbers (newest wins there too), which stay
    /// increasing when the other side restarts with a new session.
    taken: u64,
    /// Datagrams from an address other than the peer's, dropped.
    strangers: u64,
}

/// What an end's data-plane link counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// The socket's counters.
    pub endpoint: EndpointStats,
    /// The incoming stream's counters.
    pub stream: StreamStats,
    /// Datagrams from another address than the peer's.
    pub strangers: u64,
}

impl TeleopEnd {
    /// `side`'s end linked over the data plane: `endpoint` (bound on this node) exchanges
    /// samples with the other side's endpoint at `peer`.
    pub fn remote(side: Side, endpoint: Endpoint, peer: SocketAddr) -> Self {
        let (out, inbound) = side.streams();
        TeleopEnd {
            side,
            transport: Transport::DataPlane(Box::new(RemoteLink {
                endpoint,
                peer,
                sender: StreamSender::new(out),
                receiver: StreamReceiver::new(inbound),
                taken: 0,
                strangers: 0,
            })),
            sent: 0,
        }
    }

    /// The sequence number of the last sample sent.
    pub fn sent(&self) -> u64 {
        self.sent
    }

    /// Notes the sequence number of the last sample sent (when a loop gives the end back).
    pub fn set_sent(&mut self, sent: u64) {
        self.sent = sent;
    }

    /// Sends `sample` to the other side.
    ///
    /// # Real-time
    /// A cell write, or one non-blocking `sendto` (a refusal is counted, not waited on).
    pub fn publish(&mut self, sample: TeleopSample) {
        match &mut self.transport {
            Transport::Cells { send, .. } => send.write(sample),
            Transport::DataPlane(link) => {
                let sent_ns = i64::try_from(sample.sent.as_nanos()).unwrap_or(i64::MAX);
                let header = link.sender.next(sent_ns);
                let payload: WireSample = (sample.clutch, sample.reference);
                let _ = link.endpoint.send(&header, &payload, link.peer);
            }
        }
    }

    /// The other side's newest sample since the last call, if one arrived.
    ///
    /// # Real-time
    /// A cell read, or at most [`RECEIVE_BURST`] non-blocking `recvfrom` calls.
    pub fn take_newest(&mut self) -> Option<TeleopSample> {
        match &mut self.transport {
            Transport::Cells { receive, .. } => match receive.read() {
                Fresh::New(s) => Some(s),
                _ => None,
            },
            Transport::DataPlane(link) => {
                let mut newest = None;
                for _ in 0..RECEIVE_BURST {
                    let Some((from, header, (clutch, reference))) =
                        link.endpoint.receive::<WireSample>()
                    else {
                        break;
                    };
                    if from != link.peer {
                        link.strangers += 1;
                        continue;
                    }
                    if link.receiver.offer(&header) == Verdict::Accepted {
                        link.taken += 1;
                        newest = Some(TeleopSample {
                            sequence: link.taken,
                            sent: Timestamp::from_nanos(u64::try_from(header.sent_ns).unwrap_or(0)),
                            clutch,
                            reference,
                        });
                    }
                }
                newest
            }
        }
    }

    /// The data-plane link's counters (`None` for an end on cells).
    pub fn link_stats(&self) -> Option<LinkStats> {
        match &self.transport {
            Transport::Cells { .. } => None,
            Transport::DataPlane(link) => Some(LinkStats {
                endpoint: link.endpoint.stats(),
                stream: link.receiver.stats(),
                strangers: link.strangers,
            }),
        }
    }
}

/// The ends of a configured channel on this node; each is lent to the loop that runs it. A
/// channel whose other robot is on another node has only this node's end.
pub struct TeleopLink {
    /// The master's end, while no loop holds it.
    pub master: Option<TeleopEnd>,
    /// The slave's end, while no loop holds it.
    pub slave: Option<TeleopEnd>,
    /// Which ends are on this node (the others are on another node).
    local: (bool, bool),
}

impl TeleopLink {
    /// Both ends on this node, joined by new cells.
    pub fn new() -> Self {
        let (m2s_w, m2s_r) = latest::<TeleopSample>();
        let (s2m_w, s2m_r) = latest::<TeleopSample>();
        TeleopLink {
            master: Some(TeleopEnd {
                side: Side::Master,
                transport: Transport::Cells {
                    send: m2s_w,
                    receive: s2m_r,
                },
                sent: 0,
            }),
            slave: Some(TeleopEnd {
                side: Side::Slave,
                transport: Transport::Cells {
                    send: s2m_w,
                    receive: m2s_r,
                },
                sent: 0,
            }),
            local: (true, true),
        }
    }

    /// Only `end` on this node; the other side's end is on another node.
    pub fn one_end(end: TeleopEnd) -> Self {
        let side = end.side;
        let mut link = TeleopLink {
            master: None,
            slave: None,
            local: (side == Side::Master, side == Side::Slave),
        };
        link.put_back(end);
        link
    }

    /// Whether `side`'s end lives on this node.
    pub fn is_local(&self, side: Side) -> bool {
        match side {
            Side::Master => self.local.0,
            Side::Slave => self.local.1,
        }
    }

    /// Takes `side`'s end.
    pub fn take(&mut self, side: Side) -> Option<TeleopEnd> {
        match side {
            Side::Master => self.master.take(),
            Side::Slave => self.slave.take(),
        }
    }

    /// Gives an end back.
    pub fn put_back(&mut self, end: TeleopEnd) {
        match end.side {
            Side::Master => self.master = Some(end),
            Side::Slave => self.slave = Some(end),
        }
    }
}

impl Default for TeleopLink {
    fn default() -> Self {
        TeleopLink::new()
    }
}
