//! The hand-off of a simulated plant's true state to its readers: the virtual force sensor and
//! ground-truth telemetry.
//!
//! Each reader gets its own lock-free latest-value cell ([`penelope_rt_core::cell`]), so a
//! board publishing from the control thread never waits for anyone.

use heapless::Vec as FixedVec;
use penelope_hal::{JointState, Pose, Timestamp, Wrench};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, latest};

/// The largest number of readers of one tap.
pub const MAX_TAP_READERS: usize = 4;

/// The plant's true state at one instant.
#[derive(Clone, Copy, Debug, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct TapSample {
    /// When.
    pub time: Timestamp,
    /// True joint positions (rad), velocities (rad/s) and applied motor torques (N·m).
    pub joints: JointState,
    /// True tool pose in the base frame.
    pub tool_pose: Pose,
    /// Wrench applied to the tool by its surroundings, base frame, about the tool origin.
    pub base_wrench: Wrench,
    /// The same wrench in the tool frame.
    pub tool_wrench: Wrench,
    /// Kinetic energy of the robot, J.
    pub kinetic_energy: f64,
    /// Work done on the robot by its surroundings since the start, J.
    pub interaction_work: f64,
}

/// The publishing side, owned by a simulated board.
#[derive(Debug, Default)]
pub struct TapWriter {
    writers: FixedVec<ArcLatestWriter<TapSample>, MAX_TAP_READERS>,
}

/// A reading side.
#[derive(Debug)]
pub struct TapReader {
    reader: ArcLatestReader<TapSample>,
}

/// Too many readers on one tap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TooManyReaders;

impl TapWriter {
    /// A tap with no readers yet.
    pub fn new() -> Self {
        TapWriter::default()
    }

    /// A new reader of this tap (call before the real-time threads start: it allocates a cell).
    ///
    /// # Errors
    /// [`TooManyReaders`] beyond [`MAX_TAP_READERS`].
    pub fn reader(&mut self) -> Result<TapReader, TooManyReaders> {
        let (writer, reader) = latest();
        self.writers.push(writer).map_err(|_| TooManyReaders)?;
        Ok(TapReader { reader })
    }

    /// Publishes `sample` to every reader.
    ///
    /// # Real-time
    /// Wait-free, no allocation.
    pub fn publish(&mut self, sample: TapSample) {
        for w in self.writers.iter_mut() {
            w.write(sample);
        }
    }
}

impl TapReader {
    /// The latest sample, if any was published.
    ///
    /// # Real-time
    /// Wait-free, no allocation.
    pub fn latest(&mut self) -> Option<TapSample> {
        self.reader.latest()
    }
}
