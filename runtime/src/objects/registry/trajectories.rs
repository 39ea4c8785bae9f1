//! Trajectories from their specifications: for a robot, or standalone (for `reference`).

use crate::objects::error::ObjectError;
use crate::objects::kinds;
use crate::objects::registry::{GoalConfig, TrajectorySpec, not_ready};
use crate::objects::runtime::TrajectoryGenerator;
use penelope_drivers::model::{self as models, SerialRobotModel};
use penelope_hal::{JointVector, Kinematics, MAX_JOINTS, NamedPose};
use penelope_protocol::proto::joints_to_vector;
use penelope_rt_core::trajectory::{
    CubicSpline, Goal, Ramp, SplineEnds, Step, Trapezoidal, Waypoint,
};

pub(super) fn goal_vector(
    g: &GoalConfig,
    model: &SerialRobotModel,
    kind: &str,
) -> Result<JointVector, ObjectError> {
    match g {
        GoalConfig::Pose(p) => Ok(model.named_pose(*p)),
        GoalConfig::Tool { .. } => Err(ObjectError::internal("a tool goal in joint space")),
        GoalConfig::Joints(q) => {
            joints_to_vector(q, model.joint_count()).map_err(|_| ObjectError::BadConfig {
                kind: kind.into(),
                message: format!(
                    "goal has {} values, the robot has {} joints",
                    q.len(),
                    model.joint_count()
                ),
            })
        }
    }
}

pub(super) fn spec_joints(spec: &TrajectorySpec) -> usize {
    let of = |g: &GoalConfig| match g {
        GoalConfig::Joints(q) => q.len(),
        GoalConfig::Pose(_) | GoalConfig::Tool { .. } => MAX_JOINTS,
    };
    match spec {
        TrajectorySpec::Step { goal, .. }
        | TrajectorySpec::Ramp { goal, .. }
        | TrajectorySpec::Trapezoidal { goal, .. } => of(goal),
        TrajectorySpec::Spline { waypoints, .. } => {
            waypoints.first().map_or(MAX_JOINTS, |w| of(&w.1))
        }
    }
}

pub(super) fn build_standalone(
    spec: &TrajectorySpec,
    kind: &str,
) -> Result<TrajectoryGenerator, ObjectError> {
    // A named pose, or a tool goal whose orientation is the robot's start pose's.
    let uses_pose = |g: &GoalConfig| {
        matches!(
            g,
            GoalConfig::Pose(_) | GoalConfig::Tool { rpy_deg: None, .. }
        )
    };
    let any_pose = match spec {
        TrajectorySpec::Step { goal, .. }
        | TrajectorySpec::Ramp { goal, .. }
        | TrajectorySpec::Trapezoidal { goal, .. } => uses_pose(goal),
        TrajectorySpec::Spline { waypoints, .. } => waypoints.iter().any(|w| uses_pose(&w.1)),
    };
    if any_pose {
        return Err(not_ready(
            "the goal is a named pose: bind the trajectory to a controller with a robot first",
        ));
    }
    // A robot-less model of the goal's length: joints only, so any model of that many joints
    // gives the same result; use a PUMA 560 for six and below.
    let model = models::puma560();
    let n = spec_joints(spec);
    let pad = |g: &GoalConfig| match g {
        GoalConfig::Joints(q) => {
            let mut v = q.clone();
            v.resize(model.joint_count().max(n), 0.0);
            GoalConfig::Joints(v)
        }
        other => other.clone(),
    };
    let padded = match spec {
        TrajectorySpec::Step { goal, delay } => TrajectorySpec::Step {
            goal: pad(goal),
            delay: *delay,
        },
        TrajectorySpec::Ramp { goal, duration } => TrajectorySpec::Ramp {
            goal: pad(goal),
            duration: *duration,
        },
        TrajectorySpec::Trapezoidal {
            goal,
            velocity,
            acceleration,
        } => TrajectorySpec::Trapezoidal {
            goal: pad(goal),
            velocity: match velocity {
                kinds::PerJoint::Each(v) if v.len() == n => {
                    let mut v = v.clone();
                    v.resize(model.joint_count(), 1.0);
                    kinds::PerJoint::Each(v)
                }
                other => other.clone(),
            },
            acceleration: match acceleration {
                kinds::PerJoint::Each(v) if v.len() == n => {
                    let mut v = v.clone();
                    v.resize(model.joint_count(), 1.0);
                    kinds::PerJoint::Each(v)
                }
                other => other.clone(),
            },
        },
        TrajectorySpec::Spline { clamped, waypoints } => TrajectorySpec::Spline {
            clamped: *clamped,
            waypoints: waypoints.iter().map(|(t, g)| (*t, pad(g))).collect(),
        },
    };
    build_trajectory(&padded, &model, kind)
}

/// Whether `spec` moves in operational space (its goals are tool poses).
pub(super) fn spec_is_tool(spec: &TrajectorySpec) -> bool {
    match spec {
        TrajectorySpec::Step { goal, .. }
        | TrajectorySpec::Ramp { goal, .. }
        | TrajectorySpec::Trapezoidal { goal, .. } => goal.is_tool(),
        TrajectorySpec::Spline { waypoints, .. } => waypoints.iter().any(|w| w.1.is_tool()),
    }
}

/// The goal `g` for `model`: joints for a joint or named-pose goal, a tool pose for a tool goal
/// (its orientation, when not given, that of the robot's `start` pose).
fn goal_for(g: &GoalConfig, model: &SerialRobotModel, kind: &str) -> Result<Goal, ObjectError> {
    match g {
        GoalConfig::Tool { position, rpy_deg } => {
            let rotation = match rpy_deg {
                Some(a) => {
                    let [r, p, y] = a.map(f64::to_radians);
                    nalgebra::UnitQuaternion::from_euler_angles(r, p, y)
                }
                None => model.forward(&model.named_pose(NamedPose::Start)).rotation,
            };
            Ok(Goal::Cartesian(penelope_hal::Pose::from_parts(
                nalgebra::Translation3::new(position[0], position[1], position[2]),
                rotation,
            )))
        }
        other => Ok(Goal::Joint(goal_vector(other, model, kind)?)),
    }
}

/// The trajectory `spec` for `model` (named poses resolved, lengths checked).
pub(super) fn build_trajectory(
    spec: &TrajectorySpec,
    model: &SerialRobotModel,
    kind: &str,
) -> Result<TrajectoryGenerator, ObjectError> {
    let n = model.joint_count();
    let cfg_err = |e: penelope_rt_core::trajectory::TrajectoryConfigError| ObjectError::BadConfig {
        kind: kind.into(),
        message: e.to_string(),
    };
    Ok(match spec {
        TrajectorySpec::Step { goal, delay } => TrajectoryGenerator::Step(
            Step::new(goal_for(goal, model, kind)?)
                .map_err(cfg_err)?
                .with_delay(*delay),
        ),
        TrajectorySpec::Ramp { goal, duration } => TrajectoryGenerator::Ramp(
            Ramp::new(goal_for(goal, model, kind)?, *duration).map_err(cfg_err)?,
        ),
        TrajectorySpec::Trapezoidal {
            goal,
            velocity,
            acceleration,
        } => {
            let mut v = velocity.resolve(kind, "max_velocity", n, 1e-4, 20.0)?;
            let mut a = acceleration.resolve(kind, "max_acceleration", n, 1e-4, 200.0)?;
            for j in n..MAX_JOINTS {
                v[j] = 1.0;
                a[j] = 1.0;
            }
            TrajectoryGenerator::Trapezoidal(
                Trapezoidal::joint(goal_vector(goal, model, kind)?, v, a).map_err(cfg_err)?,
            )
        }
        TrajectorySpec::Spline { clamped, waypoints } => {
            let mut w = Vec::with_capacity(waypoints.len());
            for (at, g) in waypoints {
                w.push(Waypoint {
                    at: *at,
                    goal: goal_for(g, model, kind)?,
                });
            }
            let ends = if *clamped {
                SplineEnds::Clamped
            } else {
                SplineEnds::Natural
            };
            TrajectoryGenerator::Spline(CubicSpline::new(&w, ends).map_err(cfg_err)?)
        }
    })
}
