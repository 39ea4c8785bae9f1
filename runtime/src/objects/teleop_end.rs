//! The two ends of a `trajectory/teleop` channel and how samples cross between them: through a
//! pair of lock-free cells when both robots are on this node, or over the data plane (UDP, one
//! stream per direction, newest wins) when the other robot is on another node. Either way the
//! communication thread that holds the end does the I/O; the control thread never does.

use std::net::SocketAddr;
use std::os::fd::AsFd;
use std::sync::Arc;
use std::time::Duration;

use penelope_hal::{Reference, Timestamp};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Fresh, latest};
use penelope_rt_core::wake::{Doorbell, WakeOn};

/// Where an end linked to another node publishes its [`ChannelLinkStats`] (read by the channel
/// object for `describe`).
type StatsWriter = ArcLatestWriter<ChannelLinkStats>;
use penelope_rt_core::teleop::{PortEnergy, PortPayload, TeleopSample, WaveSample};

use serde::{Deserialize, Serialize};

use crate::dataplane::end_clock::{EndClock, LinkTime};
use crate::dataplane::endpoint::{Endpoint, RECEIVE_BURST, Received};
use crate::dataplane::faults::{FaultConfig, FaultConfigError, FaultyLink};
use crate::dataplane::frame::Header;
use crate::dataplane::frame::StreamId;
use crate::dataplane::histogram::TripHistogram;
use crate::dataplane::stream::{StreamReceiver, StreamSender, Verdict};
use crate::objects::delay_line::DelayLine;
use crate::objects::link_source::{
    ChannelLinkStats, DatagramTap, LinkSource, MASTER_TO_SLAVE, SLAVE_TO_MASTER, StreamDatagram,
    StreamName,
};
use penelope_protocol::link_clock::LinkClock;

/// The heartbeats and their answers, both ways (each answered, not newest-wins).
pub const HEARTBEATS: StreamId = StreamId(0);
/// A heartbeat goes out with every this many samples.
pub const HEARTBEAT_EVERY: u64 = 5;
/// Datagrams an injected-fault link holds at once (beyond: dropped and counted).
pub const FAULTY_CAPACITY: usize = 256;

/// Which side of a channel a loop runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// Sends the master's tool pose and clutch; receives the slave's pose and wrench.
    Master,
    /// Sends the slave's tool pose and sensed wrench; receives the master's pose and clutch.
    Slave,
}

impl Side {
    /// Where this side's control loop ticks in its period `period` on the common clock (its
    /// tick phase): the master at 0, the slave half a period later. A sample of either side
    /// then waits about half a period for the other side's next tick, in both directions,
    /// instead of one direction waiting almost a period and the other almost nothing (the
    /// phase two loops started with). Both sides ticking at the same period is what aligns
    /// them.
    pub fn tick_phase(self, period: Duration) -> Duration {
        match self {
            Side::Master => Duration::ZERO,
            Side::Slave => period / 2,
        }
    }

    /// The streams this side sends on and receives from.
    fn streams(self) -> (StreamId, StreamId) {
        match self {
            Side::Master => (MASTER_TO_SLAVE, SLAVE_TO_MASTER),
            Side::Slave => (SLAVE_TO_MASTER, MASTER_TO_SLAVE),
        }
    }
}

/// What crosses a channel's data-plane link (the header carries stream, sequence and send time).
// A sample is the datagram sent every communication tick, built on the stack and encoded at
// once: boxing it to shrink the heartbeat variants would allocate on the real-time path.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
enum LinkDatagram {
    /// A sample of the sending side.
    Sample {
        /// The master's clutch button.
        clutch: bool,
        /// The sample.
        reference: Reference,
        /// The passivity payload's wave (a wave-variable law's), with the sender's running
        /// totals: the wave transform runs in each side's communication thread, so the wave
        /// has to cross with the sample.
        wave: Option<WaveSample>,
        /// The passivity payload's two-port energy counters.
        energy: Option<PortEnergy>,
        /// Sent on a new safety event of the sender's loop: the receiver hands it on at once
        /// ([`TeleopSample::urgent`]).
        urgent: bool,
    },
    /// A heartbeat, sent at the header's send time (the sender's clock).
    Heartbeat,
    /// The answer to heartbeat `heartbeat`: received at `received_ns`, answered at the
    /// header's send time (the answering side's clock).
    Answer {
        /// The heartbeat's sequence number.
        heartbeat: u64,
        /// When the heartbeat was received, ns on the answering side's clock.
        received_ns: i64,
    },
}

/// One side's end of the channel.
pub struct TeleopEnd {
    /// Its side.
    pub side: Side,
    transport: Transport,
    /// The sequence number of the last sample sent: kept with the end, so that a loop
    /// re-activated on it goes on numbering and the other side (newest wins) takes its samples.
    sent: u64,
    /// Wakes the communication thread that holds this end before its period: rung by its own
    /// loop on a new safety event, and, on cells, by the other end's thread when it sent an
    /// urgent sample (`None` if the OS had no descriptor for it: the thread then only ticks).
    doorbell: Option<Arc<Doorbell>>,
    /// On cells: ring the other end's doorbell with every sample, not only an urgent one
    /// (event-driven handoff).
    wake_peer: bool,
}

/// A doorbell for an end; `None`, said in the log, when the OS refuses one.
fn new_doorbell() -> Option<Arc<Doorbell>> {
    match Doorbell::new() {
        Ok(d) => Some(Arc::new(d)),
        Err(e) => {
            log::warn!("teleop channel: no doorbell ({e}); urgent samples wait for the period");
            None
        }
    }
}

enum Transport {
    /// Both ends on this node; what this end sends goes through a delay line when the
    /// channel has faults.
    Cells {
        send: ArcLatestWriter<TeleopSample>,
        receive: ArcLatestReader<TeleopSample>,
        delay: Option<Box<DelayLine>>,
        /// The other end's doorbell, rung with an urgent sample (not through a delay line:
        /// a delayed sample arrives when the line lets it, at the other end's tick).
        peer: Option<Arc<Doorbell>>,
    },
    /// The other end on another node.
    DataPlane(Box<RemoteLink>),
    /// The other end outside Penelope, behind a bridge (an operator station on Zenoh): the
    /// bridge's non-real-time thread writes what it took into `receive` and reads what this
    /// end sends from `send`. What arrives is stamped with the tick that takes it: the bridge
    /// has no clock common with the sender.
    Bridged {
        send: ArcLatestWriter<TeleopSample>,
        receive: ArcLatestReader<TeleopSample>,
    },
}

/// The bridge's side of a channel end whose other end is outside Penelope
/// ([`TeleopLink::bridged`]): what the bridge hands the loop, and what the loop sends back.
/// Held by a non-real-time thread only.
pub struct BridgedEnd {
    /// Where the bridge writes each sample it took (its `sent` is overwritten by the tick
    /// that takes it).
    pub to_loop: ArcLatestWriter<TeleopSample>,
    /// The newest sample this node's end sent (its robot's pose and wrench).
    pub from_loop: ArcLatestReader<TeleopSample>,
}

/// The data-plane link of an end whose other end is on another node.
struct RemoteLink {
    endpoint: Endpoint,
    peer: SocketAddr,
    sender: StreamSender,
    receiver: StreamReceiver,
    heartbeats: StreamSender,
    /// The other node's clock as heartbeats estimate it.
    clock: LinkClock,
    /// The clock this end stamps with (the tick's, or the real one and the kernel's receive
    /// stamps), and its injected offset.
    stamps: EndClock,
    /// This end's time when it last looked for datagrams, and when the last one from the peer
    /// arrived (its clock, ns): how long ago the other side was heard.
    looked_at: Option<i64>,
    heard_at: Option<i64>,
    /// The samples' one-way trips on the common clock.
    one_way: TripHistogram,
    /// Injected faults on what this end sends (tests, experiments), if configured.
    faults: Option<FaultyLink<(Header, LinkDatagram)>>,
    /// Samples taken so far: the channel's sequence numbers (newest wins there too), which stay
    /// increasing when the other side restarts with a new session.
    taken: u64,
    /// Datagrams from an address other than the peer's, dropped.
    strangers: u64,
    /// The link is lost (the other side silent past the timeout), and how often it was lost
    /// and came back: safety transitions, counted.
    down: bool,
    losses: u64,
    restorations: u64,
    /// Where the counters go for the channel object to show.
    stats: StatsWriter,
    /// Where every sample sent and taken goes, for a recorder (full: dropped and counted).
    tap: DatagramTap,
}

impl RemoteLink {
    /// Sends a datagram now, or through the injected faults (which release what is due at the
    /// tick's time `now`, the time their outage windows are measured in).
    fn emit(&mut self, now: i64, header: Header, datagram: LinkDatagram) {
        match &mut self.faults {
            None => {
                let _ = self.endpoint.send(&header, &datagram, self.peer);
            }
            Some(faults) => {
                let at = Duration::from_nanos(u64::try_from(now).unwrap_or(0));
                faults.send(at, (header, datagram));
                while let Some((h, d)) = faults.poll(at) {
                    let _ = self.endpoint.send(&h, &d, self.peer);
                }
            }
        }
    }

    /// The peer's newest sample among the datagrams waiting (at most [`RECEIVE_BURST`]), with
    /// heartbeats answered and answers taken into the link's clock on the way (see
    /// [`TeleopEnd::take_newest`]).
    fn take_newest(&mut self, now: Timestamp) -> Option<TeleopSample> {
        let mut newest = None;
        let tick = nanos(now);
        self.looked_at = Some(self.stamps.now(tick));
        for _ in 0..RECEIVE_BURST {
            let Some(Received {
                from,
                header,
                payload: datagram,
                kernel_realtime_ns,
            }) = self.endpoint.receive_stamped::<LinkDatagram>()
            else {
                break;
            };
            if from != self.peer {
                self.strangers += 1;
                continue;
            }
            // t2 of a heartbeat, t4 of an answer.
            let arrived = self.stamps.received(tick, kernel_realtime_ns);
            self.heard_at = Some(arrived);
            match datagram {
                LinkDatagram::Sample { .. } => {
                    if let Some(sample) = self.take_sample(now, &header, arrived, datagram) {
                        newest = Some(sample);
                    }
                }
                LinkDatagram::Heartbeat if header.stream == HEARTBEATS => {
                    // t3: read as the answer leaves.
                    let answer = self.heartbeats.next(self.stamps.now(tick));
                    let payload = LinkDatagram::Answer {
                        heartbeat: header.sequence,
                        received_ns: arrived,
                    };
                    self.emit(tick, answer, payload);
                }
                LinkDatagram::Answer {
                    heartbeat,
                    received_ns,
                } if header.stream == HEARTBEATS => {
                    // Refusals (unmatched, duplicate, impossible times) are counted by the
                    // clock and leave its estimate alone.
                    let _ = self
                        .clock
                        .note_answer(heartbeat, received_ns, header.sent_ns, arrived);
                }
                _ => {}
            }
        }
        newest
    }

    /// A sample datagram from the peer that `arrived` (this end's clock, ns), taken if it is
    /// newer than every one taken before: counted, its one-way trip recorded, tapped for a
    /// recorder, and returned with its send time on this node's clock. `None` for a sample the
    /// stream refuses (duplicate, late, of an old session or another stream) and for any other
    /// datagram.
    fn take_sample(
        &mut self,
        now: Timestamp,
        header: &Header,
        arrived: i64,
        datagram: LinkDatagram,
    ) -> Option<TeleopSample> {
        let LinkDatagram::Sample {
            clutch,
            reference,
            wave,
            energy,
            urgent,
        } = datagram
        else {
            return None;
        };
        if self.receiver.offer(header) != Verdict::Accepted {
            return None;
        }
        self.taken += 1;
        let sent_here = self
            .clock
            .from_common(header.sent_ns)
            .unwrap_or(header.sent_ns);
        self.one_way.record(arrived - sent_here);
        // The sender's time on this node's clock, once heartbeats know the offset (before
        // that, taken as is: one host, one clock).
        let sent = self.stamps.to_node(sent_here);
        if let Some(stream) = StreamName::of(header.stream) {
            let _ = self.tap.push(StreamDatagram {
                stream,
                time_ns: now.as_nanos(),
                sequence: header.sequence,
                sent_ns: header.sent_ns,
                arrived_ns: Some(self.stamps.to_node(arrived)),
                one_way_ns: Some(arrived - sent_here),
                clutch,
                reference,
                wave,
                energy,
            });
        }
        Some(TeleopSample {
            sequence: self.taken,
            sent: Timestamp::from_nanos(u64::try_from(sent).unwrap_or(0)),
            clutch,
            reference,
            port: PortPayload { wave, energy },
            urgent,
        })
    }
}

impl TeleopEnd {
    /// `side`'s end linked over the data plane: `endpoint` (bound on this node) exchanges
    /// samples with the other side's endpoint at `peer`, stamping times from `time`; what it
    /// sends goes through injected `faults` (with their seed) when given, its clock offset by
    /// theirs; its counters go to `stats`.
    fn remote(
        side: Side,
        mut endpoint: Endpoint,
        peer: SocketAddr,
        time: LinkTime,
        faults: Option<(&FaultConfig, u64)>,
        stats: StatsWriter,
        tap: DatagramTap,
    ) -> Result<Self, FaultConfigError> {
        let (out, inbound) = side.streams();
        let offset = faults.map_or(0, |(config, _)| config.clock_offset_ns());
        // Without the kernel's stamps an arrival is timed when the thread reads it: worse by
        // the wait for the next tick, but still the real clock.
        if time == LinkTime::Real
            && let Err(e) = endpoint.enable_receive_timestamps()
        {
            log::warn!("data plane: no kernel receive timestamps ({e}); reading the clock instead");
        }
        let faults = match faults {
            Some((config, seed)) => Some(FaultyLink::new(config, seed, FAULTY_CAPACITY)?),
            None => None,
        };
        Ok(TeleopEnd {
            side,
            transport: Transport::DataPlane(Box::new(RemoteLink {
                endpoint,
                peer,
                sender: StreamSender::new(out),
                receiver: StreamReceiver::new(inbound),
                heartbeats: StreamSender::new(HEARTBEATS),
                clock: LinkClock::new(),
                stamps: EndClock::new(time, offset),
                looked_at: None,
                heard_at: None,
                one_way: TripHistogram::default(),
                faults,
                taken: 0,
                strangers: 0,
                down: false,
                losses: 0,
                restorations: 0,
                stats,
                tap,
            })),
            sent: 0,
            doorbell: new_doorbell(),
            wake_peer: false,
        })
    }

    /// Rings the other end's doorbell (on cells) with every sample sent when `every`, not
    /// only with an urgent one: its thread hands each sample on as it comes (event-driven
    /// handoff). Over the data plane the datagram itself wakes the other thread.
    pub fn wake_peer_with_every_sample(&mut self, every: bool) {
        self.wake_peer = every;
    }

    /// The sequence number of the last sample sent.
    pub fn sent(&self) -> u64 {
        self.sent
    }

    /// Notes the sequence number of the last sample sent (when a loop gives the end back).
    pub fn set_sent(&mut self, sent: u64) {
        self.sent = sent;
    }

    /// Sends `sample` (taken at `sample.sent` on this node's clock) to the other side, and
    /// every [`HEARTBEAT_EVERY`] samples a heartbeat.
    ///
    /// # Real-time
    /// A cell write (on a channel with faults, through the delay line: a few random draws and
    /// bounded heap work in a queue made at configure time, no allocation), or one or two
    /// non-blocking `sendto` calls (a refusal is counted, not waited on).
    pub fn publish(&mut self, sample: TeleopSample) {
        let wake_peer = sample.urgent || self.wake_peer;
        match &mut self.transport {
            Transport::Cells {
                send,
                delay: None,
                peer,
                ..
            } => {
                send.write(sample);
                if wake_peer && let Some(peer) = peer {
                    peer.ring();
                }
            }
            Transport::Cells {
                send,
                delay: Some(line),
                ..
            } => line.send(sample, send),
            Transport::Bridged { send, .. } => send.write(sample),
            Transport::DataPlane(link) => {
                let tick = nanos(sample.sent);
                let header = link.sender.next(link.stamps.now(tick));
                let payload = LinkDatagram::Sample {
                    clutch: sample.clutch,
                    reference: sample.reference,
                    wave: sample.port.wave,
                    energy: sample.port.energy,
                    urgent: sample.urgent,
                };
                link.emit(tick, header, payload);
                if let Some(stream) = StreamName::of(header.stream) {
                    // A full ring (no recorder draining it) refuses and counts.
                    let _ = link.tap.push(StreamDatagram {
                        stream,
                        time_ns: sample.sent.as_nanos(),
                        sequence: header.sequence,
                        sent_ns: header.sent_ns,
                        arrived_ns: None,
                        one_way_ns: None,
                        clutch: sample.clutch,
                        reference: sample.reference,
                        wave: sample.port.wave,
                        energy: sample.port.energy,
                    });
                }
                if header.sequence % HEARTBEAT_EVERY == 1 {
                    // t1: read as it leaves.
                    let t1 = link.stamps.now(tick);
                    let beat = link.heartbeats.next(t1);
                    link.clock.note_sent(beat.sequence, t1);
                    link.emit(tick, beat, LinkDatagram::Heartbeat);
                }
            }
        }
    }

    /// The other side's newest sample since the last call, if one arrived, its send time on
    /// this node's clock; heartbeats are answered and answers taken into the link's clock.
    /// `now` is the communication tick's time: on a simulated clock the time of every arrival
    /// (to within a communication period); on real time the kernel stamps arrivals.
    ///
    /// # Real-time
    /// A cell read, or at most [`RECEIVE_BURST`] non-blocking `recvfrom` (or `recvmsg`) calls
    /// and as many answers.
    pub fn take_newest(&mut self, now: Timestamp) -> Option<TeleopSample> {
        match &mut self.transport {
            Transport::Cells { receive, .. } => match receive.read() {
                Fresh::New(s) => Some(s),
                _ => None,
            },
            Transport::Bridged { receive, .. } => match receive.read() {
                Fresh::New(s) => Some(TeleopSample { sent: now, ..s }),
                _ => None,
            },
            Transport::DataPlane(link) => link.take_newest(now),
        }
    }

    /// The doorbell that wakes the communication thread holding this end (its loop rings it
    /// on a new safety event).
    pub fn doorbell(&self) -> Option<Arc<Doorbell>> {
        self.doorbell.clone()
    }

    /// What wakes the communication thread holding this end before its period: the doorbell,
    /// and for an end on the data plane its socket (an urgent sample is read as it arrives).
    /// `None` without a doorbell (the thread then only ticks).
    ///
    /// # Errors
    /// The OS's, when the socket's descriptor cannot be duplicated for the wait.
    pub fn wake_on(&self) -> std::io::Result<Option<WakeOn>> {
        let Some(bell) = self.doorbell.clone() else {
            return Ok(None);
        };
        let wake = WakeOn::doorbell(bell);
        match &self.transport {
            Transport::DataPlane(link) => wake.and_readable(link.endpoint.as_fd()).map(Some),
            _ => Ok(Some(wake)),
        }
    }

    /// Whether the other end is on another node.
    pub fn is_remote(&self) -> bool {
        matches!(self.transport, Transport::DataPlane(_))
    }

    /// Notes that the link is lost (`true`) or back (`false`); a change is counted, and
    /// returned (`true`: this call changed it, a safety event for the loop).
    pub fn note_link(&mut self, lost: bool) -> bool {
        if let Transport::DataPlane(link) = &mut self.transport
            && link.down != lost
        {
            link.down = lost;
            if lost {
                link.losses += 1;
            } else {
                link.restorations += 1;
            }
            return true;
        }
        false
    }

    /// Publishes the link's counters for the channel object (each communication tick).
    ///
    /// # Real-time
    /// One wait-free cell write.
    pub fn publish_stats(&mut self) {
        if let Some(stats) = self.link_stats()
            && let Transport::DataPlane(link) = &mut self.transport
        {
            link.stats.write(stats);
        }
    }

    /// The data-plane link's counters (`None` for an end on cells).
    pub fn link_stats(&self) -> Option<ChannelLinkStats> {
        match &self.transport {
            Transport::Cells { .. } | Transport::Bridged { .. } => None,
            Transport::DataPlane(link) => Some(ChannelLinkStats {
                down: link.down,
                losses: link.losses,
                restorations: link.restorations,
                endpoint: link.endpoint.stats(),
                stream: link.receiver.stats(),
                strangers: link.strangers,
                clock_offset_ns: link.clock.offset(),
                round_trip_ns: link.clock.delay(),
                one_way_delay_ns: link.clock.one_way_delay(),
                one_way: link.one_way,
                jitter_ns: link.clock.jitter(),
                last_heard_ns: match (link.looked_at, link.heard_at) {
                    (Some(looked), Some(heard)) => Some(looked.saturating_sub(heard).max(0)),
                    _ => None,
                },
                heartbeat_loss: link.clock.loss_ratio(),
                faults: link.faults.as_ref().map(FaultyLink::counters),
            }),
        }
    }
}

/// A time as signed nanoseconds (the data plane's clock values).
fn nanos(t: Timestamp) -> i64 {
    i64::try_from(t.as_nanos()).unwrap_or(i64::MAX)
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
    /// The counters of this node's end's link to another node, if it has one.
    stats: Option<LinkSource>,
}

impl TeleopLink {
    /// Both ends on this node, joined by new cells.
    pub fn new() -> Self {
        Self::joined(None, None)
    }

    /// Both ends on this node, joined by new cells through a seeded delay line each way: the
    /// faults of `faults` (delay, jitter, loss, duplication, reordering, outages), drawn from
    /// `seed` in both directions, as two nodes given the same channel configuration draw
    /// them (each end's own sends from the same seed).
    ///
    /// # Errors
    /// [`FaultConfigError`] for a fault configuration out of range.
    pub fn delayed(faults: &FaultConfig, seed: u64) -> Result<Self, FaultConfigError> {
        Ok(Self::joined(
            Some(Box::new(DelayLine::new(faults, seed)?)),
            Some(Box::new(DelayLine::new(faults, seed)?)),
        ))
    }

    /// Both ends on this node, each direction through its delay line if given.
    fn joined(to_slave: Option<Box<DelayLine>>, to_master: Option<Box<DelayLine>>) -> Self {
        let (m2s_w, m2s_r) = latest::<TeleopSample>();
        let (s2m_w, s2m_r) = latest::<TeleopSample>();
        let (master_bell, slave_bell) = (new_doorbell(), new_doorbell());
        TeleopLink {
            master: Some(TeleopEnd {
                side: Side::Master,
                transport: Transport::Cells {
                    send: m2s_w,
                    receive: s2m_r,
                    delay: to_slave,
                    peer: slave_bell.clone(),
                },
                sent: 0,
                doorbell: master_bell.clone(),
                wake_peer: false,
            }),
            slave: Some(TeleopEnd {
                side: Side::Slave,
                transport: Transport::Cells {
                    send: s2m_w,
                    receive: m2s_r,
                    delay: to_master,
                    peer: master_bell,
                },
                sent: 0,
                doorbell: slave_bell,
                wake_peer: false,
            }),
            local: (true, true),
            stats: None,
        }
    }

    /// Only `side`'s end on this node, linked over the data plane: `endpoint` (bound on this
    /// node) exchanges samples with the other side's endpoint at `peer`, stamping times from
    /// `time` (the tick's on a simulated clock, the real clock's on real time), through
    /// injected `faults` (with their seed) when given; the other side's end is on another node.
    ///
    /// # Errors
    /// [`FaultConfigError`] for a fault configuration out of range.
    pub fn remote(
        side: Side,
        endpoint: Endpoint,
        peer: SocketAddr,
        time: LinkTime,
        faults: Option<(&FaultConfig, u64)>,
    ) -> Result<Self, FaultConfigError> {
        let (writer, reader) = latest();
        let (tap, datagrams) = penelope_rt_core::ring::ring();
        let mut link = TeleopLink {
            master: None,
            slave: None,
            local: (side == Side::Master, side == Side::Slave),
            stats: Some(LinkSource::new(reader, datagrams)),
        };
        link.put_back(TeleopEnd::remote(
            side, endpoint, peer, time, faults, writer, tap,
        )?);
        Ok(link)
    }

    /// Only `side`'s end on this node, its other end outside Penelope behind a bridge: the
    /// returned [`BridgedEnd`] is the bridge's (it writes what it takes, the loop reads it at
    /// its next communication tick, as from the data plane).
    pub fn bridged(side: Side) -> (Self, BridgedEnd) {
        let (to_loop, receive) = latest::<TeleopSample>();
        let (send, from_loop) = latest::<TeleopSample>();
        let mut link = TeleopLink {
            master: None,
            slave: None,
            local: (side == Side::Master, side == Side::Slave),
            stats: None,
        };
        link.put_back(TeleopEnd {
            side,
            transport: Transport::Bridged { send, receive },
            sent: 0,
            doorbell: new_doorbell(),
            wake_peer: false,
        });
        (link, BridgedEnd { to_loop, from_loop })
    }

    /// The newest counters of the link to another node (`None` for a channel on this node,
    /// or before its first communication tick).
    pub fn stats(&self) -> Option<ChannelLinkStats> {
        self.stats.as_ref()?.latest()
    }

    /// Where the newest counters of the link to another node can be read from elsewhere (a
    /// recorder, a telemetry pump): `None` for a channel on this node.
    pub fn stats_source(&self) -> Option<LinkSource> {
        self.stats.clone()
    }

    /// Whether `side`'s end lives on this node.
    pub fn is_local(&self, side: Side) -> bool {
        match side {
            Side::Master => self.local.0,
            Side::Slave => self.local.1,
        }
    }

    /// The doorbell of `side`'s end, while it is here (its loop's control thread rings it).
    pub fn doorbell(&self, side: Side) -> Option<Arc<Doorbell>> {
        match side {
            Side::Master => self.master.as_ref(),
            Side::Slave => self.slave.as_ref(),
        }
        .and_then(TeleopEnd::doorbell)
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

#[cfg(test)]
#[path = "teleop_end_tests.rs"]
mod tests;
