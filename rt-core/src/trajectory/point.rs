//! Point-to-point trajectories: step, ramp and trapezoidal velocity.

use core::time::Duration;

use nalgebra::Vector6;
use penelope_hal::{JointVector, Pose, Reference, Timestamp, Trajectory, TrajectoryError};

use super::coords::{Chart, Space};
use super::profile::Profile;
use super::{Goal, TrajectoryConfigError};

/// A started point-to-point motion: `c(t) = c0 + s(t) (c1 - c0)`.
#[derive(Clone, Copy, Debug)]
struct Run {
    t0: Timestamp,
    chart: Chart,
    c0: Vector6<f64>,
    delta: Vector6<f64>,
    profile: Profile,
}

impl Run {
    fn reference(&self, goal: &Goal, now: Timestamp) -> Reference {
        let t = now.saturating_since(self.t0).as_secs_f64();
        if t >= self.profile.duration() {
            return Chart::hold(goal);
        }
        let p = self.profile.eval(t);
        self.chart.reference(
            &(self.c0 + self.delta * p.s),
            &(self.delta * p.sd),
            &(self.delta * p.sdd),
        )
    }

    fn is_finished(&self, now: Timestamp) -> bool {
        now.saturating_since(self.t0).as_secs_f64() >= self.profile.duration()
    }

    fn duration(&self) -> Duration {
        Duration::try_from_secs_f64(self.profile.duration()).unwrap_or(Duration::MAX)
    }
}

/// Starts a point-to-point motion toward `goal` from `from`, the profile chosen from the
/// coordinate difference; `None` when `from` does not fit the goal's space.
fn start_run(
    goal: &Goal,
    now: Timestamp,
    from: &Reference,
    profile: impl FnOnce(&Vector6<f64>) -> Profile,
) -> Option<Run> {
    let start = Chart::start(Space::of(goal), from)?;
    let c1 = start.chart.coords(goal)?;
    let delta = c1 - start.coords;
    Some(Run {
        t0: now,
        chart: start.chart,
        c0: start.coords,
        delta,
        profile: profile(&delta),
    })
}

fn secs(d: Duration) -> f64 {
    d.as_secs_f64()
}

/// Holds the start reference, then jumps to the goal `delay` after the start. Zero velocity and
/// acceleration feed-forward throughout (the jump is the point: step-response experiments).
///
/// # Real-time
/// [`Trajectory`] methods: no allocation, no blocking, constant time.
#[derive(Clone, Copy, Debug)]
pub struct Step {
    goal: Goal,
    delay: Duration,
    run: Option<Run>,
}

impl Step {
    /// A step to joint positions `goal` (rad), at the start.
    ///
    /// # Errors
    /// [`TrajectoryConfigError::NonFinite`] for a NaN or infinite goal.
    pub fn joint(goal: JointVector) -> Result<Self, TrajectoryConfigError> {
        Self::new(Goal::Joint(goal))
    }

    /// A step to tool pose `goal` (base frame), at the start.
    ///
    /// # Errors
    /// [`TrajectoryConfigError::NonFinite`] for a NaN or infinite goal.
    pub fn cartesian(goal: Pose) -> Result<Self, TrajectoryConfigError> {
        Self::new(Goal::Cartesian(goal))
    }

    /// A step to `goal`, at the start.
    ///
    /// # Errors
    /// [`TrajectoryConfigError::NonFinite`] for a NaN or infinite goal.
    pub fn new(goal: Goal) -> Result<Self, TrajectoryConfigError> {
        if !goal.is_finite() {
            return Err(TrajectoryConfigError::NonFinite);
        }
        Ok(Step {
            goal,
            delay: Duration::ZERO,
            run: None,
        })
    }

    /// The same step, taken `delay` after the start (the start reference is held until then).
    pub fn with_delay(mut self, delay: Duration) -> Self {
        self.delay = delay;
        self
    }

    /// The goal.
    pub fn goal(&self) -> &Goal {
        &self.goal
    }

    /// True once a start of the right kind was given.
    pub fn is_started(&self) -> bool {
        self.run.is_some()
    }
}

impl Trajectory for Step {
    fn kind(&self) -> &'static str {
        "step"
    }

    fn start(&mut self, now: Timestamp, from: &Reference) {
        let delay = secs(self.delay);
        // The start velocity is not carried over: a step holds still, then jumps.
        self.run = start_run(&self.goal, now, from, |_| Profile::Step { delay });
    }

    fn reference(&mut self, now: Timestamp) -> Result<Reference, TrajectoryError> {
        let run = self.run.as_ref().ok_or(TrajectoryError::NotStarted)?;
        Ok(run.reference(&self.goal, now))
    }

    fn is_finished(&self, now: Timestamp) -> bool {
        self.run.as_ref().is_some_and(|r| r.is_finished(now))
    }
}

/// Constant speed from the start to the goal over a fixed duration (velocity feed-forward
/// `(goal - start) / duration`, zero acceleration; the velocity steps at both ends).
///
/// # Real-time
/// [`Trajectory`] methods: no allocation, no blocking, constant time.
#[derive(Clone, Copy, Debug)]
pub struct Ramp {
    goal: Goal,
    duration: Duration,
    run: Option<Run>,
}

impl Ramp {
    /// A ramp to joint positions `goal` (rad) lasting `duration`.
    ///
    /// # Errors
    /// [`TrajectoryConfigError::NonFinite`] for a NaN or infinite goal.
    pub fn joint(goal: JointVector, duration: Duration) -> Result<Self, TrajectoryConfigError> {
        Self::new(Goal::Joint(goal), duration)
    }

    /// A ramp to tool pose `goal` (base frame) lasting `duration`: straight line and slerp.
    ///
    /// # Errors
    /// [`TrajectoryConfigError::NonFinite`] for a NaN or infinite goal.
    pub fn cartesian(goal: Pose, duration: Duration) -> Result<Self, TrajectoryConfigError> {
        Self::new(Goal::Cartesian(goal), duration)
    }

    /// A ramp to `goal` lasting `duration` (a zero duration is a step at the start).
    ///
    /// # Errors
    /// [`TrajectoryConfigError::NonFinite`] for a NaN or infinite goal.
    pub fn new(goal: Goal, duration: Duration) -> Result<Self, TrajectoryConfigError> {
        if !goal.is_finite() {
            return Err(TrajectoryConfigError::NonFinite);
        }
        Ok(Ramp {
            goal,
            duration,
            run: None,
        })
    }

    /// The goal.
    pub fn goal(&self) -> &Goal {
        &self.goal
    }

    /// True once a start of the right kind was given.
    pub fn is_started(&self) -> bool {
        self.run.is_some()
    }
}

impl Trajectory for Ramp {
    fn kind(&self) -> &'static str {
        "ramp"
    }

    fn start(&mut self, now: Timestamp, from: &Reference) {
        let duration = secs(self.duration);
        self.run = start_run(&self.goal, now, from, |_| Profile::Ramp { duration });
    }

    fn reference(&mut self, now: Timestamp) -> Result<Reference, TrajectoryError> {
        let run = self.run.as_ref().ok_or(TrajectoryError::NotStarted)?;
        Ok(run.reference(&self.goal, now))
    }

    fn is_finished(&self, now: Timestamp) -> bool {
        self.run.as_ref().is_some_and(|r| r.is_finished(now))
    }
}

/// Speed and acceleration limits of an operational-space trapezoidal motion, along the straight
/// line (linear) and about the slerp axis (angular).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartesianLimits {
    /// Largest tool speed, m/s.
    pub linear_velocity: f64,
    /// Largest tool acceleration, m/s².
    pub linear_acceleration: f64,
    /// Largest angular speed, rad/s.
    pub angular_velocity: f64,
    /// Largest angular acceleration, rad/s².
    pub angular_acceleration: f64,
}

impl Default for CartesianLimits {
    /// 0.1 m/s, 0.5 m/s², 0.5 rad/s, 2 rad/s²: gentle moves for a PUMA-sized arm.
    fn default() -> Self {
        CartesianLimits {
            linear_velocity: 0.1,
            linear_acceleration: 0.5,
            angular_velocity: 0.5,
            angular_acceleration: 2.0,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Limits {
    Joint {
        velocity: JointVector,
        acceleration: JointVector,
    },
    Cartesian(CartesianLimits),
}

/// Trapezoidal velocity profile: accelerate, cruise, decelerate, from rest to rest.
///
/// Every axis follows one common normalised profile `s(t)`, so the axes start and stop together
/// and the path is a straight line in joint space (joint goal) or a straight line plus slerp
/// (Cartesian goal). The profile is the fastest such that each axis `i` with travel `D_i`
/// respects `D_i s' <= v_max,i` and `D_i s'' <= a_max,i`; the axis with the longest time sets the
/// pace and the others are slowed to match. A Cartesian motion limits the straight-line speed by
/// the linear limits and the slerp angle rate by the angular ones.
///
/// The motion starts at rest at the start position (the start velocity is not carried over).
///
/// # Real-time
/// [`Trajectory`] methods: no allocation, no blocking, constant time.
#[derive(Clone, Copy, Debug)]
pub struct Trapezoidal {
    goal: Goal,
    limits: Limits,
    run: Option<Run>,
}

impl Trapezoidal {
    /// A joint-space move to `goal` (rad) with per-joint speed limits `velocity` (rad/s) and
    /// acceleration limits `acceleration` (rad/s²).
    ///
    /// # Errors
    /// [`TrajectoryConfigError::NonFinite`] for a NaN or infinite value,
    /// [`TrajectoryConfigError::NotPositive`] for a limit `<= 0`.
    pub fn joint(
        goal: JointVector,
        velocity: JointVector,
        acceleration: JointVector,
    ) -> Result<Self, TrajectoryConfigError> {
        let goal = Goal::Joint(goal);
        check_limits(velocity.iter().chain(acceleration.iter()).copied())?;
        if !goal.is_finite() {
            return Err(TrajectoryConfigError::NonFinite);
        }
        Ok(Trapezoidal {
            goal,
            limits: Limits::Joint {
                velocity,
                acceleration,
            },
            run: None,
        })
    }

    /// An operational-space move to tool pose `goal` (base frame) within `limits`.
    ///
    /// # Errors
    /// As [`Trapezoidal::joint`].
    pub fn cartesian(goal: Pose, limits: CartesianLimits) -> Result<Self, TrajectoryConfigError> {
        let goal = Goal::Cartesian(goal);
        check_limits(
            [
                limits.linear_velocity,
                limits.linear_acceleration,
                limits.angular_velocity,
                limits.angular_acceleration,
            ]
            .into_iter(),
        )?;
        if !goal.is_finite() {
            return Err(TrajectoryConfigError::NonFinite);
        }
        Ok(Trapezoidal {
            goal,
            limits: Limits::Cartesian(limits),
            run: None,
        })
    }

    /// The goal.
    pub fn goal(&self) -> &Goal {
        &self.goal
    }

    /// True once a start of the right kind was given.
    pub fn is_started(&self) -> bool {
        self.run.is_some()
    }

    /// The motion's duration, once started.
    pub fn duration(&self) -> Option<Duration> {
        self.run.as_ref().map(Run::duration)
    }

    fn profile(limits: &Limits, delta: &Vector6<f64>) -> Profile {
        // Normalised limits: the tightest v_max / D and a_max / D over the moving axes.
        let mut v = f64::INFINITY;
        let mut a = f64::INFINITY;
        let mut axis = |d: f64, v_max: f64, a_max: f64| {
            if d > 1e-12 {
                v = v.min(v_max / d);
                a = a.min(a_max / d);
            }
        };
        match limits {
            Limits::Joint {
                velocity,
                acceleration,
            } => {
                for i in 0..6 {
                    axis(delta[i].abs(), velocity[i], acceleration[i]);
                }
            }
            Limits::Cartesian(l) => {
                let lin = delta.fixed_rows::<3>(0).norm();
                let ang = delta.fixed_rows::<3>(3).norm();
                axis(lin, l.linear_velocity, l.linear_acceleration);
                axis(ang, l.angular_velocity, l.angular_acceleration);
            }
        }
        if v.is_finite() && a.is_finite() && v > 0.0 && a > 0.0 {
            Profile::trapezoid(v, a)
        } else {
            // Nothing moves (already at the goal), or a travel too long for f64 arithmetic:
            // go to the (finite) goal at once.
            Profile::Ramp { duration: 0.0 }
        }
    }
}

fn check_limits(values: impl Iterator<Item = f64>) -> Result<(), TrajectoryConfigError> {
    for x in values {
        if !x.is_finite() {
            return Err(TrajectoryConfigError::NonFinite);
        }
        if x <= 0.0 {
            return Err(TrajectoryConfigError::NotPositive);
        }
    }
    Ok(())
}

impl Trajectory for Trapezoidal {
    fn kind(&self) -> &'static str {
        "trapezoidal"
    }

    fn start(&mut self, now: Timestamp, from: &Reference) {
        let limits = self.limits;
        self.run = start_run(&self.goal, now, from, |delta| {
            Trapezoidal::profile(&limits, delta)
        });
    }

    fn reference(&mut self, now: Timestamp) -> Result<Reference, TrajectoryError> {
        let run = self.run.as_ref().ok_or(TrajectoryError::NotStarted)?;
        Ok(run.reference(&self.goal, now))
    }

    fn is_finished(&self, now: Timestamp) -> bool {
        self.run.as_ref().is_some_and(|r| r.is_finished(now))
    }
}
