//! The subscribers of a node's cameras: per subscriber a bounded queue that drops the oldest
//! frame when full (the camera thread never waits, nothing queues without bound), the camera's
//! link faults applied to each frame on its way, and the counts of what was sent, dropped and
//! lost. The camera thread hands each frame here; a subscriber's session takes it through its
//! [`FrameSink`] as its outbox has room.

use std::collections::VecDeque;
use std::sync::Mutex;
use std::time::Duration;

use penelope_protocol::proto::{CameraFrame, FrameBatch};

use crate::dataplane::faults::{FaultConfig, FaultyLink};
use crate::objects::error::ObjectError;

/// Where a camera subscription's frames go, without waiting.
pub trait FrameSink: Send + Sync + std::fmt::Debug {
    /// Hands over a batch; `false` when the sink is full or closed, or holds `in_flight_limit`
    /// of this subscription's batches not yet sent on (the batch is kept by the caller and
    /// offered again: the subscription's drop-oldest queue stays the bound end to end).
    fn frames(&self, batch: FrameBatch, in_flight_limit: usize) -> bool;
    /// Whether the other end has gone (the subscription ends).
    fn is_closed(&self) -> bool;
}

/// Frames a camera's link holds on their way to one subscriber (its faults' delay) before it
/// refuses more.
const LINK_CAPACITY: usize = 64;

/// What one subscription counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameSubscriberStats {
    /// Its id.
    pub id: u64,
    /// Frames handed to its session.
    pub sent: u64,
    /// Frames dropped, the oldest, from its full queue.
    pub dropped: u64,
    /// Frames lost on the camera's link (its faults).
    pub lost: u64,
    /// Frames in its queue now.
    pub queued: usize,
}

struct FrameSubscription {
    id: u64,
    session: u64,
    camera: String,
    decimation: u64,
    queue: VecDeque<CameraFrame>,
    capacity: usize,
    link: FaultyLink<CameraFrame>,
    sink: Box<dyn FrameSink>,
    stats: FrameSubscriberStats,
}

impl std::fmt::Debug for FrameSubscription {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameSubscription")
            .field("id", &self.id)
            .field("camera", &self.camera)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

impl FrameSubscription {
    /// Moves what the link released by `now_ns` into the queue (the oldest dropped when full),
    /// then hands the queue to the sink while it takes; `false` when the sink has gone.
    fn pump(&mut self, now_ns: u64, stamp: &dyn Fn() -> u64) -> bool {
        let now = Duration::from_nanos(now_ns);
        while let Some(frame) = self.link.poll(now) {
            if self.queue.len() >= self.capacity {
                self.queue.pop_front();
                self.stats.dropped += 1;
            }
            self.queue.push_back(frame);
        }
        let counters = self.link.counters();
        self.stats.lost =
            counters.dropped_loss + counters.dropped_outage + counters.dropped_capacity;
        while let Some(mut frame) = self.queue.pop_front() {
            frame.sent_ns = stamp();
            let batch = FrameBatch {
                subscription: self.id,
                dropped: self.stats.dropped + self.stats.lost,
                frames: vec![frame],
            };
            if self.sink.frames(batch.clone(), self.capacity) {
                self.stats.sent += 1;
                continue;
            }
            if self.sink.is_closed() {
                return false;
            }
            // Full: kept, first in line, for the next round.
            let mut back = batch.frames;
            if let Some(frame) = back.pop() {
                self.queue.push_front(frame);
            }
            break;
        }
        self.stats.queued = self.queue.len();
        true
    }
}

/// Every camera subscription of a creator.
#[derive(Debug, Default)]
pub struct FrameSubscriptions {
    list: Mutex<Vec<FrameSubscription>>,
}

/// A new subscription's settings.
#[derive(Clone, Debug)]
pub struct FrameSubscriptionSpec {
    /// The camera's name.
    pub camera: String,
    /// Its kind (`sensor/sim-camera`, `sensor/camera`), for errors.
    pub kind: String,
    /// One frame in `decimation` (by frame number).
    pub decimation: u32,
    /// Frames its queue holds.
    pub queue: usize,
    /// The camera's link's faults.
    pub link: FaultConfig,
    /// The faults' seed.
    pub seed: u64,
}

impl FrameSubscriptions {
    /// How many there are.
    pub fn len(&self) -> usize {
        self.list.lock().map(|l| l.len()).unwrap_or(0)
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// How many of them belong to a session `of` picks (and are open).
    pub fn count_of(&self, of: impl Fn(u64) -> bool) -> usize {
        self.list
            .lock()
            .map(|l| {
                l.iter()
                    .filter(|s| !s.sink.is_closed() && of(s.session))
                    .count()
            })
            .unwrap_or(0)
    }

    /// Drops the subscriptions whose session has gone.
    pub fn retain_open(&self) {
        if let Ok(mut l) = self.list.lock() {
            l.retain(|s| !s.sink.is_closed());
        }
    }

    /// Adds subscription `id` of `session`.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] for link faults that make no link (checked at configure, so
    /// not expected); [`ObjectError::Poisoned`].
    pub fn add(
        &self,
        id: u64,
        session: u64,
        spec: FrameSubscriptionSpec,
        sink: Box<dyn FrameSink>,
    ) -> Result<(), ObjectError> {
        // Each subscriber's link draws its own faults, from the camera's seed and its id.
        let link = FaultyLink::new(&spec.link, spec.seed ^ id, LINK_CAPACITY).map_err(|e| {
            ObjectError::BadConfig {
                kind: spec.kind.clone(),
                message: format!("link: {e}"),
            }
        })?;
        self.list
            .lock()
            .map_err(|_| ObjectError::Poisoned("camera subscriptions"))?
            .push(FrameSubscription {
                id,
                session,
                camera: spec.camera,
                decimation: u64::from(spec.decimation.max(1)),
                queue: VecDeque::with_capacity(spec.queue),
                capacity: spec.queue.max(1),
                link,
                sink,
                stats: FrameSubscriberStats {
                    id,
                    ..FrameSubscriberStats::default()
                },
            });
        Ok(())
    }

    /// Removes subscription `id` of `session`; false if there was none.
    pub fn remove(&self, session: u64, id: u64) -> bool {
        let Ok(mut l) = self.list.lock() else {
            return false;
        };
        let before = l.len();
        l.retain(|s| !(s.id == id && s.session == session));
        l.len() != before
    }

    /// Removes every subscription of `session`.
    pub fn remove_session(&self, session: u64) {
        if let Ok(mut l) = self.list.lock() {
            l.retain(|s| s.session != session);
        }
    }

    /// Ends every subscription to `camera` (cleaned up or destroyed).
    pub fn end_camera(&self, camera: &str) {
        if let Ok(mut l) = self.list.lock() {
            l.retain(|s| s.camera != camera);
        }
    }

    /// Offers `frame` of `camera` to its subscribers (one in each one's decimation) on their
    /// links at node time `now_ns`, then [`pump`](Self::pump)s them.
    pub fn publish(&self, camera: &str, frame: &CameraFrame, now_ns: u64, stamp: &dyn Fn() -> u64) {
        if let Ok(mut l) = self.list.lock() {
            for s in l.iter_mut().filter(|s| s.camera == camera) {
                if frame.seq.is_multiple_of(s.decimation) {
                    s.link.send(Duration::from_nanos(now_ns), frame.clone());
                }
            }
        }
        self.pump(camera, now_ns, stamp);
    }

    /// Moves `camera`'s frames along: out of the links (at node time `now_ns`) into the
    /// queues, out of the queues to the sinks that take them (`stamp`: the send time, common
    /// clock). A subscription whose session has gone ends.
    pub fn pump(&self, camera: &str, now_ns: u64, stamp: &dyn Fn() -> u64) {
        if let Ok(mut l) = self.list.lock() {
            l.retain_mut(|s| s.camera != camera || s.pump(now_ns, stamp));
        }
    }

    /// When the next of `camera`'s frames held by a link's delay is due, node time (`None`:
    /// none is held): how long a camera thread may sleep before it pumps again.
    pub fn next_release(&self, camera: &str) -> Option<Duration> {
        self.list.lock().ok().and_then(|l| {
            l.iter()
                .filter(|s| s.camera == camera)
                .filter_map(|s| s.link.next_release())
                .min()
        })
    }

    /// The counts of `camera`'s subscriptions.
    pub fn stats_of(&self, camera: &str) -> Vec<FrameSubscriberStats> {
        self.list
            .lock()
            .map(|l| {
                l.iter()
                    .filter(|s| s.camera == camera)
                    .map(|s| s.stats)
                    .collect()
            })
            .unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_protocol::proto::{CameraModelMsg, ImageEncoding};
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};

    /// A sink that takes frames only while `open`, and keeps them.
    #[derive(Debug, Default)]
    struct Reader {
        open: AtomicBool,
        got: Mutex<Vec<u64>>,
    }

    #[derive(Debug)]
    struct Shared(Arc<Reader>);

    impl FrameSink for Shared {
        fn frames(&self, batch: FrameBatch, _in_flight_limit: usize) -> bool {
            if !self.0.open.load(Ordering::Relaxed) {
                return false;
            }
            let mut got = self.0.got.lock().unwrap();
            got.extend(batch.frames.iter().map(|f| f.seq));
            true
        }
        fn is_closed(&self) -> bool {
            false
        }
    }

    fn frame(seq: u64) -> CameraFrame {
        CameraFrame {
            seq,
            capture_ns: seq * 1000,
            ready_ns: seq * 1000 + 10,
            sent_ns: 0,
            encoding: ImageEncoding::Jpeg,
            data: vec![seq as u8; 8],
            model: CameraModelMsg {
                frame_id: "cam".into(),
                width: 1,
                height: 1,
                fx: 1.0,
                fy: 1.0,
                cx: 0.5,
                cy: 0.5,
                pose_in_robot_base: None,
                robot: None,
            },
        }
    }

    fn spec(queue: usize, link: FaultConfig) -> FrameSubscriptionSpec {
        FrameSubscriptionSpec {
            kind: "sensor/sim-camera".into(),
            camera: "cam".into(),
            decimation: 1,
            queue,
            link,
            seed: 7,
        }
    }

    #[test]
    fn a_subscriber_that_never_reads_holds_the_newest_frames_up_to_its_queue() {
        let subs = FrameSubscriptions::default();
        let reader = Arc::new(Reader::default());
        subs.add(
            1,
            1,
            spec(4, FaultConfig::default()),
            Box::new(Shared(reader.clone())),
        )
        .unwrap();
        for seq in 0..100 {
            subs.publish("cam", &frame(seq), seq * 1000, &|| 5);
            let stats = subs.stats_of("cam")[0];
            assert!(stats.queued <= 4, "{stats:?}");
        }
        let stats = subs.stats_of("cam")[0];
        println!("after 100 frames unread: {stats:?}");
        assert_eq!((stats.queued, stats.dropped, stats.sent), (4, 96, 0));
        reader.open.store(true, Ordering::Relaxed);
        subs.pump("cam", 100_000, &|| 5);
        assert_eq!(*reader.got.lock().unwrap(), vec![96, 97, 98, 99]);
        assert_eq!(subs.stats_of("cam")[0].sent, 4);
    }

    #[test]
    fn the_links_faults_delay_and_lose_frames_and_are_counted() {
        let subs = FrameSubscriptions::default();
        let reader = Arc::new(Reader::default());
        reader.open.store(true, Ordering::Relaxed);
        let link = FaultConfig {
            delay_ms: 0.02,
            loss: 0.3,
            ..FaultConfig::default()
        };
        subs.add(1, 1, spec(64, link), Box::new(Shared(reader.clone())))
            .unwrap();
        // 10 µs apart, 20 µs of delay: each frame arrives two frames later.
        for seq in 0..200 {
            subs.publish("cam", &frame(seq), seq * 10_000, &|| 5);
        }
        subs.pump("cam", 10_000_000, &|| 5);
        let stats = subs.stats_of("cam")[0];
        let got = reader.got.lock().unwrap().clone();
        println!("lost {} of 200 at loss 0.3", stats.lost);
        assert_eq!(stats.sent as usize, got.len());
        assert_eq!(stats.lost + stats.sent, 200, "{stats:?}");
        assert!((30..=90).contains(&stats.lost), "{stats:?}");
        assert!(got.windows(2).all(|w| w[0] < w[1]), "in order: {got:?}");
    }
}
