//! The proxy of a remote robot ([`RobotProxy`]): joint state, kinematics, dynamics, encoder
//! conversions and named poses, with the math types of `hal` at the edges.

#[cfg(doc)]
use crate::proto::CallError;
use std::sync::OnceLock;

use nalgebra::{SMatrix, Vector3};
use penelope_hal::{
    Frame, Jacobian, JointSpaceMatrix, JointVector, MAX_JOINTS, NamedPose, OperationalState, Pose,
    Twist, Wrench,
};

use super::{
    Lifecycle, ObjectHandle, TypedProxy, bad, bad_reply, joints_of, matrix_of, pose_msg, wrench_of,
};
use crate::client::unexpected;
use crate::net::conn::RpcError;
#[cfg(doc)]
use crate::proto::WireError;
use crate::proto::{
    Class, ContactShapeMsg, JointAxis, Joints, Method, OperatingStateMsg, Reply, RobotMethod,
    WrenchMsg, joints_from_vector, joints_to_vector,
};

/// The reference a robot's active controller follows now ([`RobotProxy::setpoints`]; CRTK
/// `setpoint_js` / `setpoint_cp`).
#[derive(Clone, Debug, PartialEq)]
pub struct Setpoints {
    /// The loop's time of the sample the setpoint was read from, ns.
    pub time_ns: u64,
    /// Joint reference, rad (`None` when the controller follows a tool pose only).
    pub joints: Option<JointVector>,
    /// Tool pose reference in the base frame.
    pub pose: Option<Pose>,
}

/// What a 3D viewer needs to draw a robot ([`RobotProxy::description`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RobotDescription {
    /// A URDF whose link names are `frames` (a URDF robot's own, or one generated from the DH
    /// table with simple link geometry).
    pub urdf: String,
    /// The robot's frames, root first, the tool frame last ([`RobotProxy::link_frames`] gives
    /// their poses in this order).
    pub frames: Vec<String>,
    /// The joint names, one per joint.
    pub joint_names: Vec<String>,
    /// The contact shapes of the simulated environment the robot's tool touches, in the root
    /// frame; empty behind a real board.
    pub contacts: Vec<ContactShapeMsg>,
}

/// A remote robot (manipulator or joystick): the paper's `Puma200` class.
#[derive(Clone, Debug)]
pub struct RobotProxy {
    handle: ObjectHandle,
    joints: OnceLock<usize>,
}
proxy_of_class!(RobotProxy, Some(Class::Robot), { joints: OnceLock::new() });

impl RobotProxy {
    fn robot(&self, method: RobotMethod) -> Result<Reply, RpcError> {
        self.handle.call(Method::Robot(method))
    }

    /// Number of joints (learnt from the node once, then kept).
    ///
    /// # Errors
    /// The node's error or a transport error on the first call.
    pub fn joint_count(&self) -> Result<usize, RpcError> {
        if let Some(n) = self.joints.get() {
            return Ok(*n);
        }
        let q = match self.robot(RobotMethod::NamedPose {
            pose: NamedPose::Start,
        }) {
            Ok(Reply::Joints(q)) => q,
            Ok(other) => return Err(unexpected("joint values", &other)),
            Err(RpcError::Remote(_)) => match self.robot(RobotMethod::JointPositions)? {
                Reply::Joints(q) => q,
                other => return Err(unexpected("joint values", &other)),
            },
            Err(e) => return Err(e),
        };
        if q.is_empty() || q.len() > MAX_JOINTS {
            return Err(RpcError::Protocol(format!(
                "the node reports {} joints",
                q.len()
            )));
        }
        Ok(*self.joints.get_or_init(|| q.len()))
    }

    /// The wire form of an optional joint vector (`None`: the measured joints), checked finite.
    fn q_msg(&self, q: Option<&JointVector>) -> Result<Option<Joints>, RpcError> {
        let Some(q) = q else { return Ok(None) };
        let n = self.joint_count()?;
        if !q.iter().take(n).all(|x| x.is_finite()) {
            return Err(bad("a joint value is NaN or infinite"));
        }
        Ok(Some(joints_from_vector(q, n)))
    }

    /// Measured joint positions, rad.
    ///
    /// # Errors
    /// [`CallError::NotReady`] before the robot is configured; transport errors.
    pub fn joint_positions(&self) -> Result<JointVector, RpcError> {
        joints_of(self.robot(RobotMethod::JointPositions)?)
    }

    /// Measured joint velocities, rad/s.
    ///
    /// # Errors
    /// As [`RobotProxy::joint_positions`].
    pub fn joint_velocities(&self) -> Result<JointVector, RpcError> {
        joints_of(self.robot(RobotMethod::JointVelocities)?)
    }

    /// Estimated joint accelerations, rad/s².
    ///
    /// # Errors
    /// As [`RobotProxy::joint_positions`].
    pub fn joint_accelerations(&self) -> Result<JointVector, RpcError> {
        joints_of(self.robot(RobotMethod::JointAccelerations)?)
    }

    /// The tool's pose and twist in the base frame at the measured joints. The wire carries no
    /// wrench here: `wrench` is zero (see [`RobotProxy::tool_wrench`]).
    ///
    /// # Errors
    /// As [`RobotProxy::joint_positions`].
    pub fn operational_state(&self) -> Result<OperationalState, RpcError> {
        match self.robot(RobotMethod::Operational)? {
            Reply::Operational(op) => Ok(OperationalState {
                pose: op.pose.to_pose().map_err(|e| bad_reply("pose", &e))?,
                twist: Twist {
                    linear: Vector3::from(op.linear_velocity),
                    angular: Vector3::from(op.angular_velocity),
                    frame: Frame::Base,
                },
                wrench: Wrench::zero(Frame::Base),
            }),
            other => Err(unexpected("an operational state", &other)),
        }
    }

    /// The wrench at the tool from the bound force sensor, N and N·m, base frame.
    ///
    /// # Errors
    /// [`CallError::NotReady`] without a sensor; transport errors.
    pub fn tool_wrench(&self) -> Result<Wrench, RpcError> {
        wrench_of(self.robot(RobotMethod::ToolWrench)?, Frame::Base)
    }

    /// Forward kinematics: the tool pose in the base frame at `q` (rad; `None`: measured). The
    /// rotation's columns are the three orientation versors `n, o, a`.
    ///
    /// # Errors
    /// [`CallError::BadArgument`] for a NaN joint value; the node's errors; transport errors.
    pub fn forward_kinematics(&self, q: Option<&JointVector>) -> Result<Pose, RpcError> {
        let q = self.q_msg(q)?;
        match self.robot(RobotMethod::ForwardKinematics { q })? {
            Reply::Pose(p) => p.to_pose().map_err(|e| bad_reply("pose", &e)),
            other => Err(unexpected("a pose", &other)),
        }
    }

    /// What a 3D viewer needs to draw the robot: its URDF, its frames (root first, the tool
    /// last), its joint names and the contact shapes its simulated tool touches.
    ///
    /// # Errors
    /// The node's error; transport errors.
    pub fn description(&self) -> Result<RobotDescription, RpcError> {
        match self.robot(RobotMethod::Description)? {
            Reply::RobotDescription(d) => Ok(RobotDescription {
                urdf: d.urdf,
                frames: d.frames,
                joint_names: d.joint_names,
                contacts: d.contacts,
            }),
            other => Err(unexpected("a robot description", &other)),
        }
    }

    /// The pose of every frame of [`description`](Self::description)'s `frames` at `q`
    /// (`None`: measured), in the robot's root frame, in the same order.
    ///
    /// # Errors
    /// As [`RobotProxy::forward_kinematics`].
    pub fn link_frames(&self, q: Option<&JointVector>) -> Result<Vec<Pose>, RpcError> {
        let q = self.q_msg(q)?;
        match self.robot(RobotMethod::LinkFrames { q })? {
            Reply::Poses(poses) => poses
                .iter()
                .map(|p| p.to_pose().map_err(|e| bad_reply("pose", &e)))
                .collect(),
            other => Err(unexpected("poses", &other)),
        }
    }

    /// The geometric Jacobian in the base frame at `q` (`None`: measured), rows `[v; ω]`;
    /// columns past the joint count are zero, as for a local model.
    ///
    /// # Errors
    /// As [`RobotProxy::forward_kinematics`].
    pub fn jacobian(&self, q: Option<&JointVector>) -> Result<Jacobian, RpcError> {
        let n = self.joint_count()?;
        let q = self.q_msg(q)?;
        matrix_of(self.robot(RobotMethod::Jacobian { q })?, 6, n, false)
    }

    /// The damped least-squares inverse of the base-frame Jacobian at `q` with damping `lambda`
    /// (around 0.01): joint velocity per unit tool twist; rows past the joint count are zero.
    ///
    /// # Errors
    /// As [`RobotProxy::forward_kinematics`]; a negative or NaN `lambda` is a bad argument.
    pub fn jacobian_inverse(
        &self,
        q: Option<&JointVector>,
        lambda: f64,
    ) -> Result<SMatrix<f64, MAX_JOINTS, 6>, RpcError> {
        if !(lambda.is_finite() && lambda >= 0.0) {
            return Err(bad(format!(
                "damping must be finite and >= 0, got {lambda}"
            )));
        }
        let n = self.joint_count()?;
        let q = self.q_msg(q)?;
        matrix_of(
            self.robot(RobotMethod::JacobianInverse { q, damping: lambda })?,
            n,
            6,
            false,
        )
    }

    /// Inverse kinematics: every branch reaching `pose` within the joint limits (possibly none).
    ///
    /// # Errors
    /// [`CallError::BadArgument`] for a NaN or non-orthonormal pose; the node's errors.
    pub fn inverse_kinematics(&self, pose: &Pose) -> Result<Vec<JointVector>, RpcError> {
        let pose = pose_msg(pose)?;
        match self.robot(RobotMethod::InverseKinematics { pose })? {
            Reply::Solutions(list) => list
                .iter()
                .map(|q| joints_to_vector(q, q.len()).map_err(|e| bad_reply("solution", &e)))
                .collect(),
            other => Err(unexpected("solutions", &other)),
        }
    }

    /// Joint torques (N·m) that balance `wrench` at the tool, `τ = Jᵀ F`, at `q` (`None`:
    /// measured). As for a local model, a wrench in [`Frame::Base`] or [`Frame::Master`] is
    /// taken in the base frame, one in [`Frame::Tool`], [`Frame::Flange`] or [`Frame::Sensor`]
    /// in the tool frame (rotated to the base frame here, with the tool orientation at `q`).
    ///
    /// # Errors
    /// [`CallError::BadArgument`] for a NaN wrench or joint value; the node's errors.
    pub fn wrench_to_torques(
        &self,
        wrench: &Wrench,
        q: Option<&JointVector>,
    ) -> Result<JointVector, RpcError> {
        if !wrench.is_finite() {
            return Err(bad("wrench has a NaN or infinite value"));
        }
        let (base, q) = match wrench.frame {
            Frame::Base | Frame::Master => (*wrench, q.copied()),
            Frame::Tool | Frame::Flange | Frame::Sensor => {
                let q = match q {
                    Some(q) => *q,
                    None => self.joint_positions()?,
                };
                let r = self.forward_kinematics(Some(&q))?.rotation;
                let rotated = Wrench {
                    force: r * wrench.force,
                    torque: r * wrench.torque,
                    frame: Frame::Base,
                };
                (rotated, Some(q))
            }
        };
        let q = self.q_msg(q.as_ref())?;
        joints_of(self.robot(RobotMethod::WrenchToTorques {
            wrench: WrenchMsg::from(&base),
            q,
        })?)
    }

    /// Joint torques (N·m) that hold the arm still at `q` (`None`: measured) against gravity.
    ///
    /// # Errors
    /// As [`RobotProxy::forward_kinematics`].
    pub fn gravity(&self, q: Option<&JointVector>) -> Result<JointVector, RpcError> {
        let q = self.q_msg(q)?;
        joints_of(self.robot(RobotMethod::Gravity { q })?)
    }

    /// The joint-space inertia matrix (kg·m²) at `q` (`None`: measured); rows and columns past
    /// the joint count hold the identity, as for a local model.
    ///
    /// # Errors
    /// As [`RobotProxy::forward_kinematics`].
    pub fn inertia(&self, q: Option<&JointVector>) -> Result<JointSpaceMatrix, RpcError> {
        let n = self.joint_count()?;
        let q = self.q_msg(q)?;
        matrix_of(self.robot(RobotMethod::Inertia { q })?, n, n, true)
    }

    /// Encoder counts (one per joint) to joint positions, rad.
    ///
    /// # Errors
    /// [`CallError::BadArgument`] for a wrong count; the node's errors.
    pub fn counts_to_radians(&self, counts: &[i64]) -> Result<JointVector, RpcError> {
        joints_of(self.robot(RobotMethod::CountsToRadians {
            counts: counts.to_vec(),
        })?)
    }

    /// Joint positions (rad) to the nearest encoder counts.
    ///
    /// # Errors
    /// [`CallError::BadArgument`] for a NaN value; the node's errors.
    pub fn radians_to_counts(&self, q: &JointVector) -> Result<Vec<i64>, RpcError> {
        let q = self.q_msg(Some(q))?.unwrap_or_default();
        match self.robot(RobotMethod::RadiansToCounts { q })? {
            Reply::Counts(c) => Ok(c),
            other => Err(unexpected("encoder counts", &other)),
        }
    }

    /// The joint positions (rad) of a named pose (`nest`, `start`, `work`).
    ///
    /// # Errors
    /// The node's errors; transport errors.
    pub fn named_pose(&self, pose: NamedPose) -> Result<JointVector, RpcError> {
        joints_of(self.robot(RobotMethod::NamedPose { pose })?)
    }

    /// Moves to a named pose in `duration_s` seconds along a smooth joint trajectory through the
    /// robot's active controller (goNested, goStart, goWork). Returns once the motion started.
    ///
    /// # Errors
    /// [`CallError::BadArgument`] for a duration that is not finite and positive;
    /// [`CallError::NotReady`] when no active controller drives the robot.
    pub fn go_to(&self, pose: NamedPose, duration_s: f64) -> Result<(), RpcError> {
        if !(duration_s.is_finite() && duration_s > 0.0) {
            return Err(bad(format!(
                "duration must be finite and > 0 s, got {duration_s}"
            )));
        }
        self.handle
            .unit(Method::Robot(RobotMethod::GoTo { pose, duration_s }))
    }

    /// A duration checked as the node will: finite, in (0, 3600] s.
    fn duration_checked(duration_s: f64) -> Result<f64, RpcError> {
        if duration_s.is_finite() && duration_s > 0.0 && duration_s <= 3600.0 {
            Ok(duration_s)
        } else {
            Err(bad(format!(
                "duration must be finite and in (0, 3600] s, got {duration_s}"
            )))
        }
    }

    /// CRTK `move_jp`: moves to the joint positions `q` (rad) in `duration_s` seconds along a
    /// smooth joint trajectory from the active controller's current reference. Returns once the
    /// motion started; [`RobotProxy::operating_state`]'s `is_busy` stays true until it ends.
    ///
    /// # Errors
    /// [`CallError::BadArgument`] for a non-finite value, a target outside the joint limits or a
    /// duration outside (0, 3600] s; [`CallError::NotReady`] when no active controller follows
    /// a joint trajectory for the robot.
    pub fn move_joints(&self, q: &JointVector, duration_s: f64) -> Result<(), RpcError> {
        let duration_s = Self::duration_checked(duration_s)?;
        let q = self.q_msg(Some(q))?.unwrap_or_default();
        self.handle
            .unit(Method::Robot(RobotMethod::MoveJoints { q, duration_s }))
    }

    /// CRTK `move_cp`: as [`RobotProxy::move_joints`] to a tool pose in the base frame (the
    /// inverse-kinematics branch nearest the current reference).
    ///
    /// # Errors
    /// As [`RobotProxy::move_joints`]; [`CallError::BadArgument`] for a pose the robot cannot
    /// reach within its joint limits.
    pub fn move_tool(&self, pose: &Pose, duration_s: f64) -> Result<(), RpcError> {
        let duration_s = Self::duration_checked(duration_s)?;
        let pose = pose_msg(pose)?;
        self.handle
            .unit(Method::Robot(RobotMethod::MoveTool { pose, duration_s }))
    }

    /// CRTK `servo_jp`: the newest target of a stream; the active controller's reference jumps
    /// to `q` (rad) and stays there. Send one per control period or so: past the controller's
    /// reference watchdog without a new target the loop holds.
    ///
    /// # Errors
    /// As [`RobotProxy::move_joints`], and [`CallError::BadArgument`] for a target farther
    /// than the servo step limit from the current reference.
    pub fn servo_joints(&self, q: &JointVector) -> Result<(), RpcError> {
        let q = self.q_msg(Some(q))?.unwrap_or_default();
        self.handle
            .unit(Method::Robot(RobotMethod::ServoJoints { q }))
    }

    /// CRTK `servo_cp`: as [`RobotProxy::servo_joints`] to a tool pose in the base frame.
    ///
    /// # Errors
    /// As [`RobotProxy::servo_joints`]; [`CallError::BadArgument`] for an unreachable pose.
    pub fn servo_tool(&self, pose: &Pose) -> Result<(), RpcError> {
        let pose = pose_msg(pose)?;
        self.handle
            .unit(Method::Robot(RobotMethod::ServoTool { pose }))
    }

    /// CRTK `setpoint_js` / `setpoint_cp`: the reference the robot's active controller follows
    /// now.
    ///
    /// # Errors
    /// [`CallError::NotReady`] without an active controller or before its first tick.
    pub fn setpoints(&self) -> Result<Setpoints, RpcError> {
        match self.robot(RobotMethod::Setpoints)? {
            Reply::Setpoints(s) => Ok(Setpoints {
                time_ns: s.time_ns,
                joints: s
                    .joints
                    .map(|q| joints_to_vector(&q, q.len()))
                    .transpose()
                    .map_err(|e| bad_reply("joint setpoint", &e))?,
                pose: s
                    .pose
                    .map(|p| p.to_pose())
                    .transpose()
                    .map_err(|e| bad_reply("pose setpoint", &e))?,
            }),
            other => Err(unexpected("setpoints", &other)),
        }
    }

    /// CRTK `operating_state`: `DISABLED`, `ENABLED`, `PAUSED` or `FAULT`, whether the joints
    /// are homed, and whether a move is under way (`is_busy`: wait for a move by polling this
    /// until false, bounded by its duration plus a margin).
    ///
    /// # Errors
    /// The node's error; transport errors.
    pub fn operating_state(&self) -> Result<OperatingStateMsg, RpcError> {
        match self.robot(RobotMethod::OperatingState)? {
            Reply::OperatingState(s) => Ok(s),
            other => Err(unexpected("an operating state", &other)),
        }
    }

    /// Maps joints onto axes of the board `board` (a name on the robot's node), as
    /// `(joint, axis)` pairs, both 0-based. A robot may use several boards.
    ///
    /// # Errors
    /// [`CallError::BadArgument`] for an index past 255 (and the node's own range checks),
    /// [`CallError::UnknownName`] for no such board.
    pub fn map_joints(&self, board: &str, joints: &[(usize, usize)]) -> Result<(), RpcError> {
        let joints = joints
            .iter()
            .map(
                |&(joint, axis)| match (u8::try_from(joint), u8::try_from(axis)) {
                    (Ok(joint), Ok(axis)) => Ok(JointAxis { joint, axis }),
                    _ => Err(bad(format!("joint {joint} or axis {axis} is out of range"))),
                },
            )
            .collect::<Result<Vec<_>, _>>()?;
        self.handle.unit(Method::Robot(RobotMethod::MapJoints {
            board: board.to_string(),
            joints,
        }))
    }
}
