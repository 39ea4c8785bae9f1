//! The CRTK verbs a robot answers: moves (`move_jp`, `move_cp`), servo targets (`servo_jp`,
//! `servo_cp`), its setpoints and its operating state, all through the loop of the active
//! controller driving it.

use crate::objects::Registry;
use crate::objects::error::ObjectError;
use crate::objects::registry::{bad_arg, not_ready};
use crate::objects::runtime::{GoToCommand, MAX_SERVO_STEP_RAD, Running, ServoTarget};
use penelope_hal::{InverseKinematics, JointVector, Kinematics, LifecycleState, RobotModel};
use penelope_protocol::proto::{
    OperatingStateMsg, PoseMsg, Reply, SetpointsMsg, joints_from_vector, joints_to_vector,
};
use penelope_rt_core::telemetry::ReferenceKind;
use std::time::Duration;

/// A move's duration: finite, in (0, 3600] s.
pub(super) fn move_duration(duration_s: f64) -> Result<Duration, ObjectError> {
    if duration_s.is_finite() && duration_s > 0.0 && duration_s <= 3600.0 {
        Ok(Duration::from_secs_f64(duration_s))
    } else {
        Err(bad_arg(format!(
            "duration_s must be in (0, 3600] s, got {duration_s}"
        )))
    }
}

impl Registry {
    /// The running loop of the active controller driving robot `name`, which must follow a
    /// trajectory (a teleoperation end goes where the other side takes it).
    fn motion_loop(&mut self, name: &str) -> Result<&mut Running, ObjectError> {
        let driver = self.driver_of(name).ok_or_else(|| {
            not_ready(format!(
                "robot `{name}` is not driven by an active controller (activate one)"
            ))
        })?;
        let c = self.controller_mut(&driver)?;
        if c.config.teleop_side().is_some() {
            return Err(not_ready(format!(
                "robot `{name}` follows a teleoperation channel (`{driver}`): it goes \
                 where the other side takes it"
            )));
        }
        c.running
            .as_mut()
            .ok_or_else(|| not_ready(format!("controller `{driver}` is not running")))
    }

    /// The joint reference robot `name`'s loop follows now (its newest sample's; the measured
    /// joints under a law that follows poses), the base of the servo step check and the seed
    /// of inverse kinematics.
    fn current_reference(&mut self, name: &str) -> Result<JointVector, ObjectError> {
        let run = self.motion_loop(name)?;
        let newest = run
            .shared
            .newest()
            .ok_or_else(|| not_ready(format!("robot `{name}`: its loop has not ticked yet")))?;
        let s = newest.sample;
        Ok(if s.reference_kind == ReferenceKind::Joint {
            s.reference_q
        } else {
            s.q
        })
    }

    /// A joint goal for robot `name`: one finite value per joint, within the joint limits.
    fn joint_goal(&self, name: &str, q: &[f64]) -> Result<JointVector, ObjectError> {
        let model = &self.robot(name)?.model;
        let n = model.joint_count();
        let goal = joints_to_vector(q, n)?;
        let limits = model.limits();
        if let Some(j) =
            (0..n).find(|&j| !(limits.position_min[j]..=limits.position_max[j]).contains(&goal[j]))
        {
            return Err(bad_arg(format!(
                "joint {j}: {} rad is outside the joint limits [{}, {}] rad",
                goal[j], limits.position_min[j], limits.position_max[j]
            )));
        }
        Ok(goal)
    }

    /// The joints that put robot `name`'s tool at `pose`: the inverse-kinematics branch nearest
    /// the current reference, within the joint limits.
    fn tool_goal(&mut self, name: &str, pose: &PoseMsg) -> Result<JointVector, ObjectError> {
        let pose = pose.to_pose()?;
        let seed = self.current_reference(name)?;
        let q = self
            .robot(name)?
            .model
            .inverse_near(&pose, &seed)
            .map_err(|e| bad_arg(format!("robot `{name}` cannot reach the pose: {e}")))?;
        let n = self.robot(name)?.model.joint_count();
        self.joint_goal(name, &q.as_slice()[..n])
    }

    /// Queues a move of `name` to `goal` (GoTo, `move_jp`, `move_cp`): a clamped spline from the
    /// current reference, in the communication task.
    pub(super) fn start_move(
        &mut self,
        name: &str,
        goal: JointVector,
        duration: Duration,
    ) -> Result<Reply, ObjectError> {
        let run = self.motion_loop(name)?;
        // Counted before the push, so that `is_busy` is true as soon as this call returns.
        run.motion.move_requested();
        if run.goto.push(GoToCommand { goal, duration }).is_err() {
            run.motion.move_not_queued();
            return Err(not_ready("too many motions queued"));
        }
        Ok(Reply::Unit)
    }

    /// Refuses a move of robot `name` to `goal` in `duration` that the joints' velocity limits
    /// forbid: the spline from rest to rest peaks at 1.5 times the mean speed, and a joint
    /// measured past its limit faults the loop.
    fn check_move_speed(
        &mut self,
        name: &str,
        goal: &JointVector,
        duration: Duration,
    ) -> Result<(), ObjectError> {
        let from = self.current_reference(name)?;
        let model = &self.robot(name)?.model;
        let limits = model.limits();
        let t = duration.as_secs_f64();
        for j in 0..model.joint_count() {
            let distance = (goal[j] - from[j]).abs();
            let peak = 1.5 * distance / t;
            if peak > limits.velocity_max[j] {
                return Err(bad_arg(format!(
                    "joint {j}: {distance:.3} rad in {t} s peaks at {peak:.2} rad/s, past its \
                     velocity limit of {} rad/s: take at least {:.2} s",
                    limits.velocity_max[j],
                    1.5 * distance / limits.velocity_max[j]
                )));
            }
        }
        Ok(())
    }

    /// CRTK `move_jp`.
    pub(super) fn move_joints(
        &mut self,
        name: &str,
        q: &[f64],
        duration_s: f64,
    ) -> Result<Reply, ObjectError> {
        let duration = move_duration(duration_s)?;
        let goal = self.joint_goal(name, q)?;
        self.check_move_speed(name, &goal, duration)?;
        self.start_move(name, goal, duration)
    }

    /// CRTK `move_cp`.
    pub(super) fn move_tool(
        &mut self,
        name: &str,
        pose: PoseMsg,
        duration_s: f64,
    ) -> Result<Reply, ObjectError> {
        let duration = move_duration(duration_s)?;
        let goal = self.tool_goal(name, &pose)?;
        self.check_move_speed(name, &goal, duration)?;
        self.start_move(name, goal, duration)
    }

    /// CRTK `servo_jp`.
    pub(super) fn servo_joints(&mut self, name: &str, q: &[f64]) -> Result<Reply, ObjectError> {
        let goal = self.joint_goal(name, q)?;
        self.servo_to(name, goal)
    }

    /// CRTK `servo_cp`.
    pub(super) fn servo_tool(&mut self, name: &str, pose: PoseMsg) -> Result<Reply, ObjectError> {
        let goal = self.tool_goal(name, &pose)?;
        self.servo_to(name, goal)
    }

    /// Hands a servo target within the step limit of the current reference to the loop of
    /// robot `name` (its communication task checks the step again when it takes it).
    fn servo_to(&mut self, name: &str, goal: JointVector) -> Result<Reply, ObjectError> {
        let n = self.robot(name)?.model.joint_count();
        let reference = self.current_reference(name)?;
        if let Some(j) = (0..n).find(|&j| (goal[j] - reference[j]).abs() > MAX_SERVO_STEP_RAD) {
            return Err(bad_arg(format!(
                "joint {j}: the servo target is {:.4} rad from the current reference, more than \
                 the servo step limit of {MAX_SERVO_STEP_RAD} rad (use move_jp for a longer way)",
                (goal[j] - reference[j]).abs()
            )));
        }
        self.motion_loop(name)?
            .motion
            .servo(ServoTarget { q: goal });
        Ok(Reply::Unit)
    }

    /// CRTK `setpoint_js` / `setpoint_cp`: the reference of the running loop's newest sample.
    pub(super) fn setpoints(&mut self, name: &str) -> Result<Reply, ObjectError> {
        let driver = self.driver_of(name).ok_or_else(|| {
            not_ready(format!(
                "robot `{name}` is not driven by an active controller"
            ))
        })?;
        let newest = self
            .controller_mut(&driver)?
            .running
            .as_ref()
            .and_then(|r| r.shared.newest())
            .ok_or_else(|| not_ready(format!("robot `{name}`: its loop has not ticked yet")))?;
        let s = newest.sample;
        let r = self.robot(name)?;
        let n = r.model.joint_count();
        // A law that follows poses: the sample holds the tool position only (no orientation),
        // so no setpoint is claimed.
        let (joints, pose) = if s.reference_kind == ReferenceKind::Joint {
            (
                Some(joints_from_vector(&s.reference_q, n)),
                Some(PoseMsg::from(&r.kinematics.forward(&s.reference_q))),
            )
        } else {
            (None, None)
        };
        Ok(Reply::Setpoints(SetpointsMsg {
            time_ns: s.time.as_nanos(),
            joints,
            pose,
        }))
    }

    /// CRTK `operating_state`, from the running loop's newest sample.
    pub(super) fn operating_state(&mut self, name: &str) -> Result<Reply, ObjectError> {
        use penelope_rt_core::safety::SafetyState;
        // Encoders are zeroed at the start pose when the robot is configured; a simulated
        // robot always knows its joints.
        let is_homed = self.get(name)?.state != LifecycleState::Unconfigured;
        self.robot(name)?;
        let running = self
            .driver_of(name)
            .and_then(|d| self.controller_mut(&d).ok())
            .and_then(|c| c.running.as_ref())
            .map(|run| (run.shared.newest(), run.motion.status().is_busy()));
        let (state, is_busy) = match running {
            None => ("DISABLED", false),
            Some((newest, busy)) => (
                match newest.map(|n| n.sample.state) {
                    Some(SafetyState::Running) => "ENABLED",
                    Some(SafetyState::Holding) => "PAUSED",
                    Some(SafetyState::Fault | SafetyState::EStop) => "FAULT",
                    Some(SafetyState::Inactive) | None => "DISABLED",
                },
                busy,
            ),
        };
        Ok(Reply::OperatingState(OperatingStateMsg {
            state: state.into(),
            is_homed,
            is_busy,
        }))
    }
}
