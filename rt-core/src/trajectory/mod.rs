//! Trajectories: references that evolve in time (the paper's `getReferiment`).
//!
//! Four shapes, each in joint space or in operational space, all implementing
//! [`penelope_hal::Trajectory`]:
//!
//! | type | shape | feed-forward |
//! |---|---|---|
//! | [`Step`] | holds the start, then jumps to the goal after a delay | none (zero) |
//! | [`Ramp`] | constant speed from the start to the goal over a duration | velocity |
//! | [`Trapezoidal`] | velocity- and acceleration-limited, every axis synchronised | velocity, acceleration |
//! | [`CubicSpline`] | C² cubic through up to `N` timed waypoints, natural or clamped ends | velocity, acceleration |
//!
//! # Starting and holding
//!
//! [`Trajectory::start`](penelope_hal::Trajectory::start) takes the reference the robot is at
//! (typically the measured state): the trajectory begins exactly there, so the position never
//! jumps. A joint-space trajectory needs a [`Reference::Joint`](penelope_hal::Reference::Joint)
//! start; an operational-space one a `Cartesian` (or `Hybrid`, whose motion part is used) start.
//! Given a start of the wrong kind (or a non-finite one) the trajectory stays un-started and
//! [`reference`](penelope_hal::Trajectory::reference) answers
//! [`TrajectoryError::NotStarted`](penelope_hal::TrajectoryError::NotStarted), so the control loop
//! keeps its safe fallback. After the end, the goal is held exactly with zero velocity and
//! acceleration.
//!
//! # Operational space
//!
//! A Cartesian trajectory moves the tool position along the straight line between the start and the
//! goal, linearly in the profile parameter `s(t)` (`0..=1`), and the orientation by spherical
//! linear interpolation (slerp) along the shortest arc, `R(s) = exp(s·phi) R0` with
//! `phi = log(R1 R0^T)`. The twist feed-forward is in the base frame: `v = s'(t) (p1 - p0)`,
//! `omega = s'(t) phi`. [`CubicSpline`] generalises this to several waypoints by splining the
//! position and the rotation vector `phi(t)` (relative to the start orientation, unwrapped between
//! waypoints); with two knots it reduces to slerp. [`CartesianReference`](penelope_hal::CartesianReference)
//! carries no acceleration, so operational-space trajectories give pose and twist only.
//!
//! # Real-time
//! Construction validates the configuration (typed [`TrajectoryConfigError`]). `start`,
//! `reference` and `is_finished` never allocate, lock or block, never panic, and run in bounded
//! time (a spline's `start` solves one tridiagonal system of at most `N + 1` knots, `O(N)`;
//! `reference` scans at most `N` segments).

mod coords;
mod point;
mod profile;
mod spline;

use core::fmt;

use penelope_hal::{Error, ErrorKind, JointVector, Pose};

pub use point::{CartesianLimits, Ramp, Step, Trapezoidal};
pub use spline::{CubicSpline, SplineEnds, Waypoint};

/// A trajectory's goal: where it ends, in joint space or in operational space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Goal {
    /// Joint positions, rad (prismatic joints: m).
    Joint(JointVector),
    /// A tool pose in the robot's base frame (m, unit quaternion).
    Cartesian(Pose),
}

impl Goal {
    /// True when no component is NaN or infinite.
    pub fn is_finite(&self) -> bool {
        match self {
            Goal::Joint(q) => q.iter().all(|x| x.is_finite()),
            Goal::Cartesian(p) => {
                p.translation.vector.iter().all(|x| x.is_finite())
                    && p.rotation.coords.iter().all(|x| x.is_finite())
            }
        }
    }
}

/// Why a trajectory could not be built from its configuration.
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrajectoryConfigError {
    /// A goal, waypoint, limit or duration was NaN or infinite.
    NonFinite,
    /// A velocity or acceleration limit was zero or negative.
    NotPositive,
    /// More waypoints than the spline's capacity `N`.
    TooManyWaypoints,
    /// A spline needs at least one waypoint.
    NoWaypoints,
    /// Waypoint times must be strictly increasing and after the start (`at > 0`).
    TimesNotIncreasing,
    /// Waypoints mix joint-space and operational-space goals.
    MixedSpaces,
}

impl fmt::Display for TrajectoryConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            TrajectoryConfigError::NonFinite => "a goal, limit or duration is NaN or infinite",
            TrajectoryConfigError::NotPositive => "velocity and acceleration limits must be > 0",
            TrajectoryConfigError::TooManyWaypoints => "more waypoints than the spline holds",
            TrajectoryConfigError::NoWaypoints => "a spline needs at least one waypoint",
            TrajectoryConfigError::TimesNotIncreasing => {
                "waypoint times must be strictly increasing and after the start"
            }
            TrajectoryConfigError::MixedSpaces => "waypoints mix joint and Cartesian goals",
        })
    }
}

impl Error for TrajectoryConfigError {
    fn kind(&self) -> ErrorKind {
        match self {
            TrajectoryConfigError::NonFinite => ErrorKind::NonFinite,
            TrajectoryConfigError::NotPositive => ErrorKind::OutOfLimits,
            _ => ErrorKind::InvalidInput,
        }
    }
}
