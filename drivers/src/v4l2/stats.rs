//! What a camera counted: frames delivered, lost by the driver, dropped by a reader that fell
//! behind, garbled, and the kernel stamps that were not used and why.

use super::timestamp::{FallbackReason, TimestampSource};

/// A camera's counters since it was opened.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CaptureStats {
    /// Frames handed to the caller.
    pub frames: u64,
    /// Frames the driver lost (gaps in `v4l2_buffer.sequence`).
    pub lost_by_driver: u64,
    /// Frames dequeued but replaced by a newer one before the caller took them (the newest
    /// frame wins).
    pub dropped_behind: u64,
    /// Buffers dropped as garbled (the driver's error flag, a bad JPEG, a short raw frame).
    pub garbled: u64,
    /// Frames stamped at the start of the exposure by the kernel.
    pub stamped_start_of_exposure: u64,
    /// Frames stamped at the end of the frame by the kernel.
    pub stamped_end_of_frame: u64,
    /// Fallbacks (dequeue less latency): the stamp was not on the monotonic clock.
    pub fallback_not_monotonic: u64,
    /// Fallbacks: the stamp was in the future.
    pub fallback_in_future: u64,
    /// Fallbacks: the stamp was older than the bound.
    pub fallback_too_old: u64,
    /// Fallbacks: the stamp was not after the previous one.
    pub fallback_backwards: u64,
    /// MJPEG frames that came without Huffman tables and had the standard ones inserted.
    pub huffman_tables_inserted: u64,
}

impl CaptureStats {
    /// Counts one delivered frame's timestamp source.
    pub fn count_source(&mut self, source: TimestampSource) {
        let counter = match source {
            TimestampSource::StartOfExposure => &mut self.stamped_start_of_exposure,
            TimestampSource::EndOfFrame => &mut self.stamped_end_of_frame,
            TimestampSource::Fallback(FallbackReason::NotMonotonicClock) => {
                &mut self.fallback_not_monotonic
            }
            TimestampSource::Fallback(FallbackReason::InFuture) => &mut self.fallback_in_future,
            TimestampSource::Fallback(FallbackReason::TooOld) => &mut self.fallback_too_old,
            TimestampSource::Fallback(FallbackReason::Backwards) => &mut self.fallback_backwards,
        };
        *counter += 1;
    }

    /// Frames whose capture instant is the dequeue time less the configured latency.
    pub fn fallbacks(&self) -> u64 {
        self.fallback_not_monotonic
            + self.fallback_in_future
            + self.fallback_too_old
            + self.fallback_backwards
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_timestamp_source_has_its_own_counter() {
        let mut s = CaptureStats::default();
        s.count_source(TimestampSource::StartOfExposure);
        s.count_source(TimestampSource::EndOfFrame);
        s.count_source(TimestampSource::Fallback(FallbackReason::Backwards));
        s.count_source(TimestampSource::Fallback(FallbackReason::TooOld));
        s.count_source(TimestampSource::Fallback(FallbackReason::TooOld));
        assert_eq!(s.stamped_start_of_exposure, 1);
        assert_eq!(s.stamped_end_of_frame, 1);
        assert_eq!(s.fallback_backwards, 1);
        assert_eq!(s.fallback_too_old, 2);
        assert_eq!(s.fallbacks(), 3);
    }
}
