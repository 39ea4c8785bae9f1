//! The trajectory kinds' configurations: goals in joint space (joints or a named pose) or in
//! operational space (a tool position and orientation), and their checks.

use super::per_joint::PerJoint;
use crate::objects::config::describe::KindConfig;
use crate::objects::config::{bad, check_range, parse};
use crate::objects::error::ObjectError;
use crate::objects::kinds::Kind;
use penelope_hal::{MAX_JOINTS, NamedPose};
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// Where a trajectory goes: explicit joints or a named pose of the robot it moves (joint
/// space), or a tool pose in its base frame (operational space).
#[derive(Clone, Debug, PartialEq)]
pub enum GoalConfig {
    /// Joint positions, rad.
    Joints(Vec<f64>),
    /// A named pose.
    Pose(NamedPose),
    /// A tool position, m, and orientation as roll-pitch-yaw, degrees (`None`: the orientation
    /// of the robot's `start` pose).
    Tool {
        /// Position in the base frame, m.
        position: [f64; 3],
        /// Roll, pitch, yaw, degrees.
        rpy_deg: Option<[f64; 3]>,
    },
}

impl GoalConfig {
    /// True for a goal in operational space.
    pub fn is_tool(&self) -> bool {
        matches!(self, GoalConfig::Tool { .. })
    }
}

/// The goal keys every trajectory kind shares.
struct GoalKeys<'a> {
    goal: &'a Option<Vec<f64>>,
    pose: &'a Option<String>,
    position: &'a Option<[f64; 3]>,
    rpy_deg: &'a Option<[f64; 3]>,
}

fn goal_of(kind: &str, keys: GoalKeys<'_>) -> Result<GoalConfig, ObjectError> {
    let GoalKeys {
        goal,
        pose,
        position,
        rpy_deg,
    } = keys;
    if let Some(p) = position {
        if goal.is_some() || pose.is_some() {
            return Err(bad(kind, "give one of `goal`, `pose` and `position`"));
        }
        for x in p {
            check_range(kind, "position", *x, -10.0, 10.0)?;
        }
        for a in rpy_deg.iter().flatten() {
            check_range(kind, "rpy_deg", *a, -360.0, 360.0)?;
        }
        return Ok(GoalConfig::Tool {
            position: *p,
            rpy_deg: *rpy_deg,
        });
    }
    if rpy_deg.is_some() {
        return Err(bad(kind, "`rpy_deg` goes with `position`"));
    }
    match (goal, pose) {
        (Some(_), Some(_)) => Err(bad(kind, "give `goal` or `pose`, not both")),
        (Some(q), None) => {
            if q.is_empty() || q.len() > MAX_JOINTS {
                return Err(bad(kind, format!("`goal` needs 1 to {MAX_JOINTS} values")));
            }
            for x in q {
                check_range(kind, "goal", *x, -100.0, 100.0)?;
            }
            Ok(GoalConfig::Joints(q.clone()))
        }
        (None, Some(p)) => NamedPose::parse(p)
            .map(GoalConfig::Pose)
            .ok_or_else(|| bad(kind, format!("`pose` = {p:?} is not nest, start or work"))),
        (None, None) => Ok(GoalConfig::Pose(NamedPose::Start)),
    }
}

/// `trajectory/step`, `ramp` and `trapezoidal` configuration (keys not of the kind are refused).
#[derive(Clone, Debug, PartialEq, Default, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct StepConfig {
    /// The goal in joint space, rad, one per joint; or else `pose` or `position` (one of the
    /// three).
    pub goal: Option<Vec<f64>>,
    /// The goal as a named pose of the robot (nest, start, work); the default, `start`, when
    /// neither `goal` nor `position` is given.
    pub pose: Option<String>,
    /// The goal as a tool position in the base frame, m (operational space: a joint law follows
    /// it through inverse kinematics).
    pub position: Option<[f64; 3]>,
    /// With `position`: the tool orientation, roll, pitch, yaw, degrees (without it: the
    /// robot's start pose's).
    pub rpy_deg: Option<[f64; 3]>,
    /// The delay before the step, s, 0..=3600.
    pub delay_s: f64,
}

impl KindConfig for StepConfig {
    /// Every goal key set, as the key lists show them (a trajectory takes one of them).
    fn example() -> Self {
        StepConfig {
            goal: Some(vec![0.0; 6]),
            pose: Some("start".into()),
            position: Some([0.6, -0.15, 0.5]),
            rpy_deg: Some([0.0, 90.0, 0.0]),
            ..Self::default()
        }
    }
}

/// `trajectory/ramp` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct RampConfig {
    /// The goal in joint space, rad, one per joint; or else `pose` or `position` (one of the
    /// three).
    pub goal: Option<Vec<f64>>,
    /// The goal as a named pose of the robot (nest, start, work); the default, `start`, when
    /// neither `goal` nor `position` is given.
    pub pose: Option<String>,
    /// The goal as a tool position in the base frame, m (operational space: a joint law follows
    /// it through inverse kinematics).
    pub position: Option<[f64; 3]>,
    /// With `position`: the tool orientation, roll, pitch, yaw, degrees (without it: the
    /// robot's start pose's).
    pub rpy_deg: Option<[f64; 3]>,
    /// The ramp's duration, s, 0.001..=3600.
    pub duration_s: f64,
}

impl KindConfig for RampConfig {
    fn example() -> Self {
        let StepConfig {
            goal,
            pose,
            position,
            rpy_deg,
            ..
        } = StepConfig::example();
        RampConfig {
            goal,
            pose,
            position,
            rpy_deg,
            ..Self::default()
        }
    }
}

impl Default for RampConfig {
    fn default() -> Self {
        RampConfig {
            goal: None,
            pose: None,
            position: None,
            rpy_deg: None,
            duration_s: 2.0,
        }
    }
}

/// `trajectory/trapezoidal` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct TrapezoidalConfig {
    /// The goal in joint space, rad, one per joint; or else `pose` or `position` (one of the
    /// three).
    pub goal: Option<Vec<f64>>,
    /// The goal as a named pose of the robot (nest, start, work); the default, `start`, when
    /// neither `goal` nor `position` is given.
    pub pose: Option<String>,
    /// Refused: a trapezoidal move takes a joint goal (`goal` or `pose`); for a tool
    /// `position` use a step, a ramp or a spline.
    pub position: Option<[f64; 3]>,
    /// Refused, as `position`.
    pub rpy_deg: Option<[f64; 3]>,
    /// Speed limit, rad/s, one value or one per joint, 1e-4..=20.
    pub max_velocity: PerJoint,
    /// Acceleration limit, rad/s², one value or one per joint, 1e-4..=200.
    pub max_acceleration: PerJoint,
}

impl KindConfig for TrapezoidalConfig {
    fn example() -> Self {
        let StepConfig {
            goal,
            pose,
            position,
            rpy_deg,
            ..
        } = StepConfig::example();
        TrapezoidalConfig {
            goal,
            pose,
            position,
            rpy_deg,
            ..Self::default()
        }
    }
}

impl Default for TrapezoidalConfig {
    fn default() -> Self {
        TrapezoidalConfig {
            goal: None,
            pose: None,
            position: None,
            rpy_deg: None,
            max_velocity: PerJoint::One(0.5),
            max_acceleration: PerJoint::One(1.0),
        }
    }
}

/// One spline waypoint.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WaypointConfig {
    /// Time after the start, s, 0..=3600, strictly increasing from one waypoint to the next.
    pub at_s: f64,
    /// Joints, rad, one per joint; or else `pose` or `position` (every waypoint in one
    /// space).
    pub q: Option<Vec<f64>>,
    /// A named pose (nest, start, work).
    pub pose: Option<String>,
    /// A tool position in the base frame, m.
    #[serde(default)]
    pub position: Option<[f64; 3]>,
    /// With `position`: the tool orientation, roll, pitch, yaw, degrees.
    #[serde(default)]
    pub rpy_deg: Option<[f64; 3]>,
}

/// `trajectory/spline` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SplineConfig {
    /// `clamped` (arrive at rest) or `natural`.
    pub ends: String,
    /// The waypoints, 1..=16 (default: one, pose start at 2 s).
    pub waypoints: Vec<WaypointConfig>,
}

impl KindConfig for SplineConfig {
    fn example() -> Self {
        let StepConfig {
            goal: q,
            pose,
            position,
            rpy_deg,
            ..
        } = StepConfig::example();
        SplineConfig {
            waypoints: vec![WaypointConfig {
                at_s: 2.0,
                q,
                pose,
                position,
                rpy_deg,
            }],
            ..Self::default()
        }
    }
}

impl Default for SplineConfig {
    fn default() -> Self {
        SplineConfig {
            ends: "clamped".into(),
            waypoints: vec![WaypointConfig {
                at_s: 2.0,
                q: None,
                pose: Some("start".into()),
                position: None,
                rpy_deg: None,
            }],
        }
    }
}

/// The most waypoints a `trajectory/spline` holds.
pub const MAX_WAYPOINTS: usize = 16;

/// A trajectory's configuration, checked (goals may still name poses of a robot).
#[derive(Clone, Debug, PartialEq)]
pub enum TrajectorySpec {
    /// A step after `delay`.
    Step {
        /// Goal.
        goal: GoalConfig,
        /// Delay.
        delay: Duration,
    },
    /// A ramp lasting `duration`.
    Ramp {
        /// Goal.
        goal: GoalConfig,
        /// Duration.
        duration: Duration,
    },
    /// A trapezoidal move.
    Trapezoidal {
        /// Goal.
        goal: GoalConfig,
        /// Speed limit, rad/s.
        velocity: PerJoint,
        /// Acceleration limit, rad/s².
        acceleration: PerJoint,
    },
    /// A spline.
    Spline {
        /// Clamped (true) or natural ends.
        clamped: bool,
        /// `(time after start, goal)`.
        waypoints: Vec<(Duration, GoalConfig)>,
    },
}

/// Parses and checks a trajectory kind's configuration.
///
/// # Errors
/// [`ObjectError::BadConfig`].
pub fn trajectory_spec(kind: Kind, text: &str) -> Result<TrajectorySpec, ObjectError> {
    let k = kind.as_str();
    match kind {
        Kind::STEP => step_spec(k, text),
        Kind::RAMP => ramp_spec(k, text),
        Kind::TRAPEZOIDAL => trapezoidal_spec(k, text),
        _ => spline_spec(k, text),
    }
}

/// `trajectory/step`.
fn step_spec(k: &str, text: &str) -> Result<TrajectorySpec, ObjectError> {
    let c: StepConfig = parse(k, text)?;
    check_range(k, "delay_s", c.delay_s, 0.0, 3600.0)?;
    Ok(TrajectorySpec::Step {
        goal: goal_of(
            k,
            GoalKeys {
                goal: &c.goal,
                pose: &c.pose,
                position: &c.position,
                rpy_deg: &c.rpy_deg,
            },
        )?,
        delay: Duration::from_secs_f64(c.delay_s),
    })
}

/// `trajectory/ramp`.
fn ramp_spec(k: &str, text: &str) -> Result<TrajectorySpec, ObjectError> {
    let c: RampConfig = parse(k, text)?;
    check_range(k, "duration_s", c.duration_s, 0.001, 3600.0)?;
    Ok(TrajectorySpec::Ramp {
        goal: goal_of(
            k,
            GoalKeys {
                goal: &c.goal,
                pose: &c.pose,
                position: &c.position,
                rpy_deg: &c.rpy_deg,
            },
        )?,
        duration: Duration::from_secs_f64(c.duration_s),
    })
}

/// `trajectory/trapezoidal`.
fn trapezoidal_spec(k: &str, text: &str) -> Result<TrajectorySpec, ObjectError> {
    let c: TrapezoidalConfig = parse(k, text)?;
    c.max_velocity.check(k, "max_velocity", 1e-4, 20.0)?;
    c.max_acceleration
        .check(k, "max_acceleration", 1e-4, 200.0)?;
    if c.position.is_some() {
        return Err(bad(
            k,
            "a trapezoidal move takes a joint goal (`goal` or `pose`); for a tool \
                 `position` use a step, a ramp or a spline",
        ));
    }
    Ok(TrajectorySpec::Trapezoidal {
        goal: goal_of(
            k,
            GoalKeys {
                goal: &c.goal,
                pose: &c.pose,
                position: &c.position,
                rpy_deg: &c.rpy_deg,
            },
        )?,
        velocity: c.max_velocity,
        acceleration: c.max_acceleration,
    })
}

/// `trajectory/spline`.
fn spline_spec(k: &str, text: &str) -> Result<TrajectorySpec, ObjectError> {
    let c: SplineConfig = parse(k, text)?;
    let clamped = match c.ends.as_str() {
        "clamped" => true,
        "natural" => false,
        other => {
            return Err(bad(
                k,
                format!("`ends` = {other:?} is not \"clamped\" or \"natural\""),
            ));
        }
    };
    if c.waypoints.is_empty() || c.waypoints.len() > MAX_WAYPOINTS {
        return Err(bad(k, format!("needs 1 to {MAX_WAYPOINTS} waypoints")));
    }
    let mut previous = 0.0;
    let mut waypoints = Vec::with_capacity(c.waypoints.len());
    for w in &c.waypoints {
        check_range(k, "waypoints.at_s", w.at_s, 0.0, 3600.0)?;
        if w.at_s <= previous {
            return Err(bad(
                k,
                "waypoint times must be strictly increasing and after 0",
            ));
        }
        previous = w.at_s;
        waypoints.push((
            Duration::from_secs_f64(w.at_s),
            goal_of(
                k,
                GoalKeys {
                    goal: &w.q,
                    pose: &w.pose,
                    position: &w.position,
                    rpy_deg: &w.rpy_deg,
                },
            )?,
        ));
    }
    Ok(TrajectorySpec::Spline { clamped, waypoints })
}
