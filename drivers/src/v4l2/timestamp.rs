//! A dequeued buffer's kernel timestamp mapped onto the node's monotonic clock: the capture
//! instant (the middle of the exposure), or, when the stamp cannot be trusted, the dequeue time
//! less a configured latency, with the reason said (never a silently wrong stamp).
//!
//! Pure functions of the buffer's fields and the node's clock, so that every case is tested with
//! made-up buffers.

/// `V4L2_BUF_FLAG_TIMESTAMP_MASK`: which clock the timestamp is on.
pub const FLAG_TIMESTAMP_MASK: u32 = 0x0000_e000;
/// `V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN`: an unknown clock.
pub const FLAG_TIMESTAMP_UNKNOWN: u32 = 0x0000_0000;
/// `V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC`: `CLOCK_MONOTONIC`, the node's clock.
pub const FLAG_TIMESTAMP_MONOTONIC: u32 = 0x0000_2000;
/// `V4L2_BUF_FLAG_TIMESTAMP_COPY`: copied from an output buffer (not a capture instant).
pub const FLAG_TIMESTAMP_COPY: u32 = 0x0000_4000;
/// `V4L2_BUF_FLAG_TSTAMP_SRC_MASK`: which event of the frame was stamped.
pub const FLAG_TSTAMP_SRC_MASK: u32 = 0x0007_0000;
/// `V4L2_BUF_FLAG_TSTAMP_SRC_EOF`: the end of the frame (its last byte received). Zero: a
/// driver that says nothing says end of frame.
pub const FLAG_TSTAMP_SRC_EOF: u32 = 0x0000_0000;
/// `V4L2_BUF_FLAG_TSTAMP_SRC_SOE`: the start of the exposure.
pub const FLAG_TSTAMP_SRC_SOE: u32 = 0x0001_0000;
/// `V4L2_BUF_FLAG_ERROR`: the driver says the data may be corrupted.
pub const FLAG_ERROR: u32 = 0x0000_0040;

/// What a dequeued `v4l2_buffer` says about its frame's time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferStamp {
    /// `v4l2_buffer.timestamp`, in ns (`tv_sec * 1e9 + tv_usec * 1e3`).
    pub timestamp_ns: u64,
    /// `v4l2_buffer.flags`.
    pub flags: u32,
    /// `v4l2_buffer.sequence`: the driver's frame counter.
    pub sequence: u32,
}

impl BufferStamp {
    /// From the kernel's `struct timeval` fields; a negative time (never a real stamp) is 0.
    pub fn from_timeval(sec: i64, usec: i64, flags: u32, sequence: u32) -> Self {
        let ns = sec
            .max(0)
            .saturating_mul(1_000_000_000)
            .saturating_add(usec.clamp(0, 999_999) * 1_000);
        BufferStamp {
            timestamp_ns: ns as u64,
            flags,
            sequence,
        }
    }

    /// Whether the stamp is on `CLOCK_MONOTONIC`.
    pub fn is_monotonic_clock(&self) -> bool {
        self.flags & FLAG_TIMESTAMP_MASK == FLAG_TIMESTAMP_MONOTONIC
    }

    /// Whether the stamp is the start of the exposure (else the end of the frame).
    pub fn is_start_of_exposure(&self) -> bool {
        self.flags & FLAG_TSTAMP_SRC_MASK == FLAG_TSTAMP_SRC_SOE
    }
}

/// Why a kernel stamp was not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FallbackReason {
    /// The stamp is not on `CLOCK_MONOTONIC` (unknown clock or copied).
    NotMonotonicClock,
    /// The stamp is later than the dequeue (beyond the tolerance).
    InFuture,
    /// The stamp is older than the configured bound before the dequeue.
    TooOld,
    /// The stamp is not after the previous frame's.
    Backwards,
}

impl FallbackReason {
    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            FallbackReason::NotMonotonicClock => "not-monotonic-clock",
            FallbackReason::InFuture => "in-future",
            FallbackReason::TooOld => "too-old",
            FallbackReason::Backwards => "backwards",
        }
    }
}

/// Where a frame's capture instant came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TimestampSource {
    /// The kernel stamped the start of the exposure.
    StartOfExposure,
    /// The kernel stamped the end of the frame.
    EndOfFrame,
    /// The kernel's stamp was not used: the dequeue time less the configured latency.
    Fallback(FallbackReason),
}

impl TimestampSource {
    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            TimestampSource::StartOfExposure => "kernel start-of-exposure",
            TimestampSource::EndOfFrame => "kernel end-of-frame",
            TimestampSource::Fallback(r) => r.name(),
        }
    }
}

/// How stamps are turned into capture instants (all in ns).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StampPolicy {
    /// The sensor's readout: from the end of the exposure to the end of the frame (used for
    /// end-of-frame stamps).
    pub readout_ns: u64,
    /// From the capture instant to the dequeue, assumed when the kernel's stamp is not used.
    pub fallback_latency_ns: u64,
    /// A stamp more than this before its dequeue is refused.
    pub max_age_ns: u64,
    /// A stamp at most this after its dequeue is still accepted (clock reads are not atomic
    /// with the kernel's; 1 ms is plenty).
    pub future_tolerance_ns: u64,
}

/// A frame's capture instant on the node's monotonic clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CaptureInstant {
    /// The middle of the exposure (or the fallback's estimate), ns.
    pub capture_ns: u64,
    /// Where it came from.
    pub source: TimestampSource,
    /// Whether the exposure time was known (else the stamp's offset to the middle of the
    /// exposure leaves out half the exposure).
    pub exposure_known: bool,
}

/// The capture instant of a buffer dequeued at `dequeued_ns` (node monotonic clock).
///
/// `exposure_ns` is the exposure the driver reports (`V4L2_CID_EXPOSURE_ABSOLUTE`), if any;
/// `previous_stamp_ns` the previous accepted kernel stamp of this stream, if any.
///
/// - start of exposure: `stamp + exposure/2`;
/// - end of frame: `stamp - readout - exposure/2`;
/// - an unknown exposure counts as 0 (the stamp's own event, with `exposure_known` false);
/// - a stamp not on the monotonic clock, later than the dequeue, older than `max_age_ns` or not
///   after the previous one: `dequeued - fallback_latency`, with the reason.
pub fn capture_instant(
    stamp: &BufferStamp,
    dequeued_ns: u64,
    exposure_ns: Option<u64>,
    previous_stamp_ns: Option<u64>,
    policy: &StampPolicy,
) -> CaptureInstant {
    let exposure_known = exposure_ns.is_some();
    let fallback = |reason| CaptureInstant {
        capture_ns: dequeued_ns.saturating_sub(policy.fallback_latency_ns),
        source: TimestampSource::Fallback(reason),
        exposure_known,
    };
    if !stamp.is_monotonic_clock() {
        return fallback(FallbackReason::NotMonotonicClock);
    }
    let t = stamp.timestamp_ns;
    if t > dequeued_ns.saturating_add(policy.future_tolerance_ns) {
        return fallback(FallbackReason::InFuture);
    }
    if dequeued_ns.saturating_sub(t) > policy.max_age_ns {
        return fallback(FallbackReason::TooOld);
    }
    if previous_stamp_ns.is_some_and(|p| t <= p) {
        return fallback(FallbackReason::Backwards);
    }
    let half_exposure = exposure_ns.unwrap_or(0) / 2;
    let (capture_ns, source) = if stamp.is_start_of_exposure() {
        (
            t.saturating_add(half_exposure),
            TimestampSource::StartOfExposure,
        )
    } else {
        (
            t.saturating_sub(policy.readout_ns)
                .saturating_sub(half_exposure),
            TimestampSource::EndOfFrame,
        )
    };
    CaptureInstant {
        capture_ns,
        source,
        exposure_known,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    fn policy() -> StampPolicy {
        StampPolicy {
            readout_ns: 10 * MS,
            fallback_latency_ns: 40 * MS,
            max_age_ns: 500 * MS,
            future_tolerance_ns: MS,
        }
    }

    fn stamp(t: u64, flags: u32) -> BufferStamp {
        BufferStamp {
            timestamp_ns: t,
            flags,
            sequence: 0,
        }
    }

    #[test]
    fn timeval_converts_to_nanoseconds_and_negative_is_zero() {
        let s = BufferStamp::from_timeval(12, 345_678, FLAG_TIMESTAMP_MONOTONIC, 7);
        assert_eq!(s.timestamp_ns, 12_345_678_000);
        assert_eq!(s.sequence, 7);
        assert_eq!(BufferStamp::from_timeval(-1, 5, 0, 0).timestamp_ns, 5_000);
    }

    #[test]
    fn start_of_exposure_stamp_adds_half_the_exposure() {
        let s = stamp(1_000 * MS, FLAG_TIMESTAMP_MONOTONIC | FLAG_TSTAMP_SRC_SOE);
        let c = capture_instant(&s, 1_050 * MS, Some(20 * MS), None, &policy());
        assert_eq!(c.source, TimestampSource::StartOfExposure);
        assert_eq!(c.capture_ns, 1_010 * MS);
        assert!(c.exposure_known);
    }

    #[test]
    fn end_of_frame_stamp_subtracts_readout_and_half_the_exposure() {
        let s = stamp(1_000 * MS, FLAG_TIMESTAMP_MONOTONIC | FLAG_TSTAMP_SRC_EOF);
        let c = capture_instant(&s, 1_005 * MS, Some(20 * MS), None, &policy());
        assert_eq!(c.source, TimestampSource::EndOfFrame);
        assert_eq!(c.capture_ns, 980 * MS);
    }

    #[test]
    fn missing_exposure_uses_the_stamp_and_readout_alone() {
        let soe = stamp(1_000 * MS, FLAG_TIMESTAMP_MONOTONIC | FLAG_TSTAMP_SRC_SOE);
        let c = capture_instant(&soe, 1_050 * MS, None, None, &policy());
        assert_eq!((c.capture_ns, c.exposure_known), (1_000 * MS, false));
        let eof = stamp(1_000 * MS, FLAG_TIMESTAMP_MONOTONIC);
        let c = capture_instant(&eof, 1_050 * MS, None, None, &policy());
        assert_eq!(c.capture_ns, 990 * MS);
        assert_eq!(c.source, TimestampSource::EndOfFrame);
    }

    #[test]
    fn unknown_or_copied_clock_falls_back_to_dequeue_less_latency() {
        for flags in [
            FLAG_TIMESTAMP_UNKNOWN,
            FLAG_TIMESTAMP_COPY | FLAG_TSTAMP_SRC_SOE,
        ] {
            let c = capture_instant(&stamp(1_000 * MS, flags), 1_050 * MS, None, None, &policy());
            assert_eq!(
                c.source,
                TimestampSource::Fallback(FallbackReason::NotMonotonicClock)
            );
            assert_eq!(c.capture_ns, 1_010 * MS);
        }
    }

    #[test]
    fn stamp_in_the_future_falls_back() {
        let s = stamp(1_100 * MS, FLAG_TIMESTAMP_MONOTONIC);
        let c = capture_instant(&s, 1_050 * MS, None, None, &policy());
        assert_eq!(
            c.source,
            TimestampSource::Fallback(FallbackReason::InFuture)
        );
        assert_eq!(c.capture_ns, 1_010 * MS);
        // within the tolerance it is used
        let s = stamp(1_050 * MS + MS / 2, FLAG_TIMESTAMP_MONOTONIC);
        let c = capture_instant(&s, 1_050 * MS, None, None, &policy());
        assert_eq!(c.source, TimestampSource::EndOfFrame);
    }

    #[test]
    fn stamp_older_than_the_bound_falls_back() {
        let s = stamp(1_000 * MS, FLAG_TIMESTAMP_MONOTONIC | FLAG_TSTAMP_SRC_SOE);
        let c = capture_instant(&s, 1_501 * MS, None, None, &policy());
        assert_eq!(c.source, TimestampSource::Fallback(FallbackReason::TooOld));
        assert_eq!(c.capture_ns, 1_461 * MS);
        let c = capture_instant(&s, 1_500 * MS, None, None, &policy());
        assert_eq!(c.source, TimestampSource::StartOfExposure);
    }

    #[test]
    fn backwards_or_repeated_stamp_falls_back() {
        let s = stamp(1_000 * MS, FLAG_TIMESTAMP_MONOTONIC | FLAG_TSTAMP_SRC_SOE);
        for previous in [1_000 * MS, 1_020 * MS] {
            let c = capture_instant(&s, 1_050 * MS, Some(MS), Some(previous), &policy());
            assert_eq!(
                c.source,
                TimestampSource::Fallback(FallbackReason::Backwards)
            );
        }
        let c = capture_instant(&s, 1_050 * MS, Some(MS), Some(967 * MS), &policy());
        assert_eq!(c.source, TimestampSource::StartOfExposure);
    }
}
