//! Safety events raised by one thread and taken by another: one atomic word, a bit per
//! [`SafetyEvent`].
//!
//! A communication thread that notices something the control loop must record (its link to
//! another node lost or back) [`raise`](EventCell::raise)s it; the control loop
//! [`take`](EventCell::take)s whatever was raised since its last tick and notes it in its
//! [`Safety`](crate::safety::Safety), so the event appears in that tick's telemetry. Raising is a
//! `fetch_or`, taking a `swap(0)`: both wait-free, nothing allocates, no event is lost or taken
//! twice, and any number of threads may raise. Raising the same event twice before a take
//! delivers it once (a set, not a queue).
//!
//! ```
//! use penelope_rt_core::events::EventCell;
//! use penelope_rt_core::safety::SafetyEvent;
//!
//! static LINK: EventCell = EventCell::new();
//! LINK.raise(SafetyEvent::LinkLost);
//! let taken = LINK.take();
//! assert!(taken.contains(SafetyEvent::LinkLost));
//! assert!(LINK.take().is_empty()); // taken once
//! ```

use crate::safety::{EventSet, SafetyEvent};
use crate::sync::{AtomicU32, Ordering};

/// A set of safety events shared between threads. See the [module docs](self).
#[derive(Debug, Default)]
pub struct EventCell {
    bits: AtomicU32,
}

impl EventCell {
    /// An empty cell (`const`, so it can be a `static`).
    #[cfg(not(loom))]
    pub const fn new() -> Self {
        EventCell {
            bits: AtomicU32::new(0),
        }
    }

    /// An empty cell.
    #[cfg(loom)]
    pub fn new() -> Self {
        EventCell {
            bits: AtomicU32::new(0),
        }
    }

    /// Raises `event`: the next [`take`](Self::take) returns it.
    ///
    /// # Real-time
    /// One atomic `fetch_or` (release: what the raiser wrote before is visible to the taker).
    pub fn raise(&self, event: SafetyEvent) {
        let mut one = EventSet::EMPTY;
        one.insert(event);
        self.bits.fetch_or(one.0, Ordering::Release);
    }

    /// Every event raised since the last take, clearing them.
    ///
    /// # Real-time
    /// One atomic `swap` (acquire).
    pub fn take(&self) -> EventSet {
        EventSet(self.bits.swap(0, Ordering::Acquire))
    }
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;

    #[test]
    fn events_raised_by_one_thread_are_taken_once_by_another() {
        let cell = std::sync::Arc::new(EventCell::new());
        let raiser = cell.clone();
        let t = std::thread::spawn(move || {
            for i in 0..10_000u32 {
                raiser.raise(if i % 2 == 0 {
                    SafetyEvent::LinkLost
                } else {
                    SafetyEvent::LinkRestored
                });
            }
        });
        let mut seen = EventSet::EMPTY;
        while !t.is_finished() {
            seen = seen.union(cell.take());
        }
        t.join().unwrap();
        seen = seen.union(cell.take());
        assert!(seen.contains(SafetyEvent::LinkLost) && seen.contains(SafetyEvent::LinkRestored));
        assert_eq!(seen.iter().count(), 2, "{seen:?}");
        assert!(cell.take().is_empty());
    }
}

#[cfg(all(test, loom))]
mod loom_tests {
    use super::*;
    use loom::sync::Arc;

    /// Two raisers and a taker that takes twice while they run, then once after: every event
    /// is taken exactly once, whatever the interleaving.
    #[test]
    fn loom_event_cell_delivers_each_raised_event_exactly_once() {
        loom::model(|| {
            let cell = Arc::new(EventCell::new());
            let (a, b) = (cell.clone(), cell.clone());
            let ta = loom::thread::spawn(move || a.raise(SafetyEvent::LinkLost));
            let tb = loom::thread::spawn(move || b.raise(SafetyEvent::LinkRestored));
            let first = cell.take();
            let second = cell.take();
            ta.join().unwrap();
            tb.join().unwrap();
            let last = cell.take();
            for e in [SafetyEvent::LinkLost, SafetyEvent::LinkRestored] {
                let times = [first, second, last]
                    .iter()
                    .filter(|s| s.contains(e))
                    .count();
                assert_eq!(times, 1, "{e:?} taken {times} times");
            }
            assert!(cell.take().is_empty());
        });
    }

    /// What the raiser wrote before raising is visible to the thread that takes the event.
    #[test]
    fn loom_event_cell_publishes_what_came_before_the_raise() {
        use loom::sync::atomic::AtomicU32 as Data;
        loom::model(|| {
            let cell = Arc::new(EventCell::new());
            let data = Arc::new(Data::new(0));
            let (c, d) = (cell.clone(), data.clone());
            let t = loom::thread::spawn(move || {
                d.store(7, Ordering::Relaxed);
                c.raise(SafetyEvent::LinkLost);
            });
            if cell.take().contains(SafetyEvent::LinkLost) {
                assert_eq!(data.load(Ordering::Relaxed), 7);
            }
            t.join().unwrap();
        });
    }
}
