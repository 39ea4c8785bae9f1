//! One data-plane stream: the sender numbers its datagrams, the receiver keeps the newest
//! (teleoperation wants the latest sample, not every sample) and counts what it refused.
//!
//! Newest wins on `(session, sequence)`: in one session a larger sequence number is newer; a new
//! session (a restarted sender) is taken only when its number is larger than the newest
//! sample's session. Sessions are numbered by the wall clock when the sender starts
//! ([`next_session`]), so they grow across restarts and reboots alike: a recorded datagram of
//! an earlier session (even of an earlier boot of a host that had been up longer, whose send
//! times on a boot-time clock are later) is refused, and cannot take the stream from the
//! sender that runs now. With authenticated datagrams nobody but a member can make a larger
//! session or sequence number, so this rule is also the replay protection.
//!
//! Why the wall clock and not a persisted counter: a node keeps no state on disk between runs,
//! and the nodes of a lab keep their wall clocks synchronized (NTP/PTP: the common clock's
//! estimates rely on it too). The cost: a sender restarted after its wall clock was stepped
//! back by more than the time it was down is refused as stale by receivers that saw the earlier
//! session, until they restart: the link counts as lost, and a lost link ends in its safe state.

use super::frame::{DATAPLANE_VERSION, Header, StreamId};

/// The sending end of a stream: stamps each datagram with the next sequence number.
#[derive(Clone, Debug)]
pub struct StreamSender {
    stream: StreamId,
    session: u64,
    sequence: u64,
}

impl StreamSender {
    /// A sender on `stream` in a new session, larger than every earlier one ([`next_session`]).
    pub fn new(stream: StreamId) -> Self {
        StreamSender::with_session(stream, next_session())
    }

    /// A sender on `stream` in `session` (tests; a restart must take a larger session).
    pub fn with_session(stream: StreamId, session: u64) -> Self {
        StreamSender {
            stream,
            session,
            sequence: 0,
        }
    }

    /// The header of the next datagram, sent at `sent_ns` on the common clock.
    pub fn next(&mut self, sent_ns: i64) -> Header {
        self.sequence += 1;
        Header {
            version: DATAPLANE_VERSION,
            stream: self.stream,
            session: self.session,
            sequence: self.sequence,
            sent_ns,
        }
    }

    /// Datagrams numbered so far.
    pub fn sent(&self) -> u64 {
        self.sequence
    }
}

/// Random low bits of a session number: two senders (of two readers of one sensor) started
/// in the same microsecond still differ.
pub const SESSION_RANDOM_BITS: u32 = 10;

/// A new session number: the wall clock in µs since 1970 (room until the year 2540), shifted
/// past [`SESSION_RANDOM_BITS`] random bits, and larger than any this process drew before.
/// Not a secret: it orders restarts.
pub fn next_session() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    use std::sync::atomic::{AtomicU64, Ordering};
    static LAST: AtomicU64 = AtomicU64::new(0);
    let micros = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |t| t.as_micros() as u64);
    // The process's random hasher keys are drawn from the OS.
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u32(std::process::id());
    let random = h.finish() & ((1 << SESSION_RANDOM_BITS) - 1);
    let drawn = (micros << SESSION_RANDOM_BITS) | random;
    let before = LAST
        .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |last| {
            Some(drawn.max(last.saturating_add(1)))
        })
        .unwrap_or_default();
    drawn.max(before.saturating_add(1))
}

/// What the receiver did with a datagram.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Newer than anything before: taken.
    Accepted,
    /// The same sequence number as the newest (a duplicated datagram).
    Duplicate,
    /// Older than the newest in the same session (late or reordered).
    Late,
    /// A session not larger than the newest sample's (an earlier session replayed, or a
    /// sender restarted after its wall clock went back).
    StaleSession,
    /// Another stream's datagram.
    OtherStream,
}

/// What a receiver counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamStats {
    /// Datagrams taken.
    pub accepted: u64,
    /// Duplicates dropped.
    pub duplicate: u64,
    /// Late or reordered datagrams dropped.
    pub late: u64,
    /// Datagrams of a stale session dropped.
    pub stale_session: u64,
    /// Sequence numbers skipped between taken datagrams (lost, or still on their way).
    pub missed: u64,
    /// Sender restarts taken (new sessions).
    pub new_sessions: u64,
}

/// The receiving end of a stream: newest wins.
#[derive(Clone, Debug)]
pub struct StreamReceiver {
    stream: StreamId,
    newest: Option<Header>,
    stats: StreamStats,
}

impl StreamReceiver {
    /// A receiver of `stream` that has taken nothing yet.
    pub fn new(stream: StreamId) -> Self {
        StreamReceiver {
            stream,
            newest: None,
            stats: StreamStats::default(),
        }
    }

    /// Judges the datagram with `header` (already authenticated, if the system has a secret):
    /// [`Verdict::Accepted`] means it is the newest, and its payload should replace the last.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn offer(&mut self, header: &Header) -> Verdict {
        if header.stream != self.stream {
            return Verdict::OtherStream;
        }
        let verdict = match &self.newest {
            None => Verdict::Accepted,
            Some(n) if n.session == header.session => {
                if header.sequence > n.sequence {
                    self.stats.missed += header.sequence - n.sequence - 1;
                    Verdict::Accepted
                } else if header.sequence == n.sequence {
                    Verdict::Duplicate
                } else {
                    Verdict::Late
                }
            }
            Some(n) if header.session > n.session => {
                self.stats.new_sessions += 1;
                Verdict::Accepted
            }
            Some(_) => Verdict::StaleSession,
        };
        match verdict {
            Verdict::Accepted => {
                self.stats.accepted += 1;
                self.newest = Some(*header);
            }
            Verdict::Duplicate => self.stats.duplicate += 1,
            Verdict::Late => self.stats.late += 1,
            Verdict::StaleSession => self.stats.stale_session += 1,
            Verdict::OtherStream => {}
        }
        verdict
    }

    /// The newest header taken.
    pub fn newest(&self) -> Option<&Header> {
        self.newest.as_ref()
    }

    /// The counters.
    pub fn stats(&self) -> StreamStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: StreamId = StreamId(3);

    #[test]
    fn the_newest_wins_and_everything_else_is_counted() {
        let mut tx = StreamSender::with_session(S, 1);
        let mut rx = StreamReceiver::new(S);
        let h: Vec<Header> = (0..6).map(|i| tx.next(i * 1000)).collect();
        assert_eq!(rx.offer(&h[0]), Verdict::Accepted);
        assert_eq!(rx.offer(&h[0]), Verdict::Duplicate);
        assert_eq!(rx.offer(&h[3]), Verdict::Accepted); // 2 and 3 missed so far
        assert_eq!(rx.offer(&h[1]), Verdict::Late); // reordered: older than the newest
        assert_eq!(rx.offer(&h[5]), Verdict::Accepted);
        let other = StreamSender::with_session(StreamId(4), 1).next(9_000);
        assert_eq!(rx.offer(&other), Verdict::OtherStream);
        assert_eq!(rx.newest(), Some(&h[5]));
        assert_eq!(
            rx.stats(),
            StreamStats {
                accepted: 3,
                duplicate: 1,
                late: 1,
                stale_session: 0,
                missed: 3,
                new_sessions: 0,
            }
        );
    }

    #[test]
    fn a_restarted_sender_is_taken_and_an_old_session_replayed_is_not() {
        let mut old = StreamSender::with_session(S, 10);
        let recorded: Vec<Header> = (0..100).map(|i| old.next(i * 1000)).collect();
        let mut rx = StreamReceiver::new(S);
        for h in &recorded {
            rx.offer(h);
        }
        // The sender restarts: sequence numbers begin again, in a larger session.
        let mut restarted = StreamSender::with_session(S, 11);
        let first = restarted.next(200_000);
        assert_eq!(rx.offer(&first), Verdict::Accepted);
        assert_eq!(rx.offer(&restarted.next(201_000)), Verdict::Accepted);
        // Someone replays the old session's datagrams, even the newest of them.
        for h in &recorded {
            assert_eq!(rx.offer(h), Verdict::StaleSession);
        }
        assert_eq!(rx.stats().stale_session, 100);
        assert_eq!(rx.stats().new_sessions, 1);
    }

    #[test]
    fn senders_draw_growing_sessions_from_the_wall_clock() {
        let before = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_micros() as u64;
        let a = StreamSender::new(S).next(0).session;
        let b = StreamSender::new(S).next(0).session;
        assert!(b > a, "{a} {b}");
        assert!(a >> SESSION_RANDOM_BITS >= before, "{a} from {before} µs");
    }

    #[test]
    fn a_replay_from_an_earlier_boot_with_later_send_times_does_not_take_the_stream() {
        // An earlier boot of the master's host, up for days: its send times (a boot-time clock)
        // are far later than those of the boot that runs now, but its session is earlier.
        let mut earlier_boot = StreamSender::with_session(S, 1_000);
        let day_ns = 86_400_000_000_000;
        let recorded: Vec<Header> = (0..10).map(|i| earlier_boot.next(3 * day_ns + i)).collect();
        let mut now = StreamSender::new(S);
        let mut rx = StreamReceiver::new(S);
        assert_eq!(rx.offer(&now.next(5_000)), Verdict::Accepted);
        for h in &recorded {
            assert_eq!(rx.offer(h), Verdict::StaleSession);
        }
        // The master that runs now keeps the stream.
        for t in 1..=5 {
            assert_eq!(rx.offer(&now.next(5_000 + t)), Verdict::Accepted);
        }
        assert_eq!(rx.stats().stale_session, 10);
        assert_eq!(rx.stats().new_sessions, 0);
        // Even replayed to a receiver that just started (it takes the first it hears), the
        // master's next datagram takes the stream back.
        let mut fresh = StreamReceiver::new(S);
        assert_eq!(fresh.offer(&recorded[9]), Verdict::Accepted);
        assert_eq!(fresh.offer(&now.next(5_100)), Verdict::Accepted);
        assert_eq!(fresh.offer(&recorded[9]), Verdict::StaleSession);
    }
}
