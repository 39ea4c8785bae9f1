//! A stream's timing state: the driver's sequence numbers and the previous kernel stamp, turning
//! each dequeued buffer into a capture instant and counting what went wrong.

use super::sequence::SequenceTracker;
use super::stats::CaptureStats;
use super::timestamp::{
    BufferStamp, CaptureInstant, StampPolicy, TimestampSource, capture_instant,
};

/// Stamps a stream's buffers in dequeue order.
#[derive(Clone, Debug)]
pub struct FrameStamper {
    policy: StampPolicy,
    sequence: SequenceTracker,
    previous_stamp_ns: Option<u64>,
    previous_capture_ns: Option<u64>,
}

impl FrameStamper {
    /// A stamper that has seen no buffer.
    pub fn new(policy: StampPolicy) -> Self {
        FrameStamper {
            policy,
            sequence: SequenceTracker::new(),
            previous_stamp_ns: None,
            previous_capture_ns: None,
        }
    }

    /// Every dequeued buffer, used or dropped: counts the frames the driver lost before it.
    pub fn dequeued(&mut self, stamp: &BufferStamp, stats: &mut CaptureStats) {
        stats.lost_by_driver += self.sequence.observe(stamp.sequence);
    }

    /// A buffer handed out as a frame: its capture instant, counted by source. Only accepted
    /// kernel stamps become the reference for the next one's backwards check. A fallback's
    /// estimate is kept after the previous frame's capture instant (frames are captured in
    /// order; the estimate's latency is a guess, the order is not).
    pub fn stamp(
        &mut self,
        stamp: &BufferStamp,
        dequeued_ns: u64,
        exposure_ns: Option<u64>,
        stats: &mut CaptureStats,
    ) -> CaptureInstant {
        let mut instant = capture_instant(
            stamp,
            dequeued_ns,
            exposure_ns,
            self.previous_stamp_ns,
            &self.policy,
        );
        match (instant.source, self.previous_capture_ns) {
            (TimestampSource::Fallback(_), Some(previous)) => {
                instant.capture_ns = instant.capture_ns.max(previous + 1);
            }
            (TimestampSource::Fallback(_), None) => {}
            _ => self.previous_stamp_ns = Some(stamp.timestamp_ns),
        }
        self.previous_capture_ns = Some(instant.capture_ns);
        stats.count_source(instant.source);
        instant
    }
}

#[cfg(test)]
mod tests {
    use super::super::timestamp::{
        FLAG_TIMESTAMP_COPY, FLAG_TIMESTAMP_MONOTONIC, FLAG_TSTAMP_SRC_SOE, FallbackReason,
    };
    use super::*;

    const MS: u64 = 1_000_000;
    const SOE: u32 = FLAG_TIMESTAMP_MONOTONIC | FLAG_TSTAMP_SRC_SOE;

    fn policy() -> StampPolicy {
        StampPolicy {
            readout_ns: 10 * MS,
            fallback_latency_ns: 40 * MS,
            max_age_ns: 500 * MS,
            future_tolerance_ns: MS,
        }
    }

    fn buffer(sequence: u32, t_ms: u64, flags: u32) -> BufferStamp {
        BufferStamp {
            timestamp_ns: t_ms * MS,
            flags,
            sequence,
        }
    }

    /// A 30 fps stream of made-up buffers: a driver gap, a backwards step, a copied clock.
    #[test]
    fn stream_of_buffers_counts_driver_gaps_backwards_steps_and_fallbacks() {
        let mut stamper = FrameStamper::new(policy());
        let mut stats = CaptureStats::default();
        let mut out = Vec::new();
        let buffers = [
            buffer(0, 1_000, SOE),
            buffer(1, 1_033, SOE),
            buffer(4, 1_133, SOE),                      // driver lost 2, 3
            buffer(5, 1_120, SOE),                      // stamp went backwards
            buffer(6, 1_200, SOE),                      // good again
            buffer(7, 1_233, FLAG_TIMESTAMP_COPY),      // not a capture clock
            buffer(8, 1_266, FLAG_TIMESTAMP_MONOTONIC), // end of frame
        ];
        for b in &buffers {
            stamper.dequeued(b, &mut stats);
            let dequeued = b.timestamp_ns + 45 * MS;
            out.push(stamper.stamp(b, dequeued, Some(20 * MS), &mut stats));
        }
        assert_eq!(stats.lost_by_driver, 2);
        assert_eq!(stats.fallback_backwards, 1);
        assert_eq!(stats.fallback_not_monotonic, 1);
        assert_eq!(stats.stamped_start_of_exposure, 4);
        assert_eq!(stats.stamped_end_of_frame, 1);
        assert_eq!(out[0].capture_ns, 1_010 * MS);
        assert_eq!(
            out[3].source,
            TimestampSource::Fallback(FallbackReason::Backwards)
        );
        // dequeued 1165 less 40 is 1125, before the previous frame's 1143: kept just after it
        assert_eq!(out[3].capture_ns, 1_143 * MS + 1);
        assert_eq!(out[5].capture_ns, 1_238 * MS); // dequeued 1278 less 40
        // after the refused stamp, the next is judged against the last accepted one (1133)
        assert_eq!(out[4].source, TimestampSource::StartOfExposure);
        assert_eq!(out[6].capture_ns, 1_266 * MS - 10 * MS - 10 * MS);
        // capture instants strictly increase across the whole stream here
        assert!(out.windows(2).all(|w| w[1].capture_ns > w[0].capture_ns));
    }

    #[test]
    fn dropped_buffers_still_count_for_driver_gaps() {
        let mut stamper = FrameStamper::new(policy());
        let mut stats = CaptureStats::default();
        // 10, 11 dequeued but dropped behind 12: no loss; then 15: 2 lost
        for seq in [10, 11, 12, 15] {
            stamper.dequeued(&buffer(seq, 1_000 + u64::from(seq), SOE), &mut stats);
        }
        assert_eq!(stats.lost_by_driver, 2);
        assert_eq!(stats.frames, 0);
    }
}
