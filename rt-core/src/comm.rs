//! The communication loop (period `T_com`): asks a [`Trajectory`] for the reference — a local
//! trajectory, or the teleop channel from another node — and publishes it, stamped with the time it
//! was produced, into the latest-value cell the control loop reads. Slow I/O belongs here, never in
//! the control loop.

use core::ops::Deref;

use penelope_hal::{Reference, Timestamp, Trajectory, TrajectoryError};

use crate::cell::{LatestCell, LatestWriter, Stamped};

/// Where the communication loop publishes references.
pub trait ReferenceSink {
    /// Publishes one stamped reference.
    ///
    /// # Real-time
    /// Implementations must be wait-free and allocation-free.
    fn publish(&mut self, reference: Stamped<Reference>);
}

impl<P: Deref<Target = LatestCell<Stamped<Reference>>>> ReferenceSink
    for LatestWriter<Stamped<Reference>, P>
{
    fn publish(&mut self, reference: Stamped<Reference>) {
        self.write(reference);
    }
}

/// What one communication tick did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommOutcome {
    /// A reference was published.
    Published,
    /// The trajectory had nothing to give; nothing was published (the control loop's watchdog
    /// will notice if this lasts).
    Unavailable(TrajectoryError),
    /// The trajectory gave NaN or infinity; nothing was published.
    Rejected,
}

/// Counters of a [`CommLoop`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CommStats {
    /// Ticks run.
    pub ticks: u64,
    /// References published.
    pub published: u64,
    /// Ticks where the trajectory had nothing to give.
    pub unavailable: u64,
    /// Non-finite references refused.
    pub rejected: u64,
}

/// The communication loop: trajectory in, stamped reference out.
///
/// ```
/// use penelope_hal::{JointReference, Reference, Timestamp};
/// use penelope_rt_core::cell::{Fresh, LatestCell};
/// use penelope_rt_core::comm::{CommLoop, CommOutcome};
/// use penelope_testbed::SineTrajectory;
///
/// let cell = LatestCell::new();
/// let (writer, mut reader) = cell.split().unwrap();
/// let mut comm = CommLoop::new(SineTrajectory::new(0.1, 0.5), writer);
/// comm.start(Timestamp::ZERO, &Reference::Joint(JointReference::default()));
/// assert_eq!(comm.tick(Timestamp::from_nanos(1_000_000)), CommOutcome::Published);
/// let Fresh::New(r) = reader.read() else { panic!() };
/// assert_eq!(r.stamp, Timestamp::from_nanos(1_000_000));
/// ```
#[derive(Debug)]
pub struct CommLoop<Tr, W> {
    trajectory: Tr,
    sink: W,
    stats: CommStats,
}

impl<Tr: Trajectory, W: ReferenceSink> CommLoop<Tr, W> {
    /// A loop publishing `trajectory`'s references into `sink`.
    pub fn new(trajectory: Tr, sink: W) -> Self {
        CommLoop {
            trajectory,
            sink,
            stats: CommStats::default(),
        }
    }

    /// Starts the trajectory at `now` from `from` (typically the measured state).
    pub fn start(&mut self, now: Timestamp, from: &Reference) {
        self.trajectory.start(now, from);
    }

    /// One tick: the reference at `now`, published stamped with `now`.
    ///
    /// # Real-time
    /// Allocation-free if the trajectory is; one wait-free cell write.
    pub fn tick(&mut self, now: Timestamp) -> CommOutcome {
        self.stats.ticks += 1;
        match self.trajectory.reference(now) {
            Ok(r) if r.is_finite() => {
                self.sink.publish(Stamped {
                    stamp: now,
                    value: r,
                });
                self.stats.published += 1;
                CommOutcome::Published
            }
            Ok(_) => {
                self.stats.rejected += 1;
                CommOutcome::Rejected
            }
            Err(e) => {
                self.stats.unavailable += 1;
                CommOutcome::Unavailable(e)
            }
        }
    }

    /// The counters.
    pub fn stats(&self) -> CommStats {
        self.stats
    }

    /// The trajectory (to retarget it between ticks).
    pub fn trajectory_mut(&mut self) -> &mut Tr {
        &mut self.trajectory
    }
}
