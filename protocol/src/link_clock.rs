//! A common clock per link, estimated from heartbeat exchanges with four timestamps, as NTP
//! does it.
//!
//! Host A (this side) sends a heartbeat at `t1` on its own clock; the peer B receives it at
//! `t2` and answers at `t3`, both on B's clock; A receives the answer at `t4` on its own
//! clock. All times are nanoseconds on each host's monotonic clock. Per exchange:
//!
//! - offset (B's clock minus A's) = ((t2 − t1) + (t3 − t4)) / 2,
//! - round-trip delay = (t4 − t1) − (t3 − t2), and a one-way delay estimate of half of it.
//!
//! The offset of one exchange is wrong by half the difference between the two directions'
//! delays, so it is filtered as NTP's clock filter does: the last [`FILTER_LEN`] accepted
//! exchanges are kept, and the estimate is the offset of the one with the least round-trip
//! delay (the one least disturbed by queueing). Its jitter is the RMS of the kept offsets
//! around the chosen one. A constant asymmetry between the two directions biases the offset by
//! half the asymmetry; no four-timestamp method can see it.
//!
//! The peer's clock is the common clock: [`LinkClock::to_common`] adds the offset to a local
//! time, [`LinkClock::from_common`] takes it away.
//!
//! [`LinkClock`] holds fixed-size arrays only: it allocates nothing, ever.

/// How many accepted exchanges the filter keeps (NTP's clock filter keeps eight).
pub const FILTER_LEN: usize = 8;

/// How many heartbeats may await their answer at once: an answer to a heartbeat sent more
/// than this many heartbeats ago is no longer matched (counted as unmatched).
pub const PENDING_LEN: usize = 64;

/// The longest round trip accepted, ns (10 s): anything longer is not a network delay but a
/// broken clock or a forged answer.
pub const MAX_ROUND_TRIP_NS: i64 = 10_000_000_000;

/// Why an answer to a heartbeat was not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ClockError {
    /// No heartbeat with this sequence number is awaiting its answer (never sent, or sent
    /// more than [`PENDING_LEN`] heartbeats ago).
    #[error("answer to heartbeat {seq}, which is not awaiting an answer")]
    Unmatched {
        /// The answer's sequence number.
        seq: u64,
    },
    /// This heartbeat was already answered.
    #[error("second answer to heartbeat {seq}")]
    Duplicate {
        /// The answer's sequence number.
        seq: u64,
    },
    /// The answer came back before the heartbeat left (`t4 < t1`), or the peer answered
    /// before it received (`t3 < t2`).
    #[error("timestamps out of order: t1 {t1}, t2 {t2}, t3 {t3}, t4 {t4}")]
    OutOfOrder {
        /// Sent by this side, local clock.
        t1: i64,
        /// Received by the peer, peer's clock.
        t2: i64,
        /// Answered by the peer, peer's clock.
        t3: i64,
        /// Answer received by this side, local clock.
        t4: i64,
    },
    /// The peer held the heartbeat longer than the whole round trip took.
    #[error("negative round-trip delay: {delay_ns} ns")]
    NegativeDelay {
        /// The round-trip delay computed, ns.
        delay_ns: i64,
    },
    /// The round trip took longer than [`MAX_ROUND_TRIP_NS`], or an interval or the offset
    /// does not fit in 64 bits.
    #[error("absurd exchange: round trip of {round_trip_ns} ns")]
    Absurd {
        /// The round trip computed (saturated to 64 bits), ns.
        round_trip_ns: i64,
    },
}

/// One accepted exchange.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClockSample {
    /// The peer's clock minus the local clock, ns.
    pub offset_ns: i64,
    /// Round-trip delay, the peer's turnaround excluded, ns (never negative).
    pub delay_ns: i64,
    /// When the answer arrived, local clock (`t4`), ns.
    pub received_at_ns: i64,
}

/// Lifetime counts of heartbeats and answers on one link.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HeartbeatCounts {
    /// Heartbeats sent ([`LinkClock::note_sent`]).
    pub sent: u64,
    /// Heartbeats that got an answer (the first answer to each; used or refused).
    pub answered: u64,
    /// Answers used by the filter.
    pub accepted: u64,
    /// Answers refused for their timestamps ([`ClockError::OutOfOrder`],
    /// [`ClockError::NegativeDelay`], [`ClockError::Absurd`]).
    pub refused: u64,
    /// Answers to no heartbeat awaiting one ([`ClockError::Unmatched`]).
    pub unmatched: u64,
    /// Second and later answers to one heartbeat ([`ClockError::Duplicate`]).
    pub duplicates: u64,
}

/// A heartbeat awaiting its answer (or answered, kept to recognise duplicates).
#[derive(Clone, Copy, Debug, Default)]
struct PendingHeartbeat {
    seq: u64,
    sent_at_ns: i64,
    in_use: bool,
    answered: bool,
}

/// The filter's current choice among the kept samples.
#[derive(Clone, Copy, Debug)]
struct Estimate {
    offset_ns: i64,
    delay_ns: i64,
    jitter_ns: i64,
}

/// The clock estimate of one link, kept by the side that sends heartbeats.
///
/// Feed it [`note_sent`](Self::note_sent) for every heartbeat and
/// [`note_answer`](Self::note_answer) for every answer; read the estimate with
/// [`offset`](Self::offset), [`delay`](Self::delay), [`jitter`](Self::jitter) and the link's
/// health with [`loss_ratio`](Self::loss_ratio) and [`last_heard`](Self::last_heard).
#[derive(Clone, Debug)]
pub struct LinkClock {
    pending: [PendingHeartbeat; PENDING_LEN],
    ring: [ClockSample; FILTER_LEN],
    /// Index in `ring` of the oldest kept sample.
    ring_start: usize,
    ring_len: usize,
    estimate: Option<Estimate>,
    counts: HeartbeatCounts,
}

impl Default for LinkClock {
    fn default() -> Self {
        LinkClock::new()
    }
}

impl LinkClock {
    /// A link that has exchanged nothing yet: no estimate.
    pub fn new() -> Self {
        LinkClock {
            pending: [PendingHeartbeat::default(); PENDING_LEN],
            ring: [ClockSample::default(); FILTER_LEN],
            ring_start: 0,
            ring_len: 0,
            estimate: None,
            counts: HeartbeatCounts::default(),
        }
    }

    /// Records that heartbeat `seq` left at `t1_ns` (local clock). Sequence numbers should
    /// increase by one per heartbeat: a heartbeat takes the place of the one sent
    /// [`PENDING_LEN`] before it, which can no longer be answered.
    pub fn note_sent(&mut self, seq: u64, t1_ns: i64) {
        self.counts.sent = self.counts.sent.saturating_add(1);
        self.pending[pending_slot(seq)] = PendingHeartbeat {
            seq,
            sent_at_ns: t1_ns,
            in_use: true,
            answered: false,
        };
    }

    /// Takes the answer to heartbeat `seq`: received by the peer at `t2_ns` and answered at
    /// `t3_ns` (peer's clock), received here at `t4_ns` (local clock). Returns the exchange
    /// as the filter kept it.
    ///
    /// # Errors
    /// [`ClockError::Unmatched`] and [`ClockError::Duplicate`] for answers to no heartbeat
    /// awaiting one; [`ClockError::OutOfOrder`], [`ClockError::NegativeDelay`] and
    /// [`ClockError::Absurd`] for timestamps no real exchange gives. Each is counted
    /// ([`counts`](Self::counts)) and leaves the estimate as it was.
    pub fn note_answer(
        &mut self,
        seq: u64,
        t2_ns: i64,
        t3_ns: i64,
        t4_ns: i64,
    ) -> Result<ClockSample, ClockError> {
        let slot = &mut self.pending[pending_slot(seq)];
        if !slot.in_use || slot.seq != seq {
            self.counts.unmatched = self.counts.unmatched.saturating_add(1);
            return Err(ClockError::Unmatched { seq });
        }
        if slot.answered {
            self.counts.duplicates = self.counts.duplicates.saturating_add(1);
            return Err(ClockError::Duplicate { seq });
        }
        slot.answered = true;
        let t1_ns = slot.sent_at_ns;
        self.counts.answered = self.counts.answered.saturating_add(1);
        match exchange(t1_ns, t2_ns, t3_ns, t4_ns) {
            Ok(sample) => {
                self.counts.accepted = self.counts.accepted.saturating_add(1);
                self.keep(sample);
                Ok(sample)
            }
            Err(error) => {
                self.counts.refused = self.counts.refused.saturating_add(1);
                Err(error)
            }
        }
    }

    /// The peer's clock minus the local clock, ns: the offset of the kept exchange with the
    /// least round-trip delay. `None` before the first accepted exchange.
    pub fn offset(&self) -> Option<i64> {
        self.estimate.map(|e| e.offset_ns)
    }

    /// The round-trip delay of the exchange the offset comes from, ns.
    pub fn delay(&self) -> Option<i64> {
        self.estimate.map(|e| e.delay_ns)
    }

    /// The one-way delay estimate, ns: half the round trip of [`delay`](Self::delay).
    pub fn one_way_delay(&self) -> Option<i64> {
        self.estimate.map(|e| e.delay_ns / 2)
    }

    /// The RMS of the kept offsets around the chosen one, ns (0 with one sample).
    pub fn jitter(&self) -> Option<i64> {
        self.estimate.map(|e| e.jitter_ns)
    }

    /// The kept exchanges, oldest first (at most [`FILTER_LEN`]).
    pub fn samples(&self) -> impl ExactSizeIterator<Item = ClockSample> + '_ {
        (0..self.ring_len).map(|i| self.ring[(self.ring_start + i) % FILTER_LEN])
    }

    /// How long ago, ns, the last accepted answer arrived, for a local time `now_ns`
    /// (0 if `now_ns` is earlier). `None` if no answer was ever accepted.
    pub fn last_heard(&self, now_ns: i64) -> Option<i64> {
        let newest = self.samples().last()?;
        Some(now_ns.saturating_sub(newest.received_at_ns).max(0))
    }

    /// The share of heartbeats sent that got no answer, over the link's life, in `0..=1`
    /// (0 before the first heartbeat). A heartbeat still on its way counts as unanswered
    /// until its answer comes.
    pub fn loss_ratio(&self) -> f64 {
        let HeartbeatCounts { sent, answered, .. } = self.counts;
        if sent == 0 {
            return 0.0;
        }
        (sent.saturating_sub(answered) as f64 / sent as f64).clamp(0.0, 1.0)
    }

    /// Lifetime counts of heartbeats and answers.
    pub fn counts(&self) -> HeartbeatCounts {
        self.counts
    }

    /// A local time on the common clock (the peer's): `local_ns` + offset. `None` before the
    /// first accepted exchange or if the sum does not fit in 64 bits.
    pub fn to_common(&self, local_ns: i64) -> Option<i64> {
        local_ns.checked_add(self.offset()?)
    }

    /// A time on the common clock (the peer's) as a local time: `common_ns` − offset. `None`
    /// before the first accepted exchange or if the difference does not fit in 64 bits.
    pub fn from_common(&self, common_ns: i64) -> Option<i64> {
        common_ns.checked_sub(self.offset()?)
    }

    /// Keeps an accepted sample (dropping the oldest when full) and chooses again.
    fn keep(&mut self, sample: ClockSample) {
        if self.ring_len < FILTER_LEN {
            self.ring[(self.ring_start + self.ring_len) % FILTER_LEN] = sample;
            self.ring_len += 1;
        } else {
            self.ring[self.ring_start] = sample;
            self.ring_start = (self.ring_start + 1) % FILTER_LEN;
        }
        self.estimate = self.choose();
    }

    /// NTP's clock filter: the least-delay kept sample (the newest among equals), and the RMS
    /// of the other offsets around its offset.
    fn choose(&self) -> Option<Estimate> {
        let best = self
            .samples()
            .enumerate()
            .min_by_key(|&(age_rank, s)| (s.delay_ns, std::cmp::Reverse(age_rank)))
            .map(|(_, s)| s)?;
        let others = self.ring_len.saturating_sub(1);
        let jitter_ns = if others == 0 {
            0
        } else {
            let sum_of_squares: f64 = self
                .samples()
                .map(|s| {
                    let d = (s.offset_ns as f64) - (best.offset_ns as f64);
                    d * d
                })
                .sum();
            (sum_of_squares / others as f64)
                .sqrt()
                .round()
                .min(i64::MAX as f64) as i64
        };
        Some(Estimate {
            offset_ns: best.offset_ns,
            delay_ns: best.delay_ns,
            jitter_ns,
        })
    }
}

/// The slot of heartbeat `seq` in the pending table.
fn pending_slot(seq: u64) -> usize {
    (seq % PENDING_LEN as u64) as usize
}

/// One exchange's offset and delay, or why its timestamps cannot be real. Computed in 128
/// bits, so no input overflows.
fn exchange(t1: i64, t2: i64, t3: i64, t4: i64) -> Result<ClockSample, ClockError> {
    let (w1, w2, w3, w4) = (t1 as i128, t2 as i128, t3 as i128, t4 as i128);
    if w4 < w1 || w3 < w2 {
        return Err(ClockError::OutOfOrder { t1, t2, t3, t4 });
    }
    let delay = (w4 - w1) - (w3 - w2);
    let saturated = |v: i128| v.clamp(i64::MIN as i128, i64::MAX as i128) as i64;
    if delay < 0 {
        return Err(ClockError::NegativeDelay {
            delay_ns: saturated(delay),
        });
    }
    if delay > MAX_ROUND_TRIP_NS as i128 {
        return Err(ClockError::Absurd {
            round_trip_ns: saturated(delay),
        });
    }
    let offset = ((w2 - w1) + (w3 - w4)) / 2;
    let offset_ns = i64::try_from(offset).map_err(|_| ClockError::Absurd {
        round_trip_ns: saturated(delay),
    })?;
    Ok(ClockSample {
        offset_ns,
        delay_ns: delay as i64,
        received_at_ns: t4,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// One heartbeat exchange between A (local, true time) and B (A's time + `offset_ns`),
    /// with the given one-way delays and a peer turnaround of 20 µs.
    fn exchange_with(
        clock: &mut LinkClock,
        seq: u64,
        t1: i64,
        offset_ns: i64,
        forward_ns: i64,
        back_ns: i64,
    ) -> Result<ClockSample, ClockError> {
        let turnaround = 20_000;
        clock.note_sent(seq, t1);
        let t2 = t1 + forward_ns + offset_ns;
        let t3 = t2 + turnaround;
        let t4 = t1 + forward_ns + turnaround + back_ns;
        clock.note_answer(seq, t2, t3, t4)
    }

    /// Exponentially distributed queueing delay with the given mean, ns.
    fn queueing(rng: &mut ChaCha8Rng, mean_ns: f64) -> i64 {
        let u: f64 = rng.random::<f64>().max(f64::MIN_POSITIVE);
        (-u.ln() * mean_ns) as i64
    }

    #[test]
    fn injected_offset_is_recovered_within_100_microseconds() {
        let injected = 3_700_000; // +3.7 ms
        let (mut worst_filtered, mut worst_single) = (0i64, 0i64);
        let (mut error_sum, mut estimates) = (0i64, 0i64);
        for seed in 0..10 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut clock = LinkClock::new();
            let mut t1 = 1_000_000_000;
            for seq in 0..2_000u64 {
                // symmetric base delay of 150 µs each way, independent queueing jitter per
                // direction (exponential, mean 50 µs) and, one heartbeat in 20, a 5 ms spike
                // one way; a heartbeat every 10 ms.
                let mut forward = 150_000 + queueing(&mut rng, 50_000.0);
                let back = 150_000 + queueing(&mut rng, 50_000.0);
                if rng.random_ratio(1, 20) {
                    forward += 5_000_000;
                }
                let sample = exchange_with(&mut clock, seq, t1, injected, forward, back).unwrap();
                worst_single = worst_single.max((sample.offset_ns - injected).abs());
                if seq as usize >= FILTER_LEN {
                    let error = (clock.offset().unwrap() - injected).abs();
                    worst_filtered = worst_filtered.max(error);
                    error_sum += error;
                    estimates += 1;
                }
                t1 += 10_000_000;
            }
            // the estimate converts local times to the peer's clock and back
            let local = 5_000_000_000;
            let common = clock.to_common(local).unwrap();
            assert_eq!(common - local, clock.offset().unwrap());
            assert_eq!(clock.from_common(common), Some(local));
        }
        eprintln!(
            "offset +3.7 ms, 10 seeds x 2000 exchanges: filtered error mean {} ns, worst {} ns; \
             worst single exchange {} ns",
            error_sum / estimates,
            worst_filtered,
            worst_single
        );
        assert!(
            worst_filtered < 100_000,
            "filtered error {worst_filtered} ns"
        );
        // the filter earns its place: single exchanges are far worse
        assert!(
            worst_single > 1_000_000,
            "single exchange error {worst_single} ns"
        );
    }

    #[test]
    fn the_least_delay_sample_is_chosen() {
        let mut clock = LinkClock::new();
        // (forward, back) one-way delays, µs: asymmetric and jittery; the third has the least
        // round trip (100 + 60) and so an offset error of (100 − 60) / 2 = 20 µs.
        let delays = [
            (400, 300),
            (900, 100),
            (100, 60),
            (250, 250),
            (80, 500),
            (3_000, 40),
            (120, 90),
            (700, 700),
        ];
        for (seq, &(forward, back)) in delays.iter().enumerate() {
            let t1 = 1_000_000 * seq as i64;
            exchange_with(
                &mut clock,
                seq as u64,
                t1,
                2_000_000,
                forward * 1_000,
                back * 1_000,
            )
            .unwrap();
        }
        assert_eq!(clock.samples().len(), FILTER_LEN);
        assert_eq!(clock.delay(), Some(160_000));
        assert_eq!(clock.one_way_delay(), Some(80_000));
        assert_eq!(clock.offset(), Some(2_000_000 + 20_000));
        let jitter = clock.jitter().unwrap();
        assert!(jitter > 0);
        // the jitter is the RMS of the other offsets around the chosen one
        let chosen = clock.offset().unwrap() as f64;
        let rms = (clock
            .samples()
            .map(|s| (s.offset_ns as f64 - chosen).powi(2))
            .sum::<f64>()
            / (FILTER_LEN - 1) as f64)
            .sqrt();
        assert_eq!(jitter, rms.round() as i64);

        // once the least-delay sample ages out of the window, the next best is chosen
        for seq in 8..10u64 {
            let t1 = 1_000_000 * seq as i64;
            exchange_with(&mut clock, seq, t1, 2_000_000, 1_000_000, 1_000_000).unwrap();
        }
        assert_eq!(
            clock.delay(),
            Some(160_000),
            "third sample still in the window"
        );
        let t1 = 10_000_000;
        exchange_with(&mut clock, 10, t1, 2_000_000, 1_000_000, 1_000_000).unwrap();
        assert_eq!(clock.delay(), Some(210_000), "(120, 90) is now the least");
        assert_eq!(clock.offset(), Some(2_000_000 + 15_000));
    }

    #[test]
    fn losses_and_stray_answers_are_counted() {
        let mut clock = LinkClock::new();
        assert_eq!(clock.loss_ratio(), 0.0);
        assert_eq!(clock.offset(), None);
        assert_eq!(clock.last_heard(0), None);
        assert_eq!(clock.to_common(0), None);
        for seq in 0..100u64 {
            let t1 = seq as i64 * 1_000_000;
            clock.note_sent(seq, t1);
            if seq % 10 != 3 {
                clock
                    .note_answer(seq, t1 + 100, t1 + 200, t1 + 300)
                    .unwrap();
            }
        }
        assert!((clock.loss_ratio() - 0.10).abs() < 1e-12);
        // an answer twice, an answer to a heartbeat never sent, one too old to match
        assert_eq!(
            clock.note_answer(99, 0, 0, 0),
            Err(ClockError::Duplicate { seq: 99 })
        );
        assert_eq!(
            clock.note_answer(500, 0, 0, 0),
            Err(ClockError::Unmatched { seq: 500 })
        );
        assert_eq!(
            clock.note_answer(3, 0, 0, 0),
            Err(ClockError::Unmatched { seq: 3 })
        );
        let counts = clock.counts();
        assert_eq!(
            (
                counts.sent,
                counts.answered,
                counts.accepted,
                counts.duplicates,
                counts.unmatched
            ),
            (100, 90, 90, 1, 2)
        );
        // neither changed the estimate or the loss
        assert_eq!(clock.offset(), Some(0));
        assert!((clock.loss_ratio() - 0.10).abs() < 1e-12);
        assert_eq!(clock.last_heard(99_000_300 + 42), Some(42));
        assert_eq!(clock.last_heard(0), Some(0));
    }

    #[test]
    fn garbage_timestamps_are_refused() {
        let mut clock = LinkClock::new();
        let t1 = 1_000_000;
        let cases = [
            // answer before the heartbeat left
            (0, 1_000, 2_000, t1 - 1, "out of order"),
            // peer answered before it received
            (1, 5_000, 4_000, t1 + 10_000, "out of order"),
            // peer held it longer than the round trip
            (2, 0, 50_000, t1 + 10_000, "negative delay"),
            // a round trip of a minute
            (3, 0, 0, t1 + 60_000_000_000, "absurd"),
            // extremes that overflow 64-bit arithmetic
            (4, i64::MAX, i64::MAX, i64::MAX, "absurd"),
            (5, i64::MIN, i64::MIN, t1, "absurd"),
        ];
        for (seq, t2, t3, t4, what) in cases {
            clock.note_sent(seq, t1);
            let refused = clock.note_answer(seq, t2, t3, t4);
            let expected = match refused {
                Err(ClockError::OutOfOrder { .. }) => "out of order",
                Err(ClockError::NegativeDelay { .. }) => "negative delay",
                Err(ClockError::Absurd { .. }) => "absurd",
                other => panic!("seq {seq}: {other:?}"),
            };
            assert_eq!(expected, what, "seq {seq}");
        }
        assert_eq!(clock.offset(), None);
        assert_eq!(clock.samples().len(), 0);
        assert_eq!(clock.counts().refused, 6);
        // refused answers still came back: not lost
        assert_eq!(clock.loss_ratio(), 0.0);
    }

    /// An operation on a link clock, for the property test.
    #[derive(Clone, Debug)]
    enum Op {
        Sent(u64, i64),
        Answer(u64, i64, i64, i64),
        Read(i64),
    }

    fn op() -> impl Strategy<Value = Op> {
        let seq = prop_oneof![0u64..80, any::<u64>()];
        let time = prop_oneof![-1_000_000i64..1_000_000_000, any::<i64>()];
        prop_oneof![
            (seq.clone(), time.clone()).prop_map(|(s, t)| Op::Sent(s, t)),
            (seq, time.clone(), time.clone(), time.clone())
                .prop_map(|(s, a, b, c)| Op::Answer(s, a, b, c)),
            time.prop_map(Op::Read),
        ]
    }

    proptest! {
        #[test]
        fn never_panics_and_stays_consistent(ops in prop::collection::vec(op(), 0..200)) {
            let mut clock = LinkClock::new();
            for op in ops {
                match op {
                    Op::Sent(seq, t1) => clock.note_sent(seq, t1),
                    Op::Answer(seq, t2, t3, t4) => {
                        if let Ok(sample) = clock.note_answer(seq, t2, t3, t4) {
                            prop_assert!((0..=MAX_ROUND_TRIP_NS).contains(&sample.delay_ns));
                        }
                    }
                    Op::Read(now) => {
                        let _ = clock.last_heard(now);
                        let _ = clock.to_common(now);
                        let _ = clock.from_common(now);
                    }
                }
                prop_assert!(clock.samples().len() <= FILTER_LEN);
                prop_assert!((0.0..=1.0).contains(&clock.loss_ratio()));
                if let Some(delay) = clock.delay() {
                    prop_assert!(delay >= 0);
                    prop_assert!(clock.jitter().unwrap() >= 0);
                    prop_assert!(clock.samples().any(|s| s.delay_ns == delay));
                }
                let counts = clock.counts();
                prop_assert_eq!(counts.answered, counts.accepted + counts.refused);
            }
        }
    }
}
