//! Who a publisher sends samples to: a bounded table of subscribers, each with the newest
//! probe it sent, dropped when it falls silent. Time is a parameter (ns on the publisher's
//! clock), so the rules are tested without waiting.

use std::net::SocketAddr;

use super::Probe;
use crate::dataplane::frame::Header;
use crate::dataplane::stream::{StreamReceiver, Verdict};

/// One subscriber.
#[derive(Clone, Debug)]
struct Subscriber {
    address: SocketAddr,
    /// Its subscriptions, newest wins: a replayed or reordered subscription changes nothing.
    subscriptions: StreamReceiver,
    last_heard_ns: i64,
    /// Its newest probe, and the order in which probes arrived (larger: newer).
    probe: Option<(Probe, u64)>,
}

/// What became of a subscription.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Admission {
    /// A new subscriber.
    Joined,
    /// A subscriber renewed its subscription.
    Renewed,
}

/// Why a subscription (or an unsubscription) was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// The table is full.
    #[error("subscriber table full")]
    Full,
    /// Not newer than what this subscriber sent before (duplicated, late, or replayed), or
    /// another subscriber's session from a new address (replayed from elsewhere).
    #[error("subscription not newer than the subscriber's last")]
    Stale,
    /// Another stream's datagram.
    #[error("not a subscription")]
    OtherStream,
}

/// The subscribers of one publisher.
#[derive(Clone, Debug)]
pub struct SubscriberTable {
    entries: Vec<Subscriber>,
    capacity: usize,
    timeout_ns: i64,
    probes_taken: u64,
    refused_full: u64,
    refused_stale: u64,
    expired: u64,
}

impl SubscriberTable {
    /// An empty table of at most `capacity` subscribers, each dropped when not heard from for
    /// `timeout`.
    pub fn new(capacity: usize, timeout: std::time::Duration) -> Self {
        SubscriberTable {
            entries: Vec::with_capacity(capacity),
            capacity,
            timeout_ns: i64::try_from(timeout.as_nanos()).unwrap_or(i64::MAX),
            probes_taken: 0,
            refused_full: 0,
            refused_stale: 0,
            expired: 0,
        }
    }

    /// Takes the subscription of `header` (authenticated already) from `from`, received at
    /// `now_ns`, with its probe if it has one.
    ///
    /// # Errors
    /// [`Refusal`], counted.
    pub fn subscribe(
        &mut self,
        from: SocketAddr,
        header: &Header,
        probe: Option<Probe>,
        now_ns: i64,
    ) -> Result<Admission, Refusal> {
        let admission = match self.entries.iter().position(|s| s.address == from) {
            Some(i) => {
                self.judge(i, header)?;
                Admission::Renewed
            }
            None => {
                // A session is one reader's endpoint: the same session from another address is
                // a recorded subscription replayed from elsewhere, which would otherwise take a
                // place in the table and draw samples to the replayer.
                if self.entries.iter().any(|s| {
                    s.subscriptions
                        .newest()
                        .is_some_and(|n| n.session == header.session)
                }) {
                    self.refused_stale += 1;
                    return Err(Refusal::Stale);
                }
                if self.entries.len() >= self.capacity {
                    self.refused_full += 1;
                    return Err(Refusal::Full);
                }
                self.entries.push(Subscriber {
                    address: from,
                    subscriptions: StreamReceiver::new(super::SENSOR_SUBSCRIPTIONS),
                    last_heard_ns: now_ns,
                    probe: None,
                });
                let i = self.entries.len() - 1;
                if let Err(e) = self.judge(i, header) {
                    self.entries.pop();
                    return Err(e);
                }
                Admission::Joined
            }
        };
        let entry = self
            .entries
            .iter_mut()
            .find(|s| s.address == from)
            .ok_or(Refusal::OtherStream)?;
        entry.last_heard_ns = now_ns;
        if let Some(p) = probe {
            self.probes_taken += 1;
            entry.probe = Some((p, self.probes_taken));
        }
        Ok(admission)
    }

    /// Removes the subscriber at `from` whose unsubscription is `header`; `false` if it was not
    /// subscribed or the unsubscription is not newer than its last subscription.
    pub fn unsubscribe(&mut self, from: SocketAddr, header: &Header) -> bool {
        let Some(i) = self.entries.iter().position(|s| s.address == from) else {
            return false;
        };
        if self.judge(i, header).is_err() {
            return false;
        }
        self.entries.swap_remove(i);
        true
    }

    /// Drops the subscribers not heard from since `now_ns` minus the timeout; returns how many.
    pub fn expire(&mut self, now_ns: i64) -> usize {
        let before = self.entries.len();
        let timeout = self.timeout_ns;
        self.entries
            .retain(|s| now_ns.saturating_sub(s.last_heard_ns) <= timeout);
        let gone = before - self.entries.len();
        self.expired += gone as u64;
        gone
    }

    /// The newest probe any subscriber sent.
    pub fn newest_probe(&self) -> Option<Probe> {
        self.entries
            .iter()
            .filter_map(|s| s.probe)
            .max_by_key(|(_, order)| *order)
            .map(|(p, _)| p)
    }

    /// The subscribers' addresses.
    pub fn addresses(&self) -> impl Iterator<Item = SocketAddr> + '_ {
        self.entries.iter().map(|s| s.address)
    }

    /// Subscribers now.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether nobody is subscribed.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Probes taken so far.
    pub fn probes_taken(&self) -> u64 {
        self.probes_taken
    }

    /// Subscriptions refused because the table was full.
    pub fn refused_full(&self) -> u64 {
        self.refused_full
    }

    /// Subscriptions refused as not newer than the subscriber's last, or replayed from another
    /// address.
    pub fn refused_stale(&self) -> u64 {
        self.refused_stale
    }

    /// Subscribers dropped for silence.
    pub fn expired(&self) -> u64 {
        self.expired
    }

    /// Judges `header` against subscriber `i`'s subscriptions; counts a refusal.
    fn judge(&mut self, i: usize, header: &Header) -> Result<(), Refusal> {
        match self.entries[i].subscriptions.offer(header) {
            Verdict::Accepted => Ok(()),
            Verdict::OtherStream => Err(Refusal::OtherStream),
            Verdict::Duplicate | Verdict::Late | Verdict::StaleSession => {
                self.refused_stale += 1;
                Err(Refusal::Stale)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataplane::sensor_stream::SENSOR_SUBSCRIPTIONS;
    use crate::dataplane::stream::StreamSender;
    use nalgebra::Vector3;
    use std::time::Duration;

    const MS: i64 = 1_000_000;

    fn addr(port: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    fn probe(z: f64) -> Probe {
        Probe {
            pose: penelope_hal::Pose::translation(0.0, 0.0, z),
            velocity: Vector3::zeros(),
        }
    }

    #[test]
    fn a_silent_subscriber_expires_and_a_renewing_one_stays() {
        let mut table = SubscriberTable::new(4, Duration::from_secs(1));
        let (mut quiet, mut busy) = (
            StreamSender::new(SENSOR_SUBSCRIPTIONS),
            StreamSender::new(SENSOR_SUBSCRIPTIONS),
        );
        assert_eq!(
            table.subscribe(addr(1), &quiet.next(0), None, 0),
            Ok(Admission::Joined)
        );
        assert_eq!(
            table.subscribe(addr(2), &busy.next(0), Some(probe(0.1)), 0),
            Ok(Admission::Joined)
        );
        // The busy one renews every 200 ms; the quiet one never again.
        for k in 1..=10 {
            let t = k * 200 * MS;
            assert_eq!(
                table.subscribe(addr(2), &busy.next(t), None, t),
                Ok(Admission::Renewed)
            );
            table.expire(t);
        }
        assert_eq!(table.addresses().collect::<Vec<_>>(), [addr(2)]);
        assert_eq!(table.expired(), 1);
        // At exactly the timeout it is still there; one nanosecond later it is gone.
        assert_eq!(table.expire(2000 * MS + 1000 * MS), 0);
        assert_eq!(table.expire(2000 * MS + 1000 * MS + 1), 1);
        assert!(table.is_empty());
        // A subscriber that expired may come back.
        assert_eq!(
            table.subscribe(addr(1), &quiet.next(3100 * MS), None, 3100 * MS),
            Ok(Admission::Joined)
        );
    }

    #[test]
    fn the_table_is_bounded_and_frees_a_place_on_unsubscribe() {
        let mut table = SubscriberTable::new(2, Duration::from_secs(1));
        let mut senders: Vec<StreamSender> = (0..3)
            .map(|_| StreamSender::new(SENSOR_SUBSCRIPTIONS))
            .collect();
        for (i, s) in senders.iter_mut().enumerate().take(2) {
            assert!(table.subscribe(addr(i as u16), &s.next(0), None, 0).is_ok());
        }
        let third = senders[2].next(0);
        assert_eq!(
            table.subscribe(addr(2), &third, None, 0),
            Err(Refusal::Full)
        );
        assert_eq!(table.refused_full(), 1);
        assert_eq!(table.len(), 2);
        assert!(table.unsubscribe(addr(0), &senders[0].next(1)));
        assert_eq!(
            table.subscribe(addr(2), &senders[2].next(2), None, 2),
            Ok(Admission::Joined)
        );
        // Unsubscribing someone who is not there, or with an old datagram (of its own session,
        // or of an earlier session), does nothing.
        assert!(!table.unsubscribe(addr(9), &senders[0].next(3)));
        assert!(!table.unsubscribe(addr(2), &third));
        assert!(!table.unsubscribe(addr(1), &senders[0].next(4)));
        assert_eq!(table.len(), 2);
    }

    #[test]
    fn replays_are_refused_and_the_newest_probe_wins() {
        let mut table = SubscriberTable::new(4, Duration::from_secs(1));
        let (mut a, mut b) = (
            StreamSender::new(SENSOR_SUBSCRIPTIONS),
            StreamSender::new(SENSOR_SUBSCRIPTIONS),
        );
        let first = a.next(0);
        table
            .subscribe(addr(1), &first, Some(probe(0.1)), 0)
            .unwrap();
        table
            .subscribe(addr(2), &b.next(0), Some(probe(0.2)), 0)
            .unwrap();
        assert_eq!(table.newest_probe(), Some(probe(0.2)));
        // A replay of a's first subscription, carrying its old probe, changes nothing.
        assert_eq!(
            table.subscribe(addr(1), &first, Some(probe(0.1)), 5),
            Err(Refusal::Stale)
        );
        assert_eq!(table.newest_probe(), Some(probe(0.2)));
        assert_eq!((table.refused_stale(), table.probes_taken()), (1, 2));
        // A probe-less renewal keeps the subscriber's probe but is not a newer probe.
        table.subscribe(addr(1), &a.next(6), None, 6).unwrap();
        assert_eq!(table.newest_probe(), Some(probe(0.2)));
        table
            .subscribe(addr(1), &a.next(7), Some(probe(0.3)), 7)
            .unwrap();
        assert_eq!(table.newest_probe(), Some(probe(0.3)));
        // The same subscription replayed from another address takes no place.
        let replayed = a.next(8);
        table.subscribe(addr(1), &replayed, None, 8).unwrap();
        assert_eq!(
            table.subscribe(addr(7), &replayed, None, 8),
            Err(Refusal::Stale)
        );
        assert_eq!(table.len(), 2);
        // Another stream's datagram from a newcomer leaves no entry behind.
        let other = StreamSender::new(crate::dataplane::frame::StreamId(99)).next(8);
        assert_eq!(
            table.subscribe(addr(3), &other, None, 8),
            Err(Refusal::OtherStream)
        );
        assert_eq!(table.len(), 2);
    }
}
