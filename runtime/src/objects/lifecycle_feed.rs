//! The creator's lifecycle transitions as they happen (create, configure, activate, deactivate,
//! cleanup, shutdown, destroy), for the recorders that write them beside the ticks.
//!
//! Transitions happen in the creator, under its callers' threads, never in a loop: a reader is
//! a bounded channel, and a reader that falls behind loses events, counted.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};

use serde::{Deserialize, Serialize};

/// One transition of one object.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LifecycleEvent {
    /// When, ns on the node's clock (the simulated clock on a simulated node).
    pub time_ns: u64,
    /// The object's name.
    pub object: String,
    /// Its kind (`controller/force-display`, ...).
    pub kind: String,
    /// What happened: `create`, `destroy`, or the transition's name (`configure`, ...).
    pub transition: String,
    /// Its state afterwards (`unconfigured`, `inactive`, `active`, `finalized`; `destroyed`).
    pub state: String,
}

/// The readers of a creator's transitions.
#[derive(Debug, Default)]
pub struct LifecycleFeed {
    readers: Mutex<Vec<SyncSender<LifecycleEvent>>>,
    lost: AtomicU64,
}

impl LifecycleFeed {
    /// A new reader holding up to `capacity` events it has not taken yet.
    pub fn subscribe(&self, capacity: usize) -> Receiver<LifecycleEvent> {
        let (tx, rx) = sync_channel(capacity.max(1));
        if let Ok(mut readers) = self.readers.lock() {
            readers.push(tx);
        }
        rx
    }

    /// Hands `event` to every reader (a reader that has gone is forgotten; a full one loses
    /// it, counted).
    pub fn publish(&self, event: &LifecycleEvent) {
        let Ok(mut readers) = self.readers.lock() else {
            return;
        };
        readers.retain(|r| match r.try_send(event.clone()) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) => {
                self.lost.fetch_add(1, Ordering::Relaxed);
                true
            }
            Err(TrySendError::Disconnected(_)) => false,
        });
    }

    /// Events readers lost because they were full.
    pub fn lost(&self) -> u64 {
        self.lost.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn event(n: u64) -> LifecycleEvent {
        LifecycleEvent {
            time_ns: n,
            object: "c".into(),
            kind: "controller/joint-pid".into(),
            transition: "configure".into(),
            state: "inactive".into(),
        }
    }

    #[test]
    fn every_reader_gets_each_event_a_full_one_loses_and_counts_a_gone_one_is_forgotten() {
        let feed = LifecycleFeed::default();
        let a = feed.subscribe(8);
        let b = feed.subscribe(1);
        let gone = feed.subscribe(8);
        drop(gone);
        for n in 0..3 {
            feed.publish(&event(n));
        }
        assert_eq!(
            a.try_iter().map(|e| e.time_ns).collect::<Vec<_>>(),
            [0, 1, 2]
        );
        assert_eq!(b.try_iter().map(|e| e.time_ns).collect::<Vec<_>>(), [0]);
        assert_eq!(feed.lost(), 2);
        assert_eq!(feed.readers.lock().unwrap().len(), 2);
    }
}
