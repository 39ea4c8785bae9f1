//! The driver's frame counter (`v4l2_buffer.sequence`): a gap is frames the driver lost (no
//! free buffer, a USB error), counted apart from the frames this reader dropped itself.

/// Follows `v4l2_buffer.sequence` across dequeued buffers.
#[derive(Clone, Debug, Default)]
pub struct SequenceTracker {
    last: Option<u32>,
}

impl SequenceTracker {
    /// A tracker that has seen no buffer.
    pub fn new() -> Self {
        SequenceTracker::default()
    }

    /// Records the next dequeued buffer's sequence number; returns how many frames the driver
    /// lost before it (0 when it follows the previous one; a repeated or backwards number, which
    /// a driver restarting its count gives, is 0 and restarts the count).
    pub fn observe(&mut self, sequence: u32) -> u64 {
        let lost = match self.last {
            // Forward distance modulo 2^32: the counter wraps after ~2 years at 60 fps.
            Some(last) => {
                let step = sequence.wrapping_sub(last);
                if step == 0 || step > u32::MAX / 2 {
                    0
                } else {
                    u64::from(step - 1)
                }
            }
            None => 0,
        };
        self.last = Some(sequence);
        lost
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn consecutive_sequence_numbers_lose_nothing() {
        let mut t = SequenceTracker::new();
        assert_eq!(t.observe(5), 0);
        assert_eq!(t.observe(6), 0);
        assert_eq!(t.observe(7), 0);
    }

    #[test]
    fn sequence_gap_counts_the_frames_the_driver_lost() {
        let mut t = SequenceTracker::new();
        t.observe(10);
        assert_eq!(t.observe(14), 3);
        assert_eq!(t.observe(15), 0);
    }

    #[test]
    fn sequence_wrap_is_a_step_and_a_restart_is_no_loss() {
        let mut t = SequenceTracker::new();
        t.observe(u32::MAX);
        assert_eq!(t.observe(1), 1);
        assert_eq!(t.observe(0), 0, "a counter restarted by the driver");
        assert_eq!(t.observe(1), 0);
    }
}
