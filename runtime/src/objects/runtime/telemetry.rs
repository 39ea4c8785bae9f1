//! Telemetry: the pump and the subscriptions (of controllers here; of channels' links in
//! `link_telemetry`).

use crate::objects::error::ObjectError;
use crate::objects::link_source::LinkSource;
use crate::objects::runtime::{FrameSink, FrameSubscriptionSpec, FrameSubscriptions};
use crate::objects::runtime::{LinkSubscriptions, TELEMETRY_CAPACITY};
use crate::objects::tick::{TickRecord, TickStream};
use penelope_hal::JointVector;
use penelope_protocol::proto::{
    LinkBatch, TelemetryBatch, TelemetryRecord, WrenchMsg, joints_from_vector,
};
use penelope_rt_core::exec::CommonOffset;
use penelope_rt_core::ring::ArcConsumer;
use penelope_rt_core::telemetry::TelemetrySample;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::SyncSender;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// The newest state of a running loop, as the pump keeps it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Newest {
    /// The newest sample.
    pub sample: TelemetrySample,
    /// Joint accelerations estimated from the two newest samples, rad/s².
    pub acceleration: JointVector,
}

/// What a running loop shares with the non-real-time side.
#[derive(Debug, Default)]
pub struct LoopShared {
    /// The newest sample.
    pub newest: Mutex<Option<Newest>>,
    /// Samples the telemetry ring dropped.
    pub dropped: AtomicU64,
    /// Samples drained.
    pub drained: AtomicU64,
}

impl LoopShared {
    /// The newest sample.
    pub fn newest(&self) -> Option<Newest> {
        self.newest.lock().ok().and_then(|g| *g)
    }
}

/// Where a subscription's batches go, without waiting: the pump writes ticks (and the link pump
/// link statistics) to it; the implementation decides what they become. A client session's
/// `Outbox` (the service boundary, in [`objects`](crate::objects)) turns them into the protocol's `ServerMsg::Telemetry` and `ServerMsg::Link`
/// messages; an in-process subscriber could take them as they are.
pub trait TickSink: Send + Sync + std::fmt::Debug {
    /// Hands over a batch of ticks; `false` when the sink is full or closed (the batch is lost).
    fn ticks(&self, batch: TelemetryBatch) -> bool;
    /// Hands over a batch of link statistics; `false` when full or closed (lost).
    fn links(&self, batch: LinkBatch) -> bool;
    /// Whether the other end has gone (its subscriptions end).
    fn is_closed(&self) -> bool;
}

/// The most records in one telemetry batch: a record is a few hundred bytes (at most about a
/// kilobyte with a long fault text), so a batch stays well inside the default 256 KiB frame.
pub const MAX_BATCH_RECORDS: usize = 128;

/// One telemetry subscription.
#[derive(Debug)]
struct Subscription {
    id: u64,
    session: u64,
    controller: String,
    decimation: u64,
    sink: Box<dyn TickSink>,
    dropped: u64,
}

/// Every subscription of a creator (non-real-time side only): to controllers' ticks, and to
/// channels' links (one id space, one limit).
#[derive(Debug, Default)]
pub struct Subscriptions {
    list: Mutex<Vec<Subscription>>,
    links: LinkSubscriptions,
    next: AtomicU64,
    recorders: Mutex<Vec<Recorder>>,
    /// The cameras' subscriptions (one id space and one limit with the others).
    frames: FrameSubscriptions,
    /// The robot each running controller drives (a camera follows its robot's ticks).
    drives: Mutex<std::collections::HashMap<String, String>>,
    /// The address of each session that subscribed (for the quota per address).
    peers: Mutex<std::collections::HashMap<u64, std::net::IpAddr>>,
    /// The node's common-clock offset, sent with every batch.
    common_offset: Arc<CommonOffset>,
}

/// Whose ticks a recorder takes.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Watched {
    Controller(String),
    Robot(String),
}

/// An in-process consumer of every tick of one controller (not decimated), with the plant's
/// truth: what a run's report and files are made of.
#[derive(Debug)]
struct Recorder {
    /// Whose ticks: a controller's, or whichever controller drives a robot.
    of: Watched,
    to: SyncSender<TickRecord>,
    dropped: Arc<AtomicU64>,
}

impl Subscriptions {
    /// No subscriptions yet; batches carry the offset in `common_offset` (the node's common
    /// clock's cell).
    pub fn on_common_clock(common_offset: Arc<CommonOffset>) -> Self {
        Subscriptions {
            common_offset,
            ..Subscriptions::default()
        }
    }

    /// How many there are (of controllers and of links).
    pub fn len(&self) -> usize {
        self.list.lock().map(|l| l.len()).unwrap_or(0) + self.links.len() + self.frames.len()
    }

    /// The subscriptions to cameras' frames.
    pub fn frames(&self) -> &FrameSubscriptions {
        &self.frames
    }

    /// Notes that controller `controller`'s loop drives `robot` (a camera watching `robot`
    /// then takes its ticks).
    pub fn set_driver(&self, controller: &str, robot: &str) {
        if let Ok(mut d) = self.drives.lock() {
            d.insert(controller.to_string(), robot.to_string());
        }
    }

    /// The subscriptions to channels' links.
    pub fn links(&self) -> &LinkSubscriptions {
        &self.links
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Room for one more subscription (at most `limit` in all, closed sessions' dropped first):
    /// the controllers' list, held so that two adds cannot both pass the limit, and the new id.
    fn admit(&self, limit: u32) -> Result<(MutexGuard<'_, Vec<Subscription>>, u64), ObjectError> {
        let mut list = self
            .list
            .lock()
            .map_err(|_| ObjectError::Poisoned("subscriptions"))?;
        list.retain(|s| !s.sink.is_closed());
        self.links.retain_open();
        self.frames.retain_open();
        if list.len() + self.links.len() + self.frames.len() >= limit as usize {
            return Err(ObjectError::LimitReached {
                what: "subscriptions".into(),
                limit,
            });
        }
        Ok((list, self.next.fetch_add(1, Ordering::Relaxed) + 1))
    }

    /// Adds one to `controller`'s ticks (at most `limit` subscriptions in all), returning its
    /// id.
    ///
    /// # Errors
    /// [`ObjectError::LimitReached`].
    pub fn add(
        &self,
        session: u64,
        controller: &str,
        decimation: u32,
        sink: Box<dyn TickSink>,
        limit: u32,
    ) -> Result<u64, ObjectError> {
        let (mut list, id) = self.admit(limit)?;
        list.push(Subscription {
            id,
            session,
            controller: controller.to_string(),
            decimation: u64::from(decimation.max(1)),
            sink,
            dropped: 0,
        });
        Ok(id)
    }

    /// Adds one to `channel`'s link, read from `source` (at most `limit` subscriptions in
    /// all), returning its id: a record every [`LINK_PERIOD`](crate::objects::runtime::LINK_PERIOD) times `decimation`.
    ///
    /// # Errors
    /// [`ObjectError::LimitReached`].
    pub fn add_link(
        &self,
        session: u64,
        channel: &str,
        source: LinkSource,
        decimation: u32,
        sink: Box<dyn TickSink>,
        limit: u32,
    ) -> Result<u64, ObjectError> {
        // The controllers' list stays held until the link is added (see `admit`).
        let (_held, id) = self.admit(limit)?;
        self.links
            .add(id, session, channel, source, decimation, sink)?;
        Ok(id)
    }

    /// Adds one to a camera's frames (at most `limit` subscriptions in all), returning its id.
    ///
    /// # Errors
    /// [`ObjectError::LimitReached`].
    pub fn add_frames(
        &self,
        session: u64,
        spec: FrameSubscriptionSpec,
        sink: Box<dyn FrameSink>,
        limit: u32,
    ) -> Result<u64, ObjectError> {
        let (_held, id) = self.admit(limit)?;
        self.frames.add(id, session, spec, sink)?;
        Ok(id)
    }

    /// Removes subscription `id` of `session`; false if there was none.
    pub fn remove(&self, session: u64, id: u64) -> bool {
        let Ok(mut list) = self.list.lock() else {
            return false;
        };
        let before = list.len();
        list.retain(|s| !(s.id == id && s.session == session));
        list.len() != before || self.links.remove(session, id) || self.frames.remove(session, id)
    }

    /// Removes every subscription of `session`.
    pub fn remove_session(&self, session: u64) {
        if let Ok(mut list) = self.list.lock() {
            list.retain(|s| s.session != session);
        }
        self.links.remove_session(session);
        self.frames.remove_session(session);
        if let Ok(mut peers) = self.peers.lock() {
            peers.remove(&session);
        }
    }

    /// Whether `session`, from `peer`, may add a subscription: the sessions of one address
    /// hold at most `quota` (so that one client cannot take the whole pool; the pool's own
    /// limit is checked by the add).
    ///
    /// # Errors
    /// [`ObjectError::LimitReached`] at the quota.
    pub fn check_peer_quota(
        &self,
        session: u64,
        peer: std::net::IpAddr,
        quota: u32,
    ) -> Result<(), ObjectError> {
        let same: Vec<u64> = {
            let mut peers = self
                .peers
                .lock()
                .map_err(|_| ObjectError::Poisoned("subscriptions"))?;
            peers.insert(session, peer);
            peers
                .iter()
                .filter(|(_, p)| **p == peer)
                .map(|(s, _)| *s)
                .collect()
        };
        let held = self
            .list
            .lock()
            .map(|l| {
                l.iter()
                    .filter(|s| !s.sink.is_closed() && same.contains(&s.session))
                    .count()
            })
            .unwrap_or(0)
            + self.links.count_of(|s| same.contains(&s))
            + self.frames.count_of(|s| same.contains(&s));
        if held >= quota as usize {
            return Err(ObjectError::LimitReached {
                what: format!("subscriptions of one address ({peer})").into(),
                limit: quota,
            });
        }
        Ok(())
    }

    /// Records every tick of `controller` from now on into a stream holding up to `capacity`
    /// ticks; a reader that falls behind loses ticks (counted), never the loop.
    pub fn record(&self, controller: &str, capacity: usize) -> TickStream {
        self.record_of(Watched::Controller(controller.to_string()), capacity)
    }

    /// Records every tick of whichever controller drives `robot` ([`set_driver`](Self::set_driver)),
    /// across controller switches, as [`record`](Self::record) does.
    pub fn record_robot(&self, robot: &str, capacity: usize) -> TickStream {
        self.record_of(Watched::Robot(robot.to_string()), capacity)
    }

    fn record_of(&self, of: Watched, capacity: usize) -> TickStream {
        let (to, ticks) = std::sync::mpsc::sync_channel(capacity.max(1));
        let dropped = Arc::new(AtomicU64::new(0));
        if let Ok(mut r) = self.recorders.lock() {
            r.push(Recorder {
                of,
                to,
                dropped: dropped.clone(),
            });
        }
        TickStream { ticks, dropped }
    }

    /// Sends `ticks` of `controller` to its recorders (every tick) and its subscribers
    /// (decimated), without waiting: a full outbox loses the batch (counted), a closed one ends
    /// the subscription.
    pub fn publish(&self, controller: &str, ticks: &[TickRecord], joints: usize) {
        if ticks.is_empty() {
            return;
        }
        let robot = self
            .drives
            .lock()
            .ok()
            .and_then(|d| d.get(controller).cloned());
        if let Ok(mut recorders) = self.recorders.lock() {
            recorders.retain(|r| {
                let mine = match &r.of {
                    Watched::Controller(c) => c == controller,
                    Watched::Robot(name) => robot.as_ref() == Some(name),
                };
                if !mine {
                    return true;
                }
                for t in ticks {
                    match r.to.try_send(*t) {
                        Ok(()) => {}
                        Err(std::sync::mpsc::TrySendError::Full(_)) => {
                            r.dropped.fetch_add(1, Ordering::Relaxed);
                        }
                        Err(std::sync::mpsc::TrySendError::Disconnected(_)) => return false,
                    }
                }
                true
            });
        }
        let Ok(mut list) = self.list.lock() else {
            return;
        };
        list.retain_mut(|s| {
            if s.controller != controller {
                return true;
            }
            let records: Vec<TelemetryRecord> = ticks
                .iter()
                .filter(|x| x.sample.seq % s.decimation == 0)
                .map(|x| record(&x.sample, x.clutch, joints))
                .collect();
            // A pump that was held up drains up to a ring's worth at once: in batches that fit
            // a frame, or the writer would refuse the whole of it.
            for samples in records.chunks(MAX_BATCH_RECORDS) {
                let batch = TelemetryBatch {
                    subscription: s.id,
                    dropped: s.dropped,
                    samples: samples.to_vec(),
                    common_offset_ns: self.common_offset.get(),
                };
                if s.sink.ticks(batch) {
                    continue;
                }
                if s.sink.is_closed() {
                    return false;
                }
                s.dropped += 1;
            }
            true
        });
    }
}

/// A sample as a client sees it.
pub fn record(s: &TelemetrySample, clutch: Option<bool>, joints: usize) -> TelemetryRecord {
    TelemetryRecord {
        time_ns: s.time.as_nanos(),
        seq: s.seq,
        q: joints_from_vector(&s.q, joints),
        qd: joints_from_vector(&s.qd, joints),
        effort: joints_from_vector(&s.effort, joints),
        tool_position: [s.tool_position.x, s.tool_position.y, s.tool_position.z],
        wrench: WrenchMsg::from(&s.wrench),
        state: s.state.as_str().to_string(),
        fault: s.fault.map(|f| f.to_string()),
        commanded_wrench: WrenchMsg::from(&s.commanded_wrench),
        clutch,
        port_energy: s.port_energy,
        channel_energy: s.channel_energy,
    }
}

/// What drains a loop's telemetry ring: keeps the newest sample in the loop's shared state and
/// fans every tick out to recorders and subscribers. Run by a thread ([`run_pump`]) on the real
/// clock, and after every step on a simulated one.
pub struct Pump {
    ring: ArcConsumer<TickRecord, TELEMETRY_CAPACITY>,
    shared: Arc<LoopShared>,
    subscriptions: Arc<Subscriptions>,
    controller: String,
    joints: usize,
    batch: Vec<TickRecord>,
    previous: Option<TelemetrySample>,
}

impl Pump {
    /// A pump of `controller`'s ring.
    pub fn new(
        ring: ArcConsumer<TickRecord, TELEMETRY_CAPACITY>,
        shared: Arc<LoopShared>,
        subscriptions: Arc<Subscriptions>,
        controller: &str,
        joints: usize,
    ) -> Self {
        let previous = shared.newest().map(|n| n.sample);
        Pump {
            ring,
            shared,
            subscriptions,
            controller: controller.to_string(),
            joints,
            batch: Vec::with_capacity(TELEMETRY_CAPACITY),
            previous,
        }
    }

    /// Takes every tick out of the ring and passes it on.
    pub fn drain(&mut self) {
        self.batch.clear();
        while let Some(s) = self.ring.pop() {
            self.batch.push(s);
        }
        let shared = &self.shared;
        shared
            .dropped
            .store(self.ring.dropped() as u64, Ordering::Relaxed);
        shared
            .drained
            .fetch_add(self.batch.len() as u64, Ordering::Relaxed);
        if let Some(last) = self.batch.last().map(|t| t.sample) {
            let before = (self.batch.len().checked_sub(2))
                .map(|i| self.batch[i].sample)
                .or(self.previous);
            let acceleration = match before {
                Some(b) if last.time > b.time => {
                    (last.qd - b.qd) / (last.time - b.time).as_secs_f64()
                }
                _ => JointVector::zeros(),
            };
            if let Ok(mut g) = shared.newest.lock() {
                *g = Some(Newest {
                    sample: last,
                    acceleration,
                });
            }
            self.previous = Some(last);
        }
        self.subscriptions
            .publish(&self.controller, &self.batch, self.joints);
    }
}

/// Runs `pump` until `stop` (then drains once more), every `period`.
pub fn run_pump(pump: &mut Pump, period: Duration, stop: &AtomicBool) {
    loop {
        let last_round = stop.load(Ordering::Acquire);
        if !last_round {
            std::thread::sleep(period);
        }
        pump.drain();
        if last_round {
            break;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_protocol::proto::ServerMsg;
    use penelope_protocol::service::Outbox;

    #[test]
    fn a_robots_stream_follows_whichever_controller_drives_it() {
        let subs = Subscriptions::default();
        let stream = subs.record_robot("puma", 64);
        let tick = |seq: u64| {
            let mut t = TickRecord::default();
            t.sample.seq = seq;
            t
        };
        subs.set_driver("follow", "puma");
        subs.set_driver("other", "frhc");
        subs.publish("follow", &[tick(1), tick(2)], 6);
        subs.publish("other", &[tick(100)], 6);
        // The slave's law switched: another controller now drives the same robot.
        subs.set_driver("wave-follow", "puma");
        subs.publish("wave-follow", &[tick(3)], 6);
        subs.publish("unbound", &[tick(200)], 6);
        let mut got = Vec::new();
        stream.drain_into(&mut got);
        let seqs: Vec<u64> = got.iter().map(|t| t.sample.seq).collect();
        assert_eq!(seqs, [1, 2, 3]);
    }

    #[test]
    fn a_backlog_goes_out_in_batches_that_fit_a_frame_none_lost() {
        let subs = Subscriptions::default();
        let (outbox, rx) = Outbox::bounded(256);
        let id = subs.add(1, "follow", 1, Box::new(outbox), 8).unwrap();
        // A held-up pump's drain: a ring's worth of ticks at once.
        let ticks: Vec<TickRecord> = (1..=4096u64)
            .map(|seq| {
                let mut t = TickRecord::default();
                t.sample.seq = seq;
                t.sample.fault = Some(penelope_rt_core::safety::FaultCause::ReferenceTimeout);
                t
            })
            .collect();
        subs.publish("follow", &ticks, 6);
        let mut seqs = Vec::new();
        while let Ok(ServerMsg::Telemetry(b)) = rx.rx.try_recv() {
            assert_eq!((b.subscription, b.dropped), (id, 0));
            assert!(b.samples.len() <= MAX_BATCH_RECORDS);
            let frame = postcard::to_allocvec(&ServerMsg::Telemetry(b.clone())).unwrap();
            assert!(
                frame.len() <= penelope_protocol::proto::DEFAULT_MAX_FRAME,
                "{}",
                frame.len()
            );
            seqs.extend(b.samples.iter().map(|r| r.seq));
        }
        assert_eq!(seqs, (1..=4096).collect::<Vec<_>>());
    }

    #[test]
    fn every_batch_carries_the_nodes_common_clock_offset_as_it_is_now() {
        let offset = Arc::new(CommonOffset::new(-3_700));
        let subs = Subscriptions::on_common_clock(offset.clone());
        let (outbox, rx) = Outbox::bounded(16);
        subs.add(1, "follow", 1, Box::new(outbox), 8).unwrap();
        let mut tick = TickRecord::default();
        tick.sample.seq = 1;
        tick.sample.time = penelope_hal::Timestamp::from_nanos(10_000);
        subs.publish("follow", &[tick], 6);
        offset.set(52_000);
        tick.sample.seq = 2;
        subs.publish("follow", &[tick], 6);
        let mut common = Vec::new();
        while let Ok(ServerMsg::Telemetry(b)) = rx.rx.try_recv() {
            common.extend(b.samples.iter().map(|r| b.to_common(r.time_ns)));
        }
        assert_eq!(common, vec![6_300, 62_000]);
    }
}
