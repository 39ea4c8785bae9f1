//! Trajectories: what produces a controller's reference at time t (the paper's `getReferiment`).

use core::fmt;

use crate::error::{Error, ErrorKind};
use crate::reference::Reference;
use crate::time::Timestamp;

/// Why a trajectory has no reference to give.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TrajectoryError {
    /// [`Trajectory::start`] was not called yet.
    NotStarted,
    /// A streamed trajectory (the teleop channel) has received nothing yet.
    NoData,
}

impl fmt::Display for TrajectoryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            TrajectoryError::NotStarted => "trajectory not started",
            TrajectoryError::NoData => "no reference received yet",
        })
    }
}

impl Error for TrajectoryError {
    fn kind(&self) -> ErrorKind {
        match self {
            TrajectoryError::NotStarted => ErrorKind::WrongState,
            TrajectoryError::NoData => ErrorKind::Timeout,
        }
    }
}

/// A source of references.
///
/// # Real-time
/// [`reference`](Trajectory::reference) may be called from the communication thread or the
/// control thread: no allocation, no blocking, bounded time.
pub trait Trajectory {
    /// The trajectory's kind, for example `"spline"`.
    fn kind(&self) -> &'static str;

    /// Starts the trajectory at `now` from `from` (typically the measured state, so nothing jumps).
    fn start(&mut self, now: Timestamp, from: &Reference);

    /// The reference at time `now`. After the end, the final reference is held.
    ///
    /// # Errors
    /// [`TrajectoryError`] when there is nothing to give.
    fn reference(&mut self, now: Timestamp) -> Result<Reference, TrajectoryError>;

    /// True once `now` is past the end (never, for a streamed channel).
    fn is_finished(&self, now: Timestamp) -> bool;
}
