//! The stop latch: an e-stop request that no queue can refuse and no lock can hold back.
//!
//! A [`StopLatch`] is one atomic request counter that any thread may bump
//! ([`StopLatch::request`]) and that a control loop reads every tick through its
//! [`StopAwareCommands`] port: a counter that moved since the last tick becomes an
//! [`ControlCommand::EStop`] ahead of any queued command. Unlike a command ring, it cannot be
//! full, and raising it takes no lock, so a stop is never queued behind work or refused. A second
//! word, written only by the tick, tells the requester which request the loop has acted on
//! ([`StopLatch::acted_on`]).
//!
//! ```
//! use penelope_rt_core::control::{CommandSource, ControlCommand, NoCommands};
//! use penelope_rt_core::stop::{StopAwareCommands, StopLatch};
//!
//! let latch = StopLatch::new();
//! let mut port = StopAwareCommands::new(NoCommands, &latch);
//! assert_eq!(port.next_command(), None);
//! let request = latch.request();
//! assert!(!latch.acted_on(request));
//! assert_eq!(port.next_command(), Some(ControlCommand::EStop));
//! assert!(latch.acted_on(request));
//! assert_eq!(port.next_command(), None); // one request, one e-stop
//! ```

use core::ops::Deref;

use crate::control::{CommandSource, ControlCommand};
use crate::sync::{AtomicU32, Ordering};

/// An e-stop request counter shared by whoever may stop a loop and the loop itself.
///
/// # Real-time
/// Every method is one atomic operation: wait-free, no allocation, no lock.
#[derive(Debug)]
pub struct StopLatch {
    /// Requests so far (wrapping); bumped by requesters.
    requests: AtomicU32,
    /// The newest request the loop has taken; written only by the loop's [`StopReader`].
    taken: AtomicU32,
}

impl Default for StopLatch {
    fn default() -> Self {
        Self::new()
    }
}

impl StopLatch {
    /// A latch with no request (`const`, so it can be a `static`).
    #[cfg(not(loom))]
    pub const fn new() -> Self {
        StopLatch {
            requests: AtomicU32::new(0),
            taken: AtomicU32::new(0),
        }
    }

    /// A latch with no request.
    #[cfg(loom)]
    pub fn new() -> Self {
        StopLatch {
            requests: AtomicU32::new(0),
            taken: AtomicU32::new(0),
        }
    }

    /// Asks the loop to latch its e-stop on its next tick; returns this request's number, for
    /// [`StopLatch::acted_on`]. Never blocks and never fails.
    pub fn request(&self) -> u32 {
        self.requests.fetch_add(1, Ordering::AcqRel).wrapping_add(1)
    }

    /// Whether the loop has taken request `request` (or a later one) and latched its e-stop.
    pub fn acted_on(&self, request: u32) -> bool {
        // Wrapping distance: a taken count at or past `request` (within half the range).
        let taken = self.taken.load(Ordering::Acquire);
        (taken.wrapping_sub(request) as i32) >= 0
    }

    /// Requests made so far (wrapping).
    pub fn requests(&self) -> u32 {
        self.requests.load(Ordering::Acquire)
    }
}

/// The loop's side of a [`StopLatch`]: sees each new request once.
#[derive(Debug)]
pub struct StopReader<P: Deref<Target = StopLatch>> {
    latch: P,
    seen: u32,
}

impl<P: Deref<Target = StopLatch>> StopReader<P> {
    /// A reader of `latch` that ignores the requests made before it existed.
    pub fn new(latch: P) -> Self {
        let seen = latch.requests.load(Ordering::Acquire);
        StopReader { latch, seen }
    }

    /// Whether a stop was requested since the last call; if so, the request is marked taken
    /// (the caller latches its e-stop at once).
    ///
    /// # Real-time
    /// One atomic load, and one store when a request is new: wait-free, no allocation.
    pub fn take(&mut self) -> bool {
        let now = self.latch.requests.load(Ordering::Acquire);
        if now == self.seen {
            return false;
        }
        self.seen = now;
        self.latch.taken.store(now, Ordering::Release);
        true
    }

    /// The latch read.
    pub fn latch(&self) -> &StopLatch {
        &self.latch
    }
}

/// A control loop's command port with a stop latch in front: a new stop request comes out as
/// [`ControlCommand::EStop`] before any queued command, on the first command read of the tick
/// (every tick reads its port at least once).
#[derive(Debug)]
pub struct StopAwareCommands<C, P: Deref<Target = StopLatch>> {
    inner: C,
    stop: StopReader<P>,
}

impl<C, P: Deref<Target = StopLatch>> StopAwareCommands<C, P> {
    /// `inner` behind the stop latch `latch`.
    pub fn new(inner: C, latch: P) -> Self {
        StopAwareCommands {
            inner,
            stop: StopReader::new(latch),
        }
    }

    /// The latch this port reads.
    pub fn latch(&self) -> &StopLatch {
        self.stop.latch()
    }
}

impl<C: CommandSource, P: Deref<Target = StopLatch>> CommandSource for StopAwareCommands<C, P> {
    /// # Real-time
    /// Wait-free and allocation-free when `inner` is.
    fn next_command(&mut self) -> Option<ControlCommand> {
        if self.stop.take() {
            return Some(ControlCommand::EStop);
        }
        self.inner.next_command()
    }
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;
    use crate::control::NoCommands;

    struct Queue(&'static [ControlCommand], usize);

    impl CommandSource for Queue {
        fn next_command(&mut self) -> Option<ControlCommand> {
            let c = self.0.get(self.1).copied();
            self.1 += 1;
            c
        }
    }

    #[test]
    fn a_stop_comes_before_queued_commands() {
        let latch = StopLatch::new();
        let queue = Queue(&[ControlCommand::Activate, ControlCommand::Rearm], 0);
        let mut port = StopAwareCommands::new(queue, &latch);
        latch.request();
        assert_eq!(port.next_command(), Some(ControlCommand::EStop));
        assert_eq!(port.next_command(), Some(ControlCommand::Activate));
        assert_eq!(port.next_command(), Some(ControlCommand::Rearm));
        assert_eq!(port.next_command(), None);
    }

    #[test]
    fn requests_before_the_reader_are_ignored_and_several_make_one_stop() {
        let latch = StopLatch::new();
        latch.request();
        let mut port = StopAwareCommands::new(NoCommands, &latch);
        assert_eq!(port.next_command(), None);
        let first = latch.request();
        let second = latch.request();
        assert!(!latch.acted_on(first));
        assert_eq!(port.next_command(), Some(ControlCommand::EStop));
        assert_eq!(port.next_command(), None);
        assert!(latch.acted_on(first) && latch.acted_on(second));
        assert!(!latch.acted_on(second.wrapping_add(1)));
    }

    #[test]
    fn the_counter_wraps() {
        let latch = StopLatch::new();
        latch.requests.store(u32::MAX, Ordering::Relaxed);
        latch.taken.store(u32::MAX, Ordering::Relaxed);
        let mut port = StopAwareCommands::new(NoCommands, &latch);
        let request = latch.request();
        assert_eq!(request, 0);
        assert!(!latch.acted_on(request));
        assert_eq!(port.next_command(), Some(ControlCommand::EStop));
        assert!(latch.acted_on(request));
    }
}

#[cfg(all(test, loom))]
mod loom_tests {
    use super::*;
    use crate::control::NoCommands;
    use loom::sync::Arc;

    /// Two requesters and the loop: every request is acted on by a poll that follows it, no
    /// more e-stops than requests, none without a request.
    #[test]
    fn loom_stop_latch_two_requesters_one_tick_loop() {
        loom::model(|| {
            let latch = Arc::new(StopLatch::new());
            let mut port = StopAwareCommands::new(NoCommands, latch.clone());
            let requesters: [_; 2] = core::array::from_fn(|_| {
                let latch = latch.clone();
                loom::thread::spawn(move || latch.request())
            });
            let mut stops = 0;
            // The loop polls while the requesters run.
            for _ in 0..2 {
                match port.next_command() {
                    Some(ControlCommand::EStop) => stops += 1,
                    None => {}
                    other => panic!("unexpected {other:?}"),
                }
            }
            let numbers = requesters.map(|t| t.join().unwrap());
            // A poll after both requests: every request has now been acted on.
            if port.next_command() == Some(ControlCommand::EStop) {
                stops += 1;
            }
            assert_eq!(port.next_command(), None, "no e-stop without a new request");
            // Each e-stop takes at least one request: never more stops than requests.
            assert!((1..=2).contains(&stops), "{stops} e-stops for 2 requests");
            for n in numbers {
                assert!(latch.acted_on(n));
            }
            assert_eq!(latch.requests(), 2);
        });
    }
}
