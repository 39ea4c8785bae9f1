//! Link telemetry: the statistics of a channel's data-plane link, pushed to its subscribers
//! every [`LINK_PERIOD`] (times their decimation), to each subscription's [`TickSink`].
//!
//! The statistics are read through the channel's [`LinkSource`] (the communication thread
//! writes them into a wait-free cell each tick; the source locks, so it is read here, never in
//! a real-time thread). On the real clock a [`LinkPump`] thread publishes; on a simulated clock
//! the creator publishes after each advance, at the simulated time, so records follow the
//! clock that moves the links.

use std::sync::mpsc::{RecvTimeoutError, SyncSender};
use std::thread::JoinHandle;

use crate::objects::Subscriptions;
use crate::objects::error::ObjectError;
use crate::objects::link_source::LinkSource;
use crate::objects::runtime::TickSink;
use penelope_protocol::proto::LinkBatch;
use penelope_rt_core::clock::MonotonicClock;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// How often a link subscription of decimation 1 gets a record.
pub const LINK_PERIOD: Duration = Duration::from_millis(100);

/// One subscription to a channel's link.
struct LinkSubscription {
    id: u64,
    session: u64,
    channel: String,
    source: LinkSource,
    /// Between two records, ns: [`LINK_PERIOD`] times the decimation.
    every_ns: u64,
    /// When the next record is due, ns on the creator's clock (`None`: at the next round).
    next_ns: Option<u64>,
    sink: Box<dyn TickSink>,
    dropped: u64,
}

/// Every link subscription of a creator (non-real-time side only); part of [`Subscriptions`],
/// which gives them their ids and counts them against its limit.
#[derive(Default)]
pub struct LinkSubscriptions {
    list: Mutex<Vec<LinkSubscription>>,
}

impl std::fmt::Debug for LinkSubscriptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LinkSubscriptions")
            .field("len", &self.len())
            .finish()
    }
}

impl LinkSubscriptions {
    /// How many there are.
    pub fn len(&self) -> usize {
        self.list.lock().map(|l| l.len()).unwrap_or(0)
    }

    /// How many belong to a session for which `of` holds.
    pub fn count_of(&self, of: impl Fn(u64) -> bool) -> usize {
        self.list
            .lock()
            .map(|l| l.iter().filter(|s| of(s.session)).count())
            .unwrap_or(0)
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Adds subscription `id` of `session` to `channel`'s link, read from `source`.
    pub(super) fn add(
        &self,
        id: u64,
        session: u64,
        channel: &str,
        source: LinkSource,
        decimation: u32,
        sink: Box<dyn TickSink>,
    ) -> Result<(), ObjectError> {
        let every = LINK_PERIOD.saturating_mul(decimation.max(1));
        let mut list = self
            .list
            .lock()
            .map_err(|_| ObjectError::Poisoned("link subscriptions"))?;
        list.push(LinkSubscription {
            id,
            session,
            channel: channel.to_string(),
            source,
            every_ns: u64::try_from(every.as_nanos()).unwrap_or(u64::MAX),
            next_ns: None,
            sink,
            dropped: 0,
        });
        Ok(())
    }

    /// Drops the subscriptions whose connection closed.
    pub(super) fn retain_open(&self) {
        if let Ok(mut list) = self.list.lock() {
            list.retain(|s| !s.sink.is_closed());
        }
    }

    /// Removes subscription `id` of `session`; false if there was none.
    pub(super) fn remove(&self, session: u64, id: u64) -> bool {
        let Ok(mut list) = self.list.lock() else {
            return false;
        };
        let before = list.len();
        list.retain(|s| !(s.id == id && s.session == session));
        list.len() != before
    }

    /// Removes every subscription of `session`.
    pub(super) fn remove_session(&self, session: u64) {
        if let Ok(mut list) = self.list.lock() {
            list.retain(|s| s.session != session);
        }
    }

    /// Ends the subscriptions to `channel` unless they read its link `current` (the channel
    /// was destroyed, cleaned up or configured anew: their link is gone).
    pub fn end_stale(&self, channel: &str, current: Option<&LinkSource>) {
        if let Ok(mut list) = self.list.lock() {
            list.retain(|s| {
                s.channel != channel || current.is_some_and(|c| c.same_link(&s.source))
            });
        }
    }

    /// Sends each subscription whose record is due at `now_ns` (the creator's clock) its
    /// link's newest statistics, without waiting: a full outbox loses the batch (counted in
    /// the next one's `dropped`), a closed one ends the subscription. A link not yet ticked
    /// has nothing to send.
    pub fn publish(&self, now_ns: u64) {
        let Ok(mut list) = self.list.lock() else {
            return;
        };
        list.retain_mut(|s| {
            if s.next_ns.is_some_and(|due| now_ns < due) {
                return true;
            }
            // Keep the cadence of the first record unless the publisher fell a period behind.
            s.next_ns = Some(match s.next_ns {
                Some(due) if due.saturating_add(s.every_ns) > now_ns => due + s.every_ns,
                _ => now_ns.saturating_add(s.every_ns),
            });
            let Some(stats) = s.source.latest() else {
                return !s.sink.is_closed();
            };
            let batch = LinkBatch {
                subscription: s.id,
                dropped: s.dropped,
                records: vec![stats.record(now_ns)],
            };
            if s.sink.links(batch) {
                true
            } else if s.sink.is_closed() {
                false
            } else {
                s.dropped += 1;
                true
            }
        });
    }
}

/// The thread that publishes link records on the real clock, every [`LINK_PERIOD`]; stopped
/// and joined when dropped.
pub struct LinkPump {
    stop: Option<SyncSender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for LinkPump {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LinkPump").finish_non_exhaustive()
    }
}

impl LinkPump {
    /// Starts publishing the link subscriptions of `subscriptions` at the monotonic clock's
    /// time (normal priority).
    ///
    /// # Errors
    /// The system's refusal to start a thread.
    pub fn start(subscriptions: Arc<Subscriptions>) -> std::io::Result<LinkPump> {
        let (stop, stopped) = std::sync::mpsc::sync_channel::<()>(1);
        let thread = std::thread::Builder::new()
            .name("link-telemetry".into())
            .spawn(move || {
                // The sender's drop (or a message) ends the thread at once, not after a period.
                while let Err(RecvTimeoutError::Timeout) = stopped.recv_timeout(LINK_PERIOD) {
                    subscriptions
                        .links()
                        .publish(MonotonicClock::read().as_nanos());
                }
            })?;
        Ok(LinkPump {
            stop: Some(stop),
            thread: Some(thread),
        })
    }
}

impl Drop for LinkPump {
    fn drop(&mut self) {
        drop(self.stop.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
