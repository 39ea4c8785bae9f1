//! Waking a periodic thread before its deadline (Linux, feature `std`): a [`Doorbell`] another
//! thread rings, and a socket that becomes readable.
//!
//! A communication thread runs on its period, but some news should not wait for the next one:
//! a safety event of its own loop (a force sensor's fault must reach the master's display at
//! once), or a sample the other side sent out of turn. [`spawn_woken`](crate::exec::spawn_woken)
//! runs a periodic thread that sleeps until its deadline *or* until one of its [`WakeOn`]
//! sources fires, whichever is first; an early wake calls the body with
//! [`Tick::early`](crate::exec::Tick::early) set and leaves the period's schedule alone.
//!
//! The doorbell is an `eventfd`: [`Doorbell::ring`] is one non-blocking `write` (no allocation,
//! no lock, never waits), so a control thread may ring it; the waiting side is one `ppoll` on
//! the doorbell and the socket with the time left to the deadline.
//!
//! ```
//! use std::sync::Arc;
//! use std::time::Duration;
//! use penelope_rt_core::wake::{Doorbell, Woken};
//! use penelope_rt_core::clock::MonotonicClock;
//!
//! let bell = Arc::new(Doorbell::new().expect("an eventfd"));
//! let ringer = bell.clone();
//! std::thread::spawn(move || ringer.ring());
//! let deadline = MonotonicClock::read() + Duration::from_secs(5);
//! // Rung long before the deadline (or, if the ring came first, at once).
//! assert_eq!(bell.wait_until(deadline, None), Woken::Early);
//! ```

use std::io;
use std::os::fd::{AsFd, BorrowedFd, OwnedFd};
use std::sync::Arc;

use nix::errno::Errno;
use nix::poll::{PollFd, PollFlags, ppoll};
use nix::sys::eventfd::{EfdFlags, EventFd};
use nix::sys::time::TimeSpec;
use penelope_hal::Timestamp;

use crate::clock::MonotonicClock;

/// Early wakes a thread takes per period at most, by default: beyond, it sleeps to its
/// deadline. A socket that stays readable (datagrams the body leaves unread) or a doorbell rung
/// every few microseconds must not turn a periodic thread into a busy one. A thread woken by
/// every tick of a faster loop (a communication thread whose control loop rings it with each
/// sample) takes this many per tick of that loop ([`WakeOn::per_period`]).
pub const MAX_EARLY_WAKES: u32 = 4;

/// Wakes a periodic thread before its deadline. Cheap to ring from any thread, including a
/// real-time one; rings before the thread waits are not lost (they wake its next wait).
#[derive(Debug)]
pub struct Doorbell {
    fd: EventFd,
}

/// Why [`Doorbell::wait_until`] returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Woken {
    /// The deadline came.
    Deadline,
    /// The doorbell rang or the socket became readable before the deadline.
    Early,
}

impl Doorbell {
    /// A new doorbell (an `eventfd`, non-blocking, closed on exec).
    ///
    /// # Errors
    /// The OS's, when it has no file descriptor to give.
    pub fn new() -> io::Result<Self> {
        let fd = EventFd::from_value_and_flags(0, EfdFlags::EFD_NONBLOCK | EfdFlags::EFD_CLOEXEC)
            .map_err(io::Error::from)?;
        Ok(Doorbell { fd })
    }

    /// Rings: the waiting thread (or its next wait) wakes early.
    ///
    /// # Real-time
    /// One non-blocking `write` of 8 bytes; no allocation, no lock. It cannot fail but for a
    /// counter 2^64 - 2 rings deep, which is ignored (the bell is rung anyway).
    pub fn ring(&self) {
        let _ = self.fd.write(1);
    }

    /// Takes the rings so far (the bell is quiet again).
    fn drain(&self) {
        let _ = self.fd.read();
    }

    /// Sleeps until `deadline` (`CLOCK_MONOTONIC`), or until the bell rings or `readable`
    /// (a socket's descriptor) has data, whichever is first. A ring is taken (the bell is
    /// quiet again); the socket's data is left for the caller to read.
    ///
    /// # Real-time
    /// One `ppoll` (more only after a signal) and a `read` when rung; no allocation. The
    /// timeout is relative, to the nanosecond, and on a real-time thread has no timer slack.
    pub fn wait_until(&self, deadline: Timestamp, readable: Option<BorrowedFd<'_>>) -> Woken {
        loop {
            let now = MonotonicClock::read();
            if now >= deadline {
                return Woken::Deadline;
            }
            let left = TimeSpec::from_duration(deadline.saturating_since(now));
            let mut fds = [
                PollFd::new(self.fd.as_fd(), PollFlags::POLLIN),
                PollFd::new(readable.unwrap_or(self.fd.as_fd()), PollFlags::POLLIN),
            ];
            let count = if readable.is_some() { 2 } else { 1 };
            match ppoll(&mut fds[..count], Some(left), None) {
                // Timed out: the loop's clock check returns (or waits out a short wake).
                Ok(0) | Err(Errno::EINTR) => {}
                Ok(_) => {
                    self.drain();
                    return Woken::Early;
                }
                // Not expected (the descriptors are valid while the thread waits): sleep out
                // the period rather than spin.
                Err(_) => {
                    crate::clock::sleep_until(deadline);
                    return Woken::Deadline;
                }
            }
        }
    }
}

/// What may wake a periodic thread before its deadline: a doorbell, and optionally a socket
/// that becomes readable.
#[derive(Debug)]
pub struct WakeOn {
    /// The doorbell.
    pub doorbell: Arc<Doorbell>,
    /// A socket whose data wakes the thread (owned here as a duplicate of the caller's
    /// descriptor, so it stays valid as long as the thread waits on it).
    pub readable: Option<OwnedFd>,
    /// Early wakes taken per period at most ([`MAX_EARLY_WAKES`] unless
    /// [`per_period`](Self::per_period) says otherwise).
    pub max_early_wakes: u32,
}

impl WakeOn {
    /// Woken by `doorbell` alone.
    pub fn doorbell(doorbell: Arc<Doorbell>) -> Self {
        WakeOn {
            doorbell,
            readable: None,
            max_early_wakes: MAX_EARLY_WAKES,
        }
    }

    /// At most [`MAX_EARLY_WAKES`] early wakes per tick of a loop that runs `ticks` times in
    /// this thread's period (at least one): the cap on the rate of wakes, kept per tick of the
    /// faster loop when that loop rings with every tick.
    pub fn per_period(mut self, ticks: u32) -> Self {
        self.max_early_wakes = MAX_EARLY_WAKES.saturating_mul(ticks.max(1));
        self
    }

    /// Woken also when `socket` has data (the descriptor is duplicated).
    ///
    /// # Errors
    /// The OS's, when the descriptor cannot be duplicated.
    pub fn and_readable(mut self, socket: BorrowedFd<'_>) -> io::Result<Self> {
        self.readable = Some(socket.try_clone_to_owned()?);
        Ok(self)
    }

    /// Sleeps until `deadline` or an early wake ([`Doorbell::wait_until`]).
    pub fn wait_until(&self, deadline: Timestamp) -> Woken {
        self.doorbell
            .wait_until(deadline, self.readable.as_ref().map(AsFd::as_fd))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::UdpSocket;
    use std::time::Duration;

    #[test]
    fn an_unrung_bell_sleeps_to_the_deadline() {
        let bell = Doorbell::new().unwrap();
        let deadline = MonotonicClock::read() + Duration::from_millis(3);
        assert_eq!(bell.wait_until(deadline, None), Woken::Deadline);
        assert!(MonotonicClock::read() >= deadline);
    }

    #[test]
    fn a_ring_before_the_wait_wakes_it_at_once_and_is_taken() {
        let bell = Doorbell::new().unwrap();
        bell.ring();
        bell.ring();
        let deadline = MonotonicClock::read() + Duration::from_secs(30);
        assert_eq!(bell.wait_until(deadline, None), Woken::Early);
        // Both rings were taken by that one wake: the next wait sleeps to its deadline.
        let soon = MonotonicClock::read() + Duration::from_millis(2);
        assert_eq!(bell.wait_until(soon, None), Woken::Deadline);
    }

    #[test]
    fn a_ring_from_another_thread_wakes_the_waiter() {
        let bell = Arc::new(Doorbell::new().unwrap());
        let ringer = bell.clone();
        let (tx, rx) = std::sync::mpsc::channel();
        let waiter = std::thread::spawn(move || {
            tx.send(()).unwrap();
            bell.wait_until(MonotonicClock::read() + Duration::from_secs(30), None)
        });
        rx.recv().unwrap();
        ringer.ring();
        assert_eq!(waiter.join().unwrap(), Woken::Early);
    }

    #[test]
    fn a_datagram_wakes_the_waiter_and_is_left_to_read() {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
        let wake = WakeOn::doorbell(Arc::new(Doorbell::new().unwrap()))
            .and_readable(socket.as_fd())
            .unwrap();
        assert!(wake.readable.is_some());
        sender.send_to(b"x", socket.local_addr().unwrap()).unwrap();
        let deadline = MonotonicClock::read() + Duration::from_secs(30);
        assert_eq!(wake.wait_until(deadline), Woken::Early);
        let mut buf = [0u8; 4];
        socket.set_nonblocking(true).unwrap();
        assert_eq!(socket.recv(&mut buf).unwrap(), 1);
        // Read: the next wait sleeps to its deadline.
        let soon = MonotonicClock::read() + Duration::from_millis(2);
        assert_eq!(wake.wait_until(soon), Woken::Deadline);
    }
}
