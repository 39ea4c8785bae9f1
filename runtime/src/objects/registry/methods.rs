//! The methods every object answers, by class.

use super::crtk_methods::move_duration;
use super::trajectories::{build_standalone, build_trajectory, spec_joints};
use crate::objects::error::ObjectError;
use crate::objects::registry::{
    Object, TrajectorySpec, bad_arg, finite3, not_ready, unreachable_body,
};
use crate::objects::{KindState, Registry};
use penelope_drivers::galil::GalilBoard;
use penelope_hal::{
    AxisState, Board, Dynamics, Frame, InverseKinematics, JacobianFrame, JointState, JointVector,
    Kinematics, LifecycleState, MAX_AXES, MAX_JOINTS, RobotModel, Timestamp,
};
use penelope_protocol::proto::{
    BoardMethod, Class, ContactShapeMsg, JointAxis, Joints, MatrixMsg, OperationalMsg, PoseMsg,
    ReferenceMsg, Reply, RobotDescriptionMsg, RobotMethod, SensorMethod, TrajectoryMethod,
    WrenchMsg, joints_from_vector, joints_to_vector,
};
use std::time::Duration;

impl Registry {
    /// The measured joint state of `robot`: from its running loop, its simulated body, or its
    /// Galil boards.
    fn measured(&mut self, robot: &str) -> Result<(JointState, JointVector), ObjectError> {
        if let Some(c) = self.driver_of(robot)
            && let Ok(ctrl) = self.controller_mut(&c)
            && let Some(run) = &ctrl.running
        {
            let Some(n) = run.shared.newest() else {
                return Err(not_ready(format!(
                    "robot `{robot}`: its loop has not ticked yet"
                )));
            };
            let s = n.sample;
            return Ok((
                JointState {
                    position: s.q,
                    velocity: s.qd,
                    effort: s.effort,
                },
                n.acceleration,
            ));
        }
        let r = self.robot(robot)?;
        if let Some(b) = &r.body {
            return Ok((b.plant().snapshot().joints, JointVector::zeros()));
        }
        let model = r.model.clone();
        let zero = model.named_pose(r.start);
        let maps = r.maps.clone();
        let mut state = JointState::default();
        let mut any = false;
        for (board, joints) in &maps {
            let Ok(Object {
                body: KindState::Galil(g),
                ..
            }) = self.get_mut(board)
            else {
                continue;
            };
            let Some(b) = g.board.as_mut() else { continue };
            let mut axes = [AxisState::default(); MAX_AXES];
            let count = b.axis_count().min(MAX_AXES);
            b.read_axes(
                penelope_rt_core::clock::MonotonicClock::read(),
                &mut axes[..count],
            )
            .map_err(|e| ObjectError::device(format!("board `{board}`"), e))?;
            for ja in joints {
                let j = usize::from(ja.joint);
                let cpr = model.counts_per_radian(j);
                let offset = -((zero[j] * cpr).round() as i64);
                let a = axes[usize::from(ja.axis)];
                state.position[j] = a.position.wrapping_sub(offset) as f64 / cpr;
                state.velocity[j] = a.velocity / cpr;
                any = true;
            }
        }
        if any {
            Ok((state, JointVector::zeros()))
        } else {
            Err(not_ready(format!("robot `{robot}` is not configured")))
        }
    }

    fn q_or_measured(
        &mut self,
        robot: &str,
        q: &Option<Joints>,
    ) -> Result<JointVector, ObjectError> {
        let n = self.robot(robot)?.model.joint_count();
        match q {
            Some(q) => Ok(joints_to_vector(q, n)?),
            None => Ok(self.measured(robot)?.0.position),
        }
    }

    /// The contact shapes of the simulated boards `robot` is mapped onto (in its base frame).
    pub(crate) fn contacts_of(&self, robot: &str) -> Result<Vec<ContactShapeMsg>, ObjectError> {
        let mut contacts = Vec::new();
        for (board, _) in &self.robot(robot)?.maps {
            let Ok(Object {
                body: KindState::SimBoard(s),
                ..
            }) = self.get(board)
            else {
                continue;
            };
            let env = crate::objects::kinds::environment(
                crate::objects::kinds::Kind::SIM_BOARD.as_str(),
                &s.config.shapes,
            )?;
            contacts.extend(
                env.shapes()
                    .iter()
                    .map(|c| crate::objects::recording::scene::contact_shape_msg(&c.shape)),
            );
        }
        Ok(contacts)
    }

    pub fn robot_method(&mut self, name: &str, m: RobotMethod) -> Result<Reply, ObjectError> {
        match m {
            RobotMethod::JointPositions
            | RobotMethod::JointVelocities
            | RobotMethod::JointAccelerations
            | RobotMethod::Operational => self.measured_state(name, m),
            RobotMethod::ToolWrench => self.tool_wrench(name),
            RobotMethod::GoTo { pose, duration_s } => self.go_to(name, pose, duration_s),
            RobotMethod::MapJoints { board, joints } => self.map_joints(name, board, joints),
            RobotMethod::MoveJoints { q, duration_s } => self.move_joints(name, &q, duration_s),
            RobotMethod::MoveTool { pose, duration_s } => self.move_tool(name, pose, duration_s),
            RobotMethod::ServoJoints { q } => self.servo_joints(name, &q),
            RobotMethod::ServoTool { pose } => self.servo_tool(name, pose),
            RobotMethod::Setpoints => self.setpoints(name),
            RobotMethod::OperatingState => self.operating_state(name),
            m => self.robot_model_method(name, m),
        }
    }

    /// What the robot's model computes, at given joints or the measured ones: nothing here
    /// moves the robot or changes the object.
    fn robot_model_method(&mut self, name: &str, m: RobotMethod) -> Result<Reply, ObjectError> {
        let n = self.robot(name)?.model.joint_count();
        match m {
            RobotMethod::Description
            | RobotMethod::CountsToRadians { .. }
            | RobotMethod::RadiansToCounts { .. }
            | RobotMethod::NamedPose { .. } => self.robot_model_facts(name, m),
            RobotMethod::LinkFrames { q } => {
                let q = self.q_or_measured(name, &q)?;
                Ok(Reply::Poses(
                    self.robot(name)?
                        .model
                        .link_frames(&q)
                        .iter()
                        .map(PoseMsg::from)
                        .collect(),
                ))
            }
            RobotMethod::ForwardKinematics { q } => {
                let q = self.q_or_measured(name, &q)?;
                Ok(Reply::Pose(PoseMsg::from(
                    &self.robot(name)?.kinematics.forward(&q),
                )))
            }
            RobotMethod::Jacobian { q } => {
                let q = self.q_or_measured(name, &q)?;
                let j = self
                    .robot(name)?
                    .kinematics
                    .jacobian(&q, JacobianFrame::Base);
                Ok(Reply::Matrix(MatrixMsg::from_block(&j, 6, n)))
            }
            RobotMethod::JacobianInverse { q, damping } => {
                if !(damping.is_finite() && (0.0..=10.0).contains(&damping)) {
                    return Err(bad_arg("damping must be finite, 0..=10"));
                }
                let q = self.q_or_measured(name, &q)?;
                let j = self
                    .robot(name)?
                    .kinematics
                    .jacobian_damped_inverse(&q, damping);
                Ok(Reply::Matrix(MatrixMsg::from_block(&j, n, 6)))
            }
            RobotMethod::InverseKinematics { pose } => {
                let pose = pose.to_pose()?;
                let mut out = penelope_hal::IkSolutions::new();
                let model = &self.robot(name)?.model;
                let _ = model.inverse_all(&pose, &mut out);
                Ok(Reply::Solutions(
                    out.iter()
                        .filter(|s| s.within_limits)
                        .map(|s| joints_from_vector(&s.q, n))
                        .collect(),
                ))
            }
            RobotMethod::WrenchToTorques { wrench, q } => {
                let w = wrench.to_wrench(Frame::Base)?;
                let q = self.q_or_measured(name, &q)?;
                let tau = self
                    .robot(name)?
                    .kinematics
                    .wrench_to_torques(&q, &w)
                    .map_err(|e| bad_arg(e.to_string()))?;
                Ok(Reply::Joints(joints_from_vector(&tau, n)))
            }
            RobotMethod::Gravity { q } => {
                let q = self.q_or_measured(name, &q)?;
                Ok(Reply::Joints(joints_from_vector(
                    &self.robot(name)?.model.gravity(&q),
                    n,
                )))
            }
            RobotMethod::Inertia { q } => {
                let q = self.q_or_measured(name, &q)?;
                let m = self.robot(name)?.model.inertia(&q);
                Ok(Reply::Matrix(MatrixMsg::from_block(&m, n, n)))
            }
            _ => Err(ObjectError::internal("robot method dispatch")),
        }
    }

    /// What the robot's model is: its description (URDF, frames, joints, the contact shapes it
    /// meets), its encoder scaling and its named poses.
    fn robot_model_facts(&self, name: &str, m: RobotMethod) -> Result<Reply, ObjectError> {
        let n = self.robot(name)?.model.joint_count();
        match m {
            RobotMethod::Description => {
                let model = &self.robot(name)?.model;
                Ok(Reply::RobotDescription(RobotDescriptionMsg {
                    urdf: model.urdf(),
                    frames: model.link_names(),
                    joint_names: model.joint_names().to_vec(),
                    contacts: self.contacts_of(name)?,
                }))
            }
            RobotMethod::CountsToRadians { counts } => {
                if counts.len() != n {
                    return Err(bad_arg(format!(
                        "expected {n} counts, got {}",
                        counts.len()
                    )));
                }
                let model = &self.robot(name)?.model;
                Ok(Reply::Joints(
                    counts
                        .iter()
                        .enumerate()
                        .map(|(j, c)| *c as f64 / model.counts_per_radian(j))
                        .collect(),
                ))
            }
            RobotMethod::RadiansToCounts { q } => {
                let q = joints_to_vector(&q, n)?;
                let model = &self.robot(name)?.model;
                Ok(Reply::Counts(
                    (0..n)
                        .map(|j| (q[j] * model.counts_per_radian(j)).round() as i64)
                        .collect(),
                ))
            }
            RobotMethod::NamedPose { pose } => Ok(Reply::Joints(joints_from_vector(
                &self.robot(name)?.model.named_pose(pose),
                n,
            ))),
            _ => Err(ObjectError::internal("robot method dispatch")),
        }
    }

    /// The robot's measured joint state, or its tool's operational state.
    fn measured_state(&mut self, name: &str, m: RobotMethod) -> Result<Reply, ObjectError> {
        let n = self.robot(name)?.model.joint_count();
        match m {
            RobotMethod::JointPositions => Ok(Reply::Joints(joints_from_vector(
                &self.measured(name)?.0.position,
                n,
            ))),
            RobotMethod::JointVelocities => Ok(Reply::Joints(joints_from_vector(
                &self.measured(name)?.0.velocity,
                n,
            ))),
            RobotMethod::JointAccelerations => Ok(Reply::Joints(joints_from_vector(
                &self.measured(name)?.1,
                n,
            ))),
            RobotMethod::Operational => {
                let s = self.measured(name)?.0;
                let model = &self.robot(name)?.model;
                let o = model.operational_state(&s);
                Ok(Reply::Operational(OperationalMsg {
                    pose: PoseMsg::from(&o.pose),
                    linear_velocity: o.twist.linear.into(),
                    angular_velocity: o.twist.angular.into(),
                }))
            }
            _ => Err(ObjectError::internal("robot method dispatch")),
        }
    }

    /// The wrench the sensor of the controller driving `name` measured last.
    fn tool_wrench(&mut self, name: &str) -> Result<Reply, ObjectError> {
        let driver = self.driver_of(name).ok_or_else(|| {
            not_ready(format!(
                "robot `{name}` is not driven by an active controller"
            ))
        })?;
        let c = self.controller_mut(&driver)?;
        if c.sensor.is_none() {
            return Err(not_ready(format!(
                "controller `{driver}` has no force sensor"
            )));
        }
        let s = c
            .running
            .as_ref()
            .and_then(|r| r.shared.newest())
            .ok_or_else(|| not_ready("no sample yet"))?;
        Ok(Reply::Wrench(WrenchMsg::from(&s.sample.wrench)))
    }

    /// Queues a move of `name` to a named pose, for the controller driving it.
    fn go_to(
        &mut self,
        name: &str,
        pose: penelope_hal::NamedPose,
        duration_s: f64,
    ) -> Result<Reply, ObjectError> {
        let duration = move_duration(duration_s)?;
        let goal = self.robot(name)?.model.named_pose(pose);
        self.start_move(name, goal, duration)
    }

    /// Maps joints of `name` onto axes of `board` (before configure).
    fn map_joints(
        &mut self,
        name: &str,
        board: String,
        joints: Vec<JointAxis>,
    ) -> Result<Reply, ObjectError> {
        let n = self.robot(name)?.model.joint_count();
        let o = self.get(name)?;
        if o.state != LifecycleState::Unconfigured {
            return Err(not_ready(format!(
                "map the joints of `{name}` before configure (cleanup first)"
            )));
        }
        penelope_protocol::proto::check_name(&board)?;
        if joints.is_empty() || joints.len() > MAX_JOINTS {
            return Err(bad_arg(format!("map 1 to {MAX_JOINTS} joints")));
        }
        for (i, ja) in joints.iter().enumerate() {
            if usize::from(ja.joint) >= n {
                return Err(bad_arg(format!("robot `{name}` has no joint {}", ja.joint)));
            }
            if usize::from(ja.axis) >= MAX_AXES {
                return Err(bad_arg(format!("axis {} is past {MAX_AXES}", ja.axis)));
            }
            if joints[..i]
                .iter()
                .any(|o| o.joint == ja.joint || o.axis == ja.axis)
            {
                return Err(bad_arg("a joint or an axis appears twice"));
            }
        }
        let KindState::Robot(r) = &mut self.get_mut(name)?.body else {
            return Err(ObjectError::internal("robot body"));
        };
        // Replaces this board's mapping; joints mapped elsewhere move here.
        r.maps.retain(|(b, _)| b != &board);
        for (_, js) in r.maps.iter_mut() {
            js.retain(|x| !joints.iter().any(|y| y.joint == x.joint));
        }
        r.maps.retain(|(_, js)| !js.is_empty());
        let previous = std::mem::take(&mut r.maps);
        r.maps.clone_from(&previous);
        r.maps.push((board, joints));
        // An fpga board takes the FRHC only, and all of it: refused here already when
        // the board exists (again at configure, when every board must).
        if let Err(e) = self.fpga_board_of(name) {
            if let KindState::Robot(r) = &mut self.get_mut(name)?.body {
                r.maps = previous;
            }
            return Err(e);
        }
        Ok(Reply::Unit)
    }

    pub fn board_method(&mut self, name: &str, m: BoardMethod) -> Result<Reply, ObjectError> {
        let o = self.expect_class(name, Class::Board)?;
        let active = !o.users.is_empty();
        match (&o.body, m) {
            (KindState::SimBoard(s), BoardMethod::AxisCount) => Ok(Reply::Count(s.config.axes)),
            (KindState::Galil(g), BoardMethod::AxisCount) => Ok(Reply::Count(g.config.axes)),
            (_, BoardMethod::AmplifiersEnabled) => self.amplifiers_enabled(name, active),
            (_, BoardMethod::Rearm) if active => Err(not_ready(format!(
                "board `{name}` is driven by `{}`: re-arm that controller (it re-arms the board \
                 and its loop)",
                o.users.iter().next().cloned().unwrap_or_default()
            ))),
            (KindState::Galil(g), BoardMethod::Rearm) => match &g.board {
                Some(b) => {
                    b.rearm();
                    Ok(Reply::Unit)
                }
                None => Err(not_ready(format!(
                    "board `{name}` is not open (configure it)"
                ))),
            },
            // A simulated board latches nothing.
            (_, BoardMethod::Rearm) => Ok(Reply::Unit),
            (_, BoardMethod::ReadEncoders) => self.read_encoders(name, active),
            _ => Err(ObjectError::internal("board body")),
        }
    }

    /// Whether board `name`'s amplifiers are on: an idle board says what the device holds, a
    /// driven one what its loop's safety state implies.
    fn amplifiers_enabled(&mut self, name: &str, active: bool) -> Result<Reply, ObjectError> {
        let o = self.get(name)?;
        // An idle board says what the device holds (a failed loop may leave a position
        // board holding); a driven one, what its loop's safety state implies.
        if !active {
            let on = match &o.body {
                KindState::Galil(g) => g.board.as_ref().is_some_and(GalilBoard::is_enabled),
                _ => self.objects.values().any(|r| match &r.body {
                    KindState::Robot(r) => {
                        r.maps.iter().any(|(b, _)| b == name)
                            && r.body.as_ref().is_some_and(|b| b.is_enabled())
                    }
                    _ => false,
                }),
            };
            return Ok(Reply::Flag(on));
        }
        let user = o.users.iter().next().cloned().unwrap_or_default();
        let c = self.controller_mut(&user)?;
        let on = c
            .running
            .as_ref()
            .and_then(|r| r.shared.newest())
            .is_some_and(|n| {
                use penelope_rt_core::safety::SafetyState;
                matches!(
                    n.sample.state,
                    SafetyState::Running | SafetyState::Holding | SafetyState::Fault
                )
            });
        Ok(Reply::Flag(on))
    }

    /// Board `name`'s encoder counts: read from an idle Galil, else from the measured state of
    /// every robot mapped onto it.
    fn read_encoders(&mut self, name: &str, active: bool) -> Result<Reply, ObjectError> {
        let o = self.get(name)?;
        let axes = match &o.body {
            KindState::SimBoard(s) => s.config.axes as usize,
            KindState::Galil(g) => g.config.axes as usize,
            _ => 0,
        };
        let mut counts = vec![0i64; axes];
        if let KindState::Galil(_) = &o.body
            && !active
        {
            let KindState::Galil(g) = &mut self.get_mut(name)?.body else {
                unreachable_body()?
            };
            let b = g
                .board
                .as_mut()
                .ok_or_else(|| not_ready(format!("board `{name}` is not configured")))?;
            let mut st = [AxisState::default(); MAX_AXES];
            let count = b.axis_count().min(MAX_AXES);
            b.read_axes(
                penelope_rt_core::clock::MonotonicClock::read(),
                &mut st[..count],
            )
            .map_err(|e| ObjectError::device(format!("board `{name}`"), e))?;
            for (c, s) in counts.iter_mut().zip(st.iter()) {
                *c = s.position;
            }
            return Ok(Reply::Counts(counts));
        }
        // Every robot mapped onto it: its joints' counts from the measured state.
        let robots: Vec<(String, Vec<JointAxis>)> = self
            .objects
            .iter()
            .filter_map(|(rn, ro)| match &ro.body {
                KindState::Robot(r) => r
                    .maps
                    .iter()
                    .find(|(b, _)| b == name)
                    .map(|(_, j)| (rn.clone(), j.clone())),
                _ => None,
            })
            .collect();
        for (rn, joints) in robots {
            let Ok((state, _)) = self.measured(&rn) else {
                continue;
            };
            let r = self.robot(&rn)?;
            let zero = r.model.named_pose(r.start);
            let on_sim = r.body.is_some() || matches!(self.get(name)?.body, KindState::SimBoard(_));
            for ja in joints {
                let j = usize::from(ja.joint);
                let cpr = r.model.counts_per_radian(j);
                let offset = if on_sim {
                    0
                } else {
                    -((zero[j] * cpr).round() as i64)
                };
                if let Some(c) = counts.get_mut(usize::from(ja.axis)) {
                    *c = (state.position[j] * cpr).floor() as i64 + offset;
                }
            }
        }
        Ok(Reply::Counts(counts))
    }

    pub fn sensor_method(&mut self, name: &str, m: SensorMethod) -> Result<Reply, ObjectError> {
        let o = self.expect_class(name, Class::Sensor)?;
        if o.state == LifecycleState::Unconfigured {
            return Err(not_ready(format!("sensor `{name}` is not configured")));
        }
        let s = match &o.body {
            KindState::Sensor(s) => s,
            KindState::Hand(h) => {
                return Err(ObjectError::Unsupported {
                    kind: o.kind.as_str().into(),
                    method: format!(
                        "{m:?} (the hand pushes `{}`'s simulated handle; what it feels is in \
                         that robot's telemetry)",
                        h.config.robot
                    )
                    .into(),
                });
            }
            KindState::LoopSensor(s) => return s.method(o.kind, m),
            KindState::Camera(_) => return Err(super::camera::camera_method(o.kind, m)),
            KindState::ReplaySensor(_) | KindState::OperatorReplay(_) => {
                return Err(ObjectError::Unsupported {
                    kind: o.kind.as_str().into(),
                    method: format!(
                        "{m:?} (a replay plays its recording to the loop that uses it; the                          readings are in that loop's telemetry)"
                    ).into(),
                });
            }
            _ => return Err(ObjectError::internal("sensor body")),
        };
        if m == SensorMethod::Stream {
            return self.sensor_stream(name, s);
        }
        let state = s.state.clone();
        let mut st = state
            .lock()
            .map_err(|_| ObjectError::Poisoned("sensor state"))?;
        match m {
            SensorMethod::Read => Ok(Reply::Wrench(WrenchMsg::from(&st.read()))),
            SensorMethod::Bias => {
                st.bias();
                Ok(Reply::Unit)
            }
            SensorMethod::SetProbe { pose, velocity } => {
                let pose = pose.to_pose()?;
                let v = finite3(velocity)?;
                st.measure(&pose, v);
                Ok(Reply::Unit)
            }
            SensorMethod::Measure { pose, velocity } => {
                let pose = pose.to_pose()?;
                let v = finite3(velocity)?;
                Ok(Reply::Wrench(WrenchMsg::from(&st.measure(&pose, v))))
            }
            SensorMethod::Stream => unreachable_body(),
        }
    }

    pub fn trajectory_method(
        &mut self,
        name: &str,
        m: TrajectoryMethod,
    ) -> Result<Reply, ObjectError> {
        let o = self.expect_class(name, Class::Trajectory)?;
        let t = match &o.body {
            KindState::Trajectory(t) => t,
            KindState::Teleop(_) => {
                return Err(ObjectError::Unsupported {
                    kind: o.kind.as_str().into(),
                    method: format!(
                        "{m:?} (a teleoperation channel's reference is what the other side sends)"
                    )
                    .into(),
                });
            }
            _ => return Err(ObjectError::internal("trajectory body")),
        };
        let spec = t.spec.clone();
        let kind = o.kind.as_str();
        // Standalone: started at t = 0 from zero joints of the goal's length; a goal that names
        // a pose needs a robot (the one of a controller using it).
        let robot_model = self
            .objects
            .values()
            .find_map(|c| match &c.body {
                KindState::Controller(x) if x.trajectory.as_deref() == Some(name) => {
                    x.robot.clone()
                }
                _ => None,
            })
            .and_then(|r| self.robot(&r).ok().map(|r| r.model.clone()));
        let mut traj = match &robot_model {
            Some(m) => build_trajectory(&spec, m, kind)?,
            None => build_standalone(&spec, kind)?,
        };
        let n = robot_model
            .as_ref()
            .map_or_else(|| spec_joints(&spec), |m| m.joint_count());
        use penelope_hal::Trajectory;
        traj.start(
            Timestamp::ZERO,
            &penelope_hal::Reference::Joint(penelope_hal::JointReference::default()),
        );
        match m {
            TrajectoryMethod::Duration => Ok(Reply::Duration(match &spec {
                TrajectorySpec::Step { delay, .. } => Some(delay.as_secs_f64()),
                TrajectorySpec::Ramp { duration, .. } => Some(duration.as_secs_f64()),
                _ => traj.duration().map(|d| d.as_secs_f64()),
            })),
            TrajectoryMethod::Reference { t_s } => {
                if !(t_s.is_finite() && (0.0..=1e6).contains(&t_s)) {
                    return Err(bad_arg("t_s must be finite, 0..=1e6"));
                }
                let r = traj
                    .reference(Timestamp::ZERO + Duration::from_secs_f64(t_s))
                    .map_err(|e| not_ready(e.to_string()))?;
                Ok(Reply::Reference(match r {
                    penelope_hal::Reference::Joint(j) => ReferenceMsg::Joint {
                        q: joints_from_vector(&j.position, n),
                        qd: joints_from_vector(&j.velocity, n),
                    },
                    penelope_hal::Reference::Cartesian(c) => ReferenceMsg::Cartesian {
                        pose: PoseMsg::from(&c.pose),
                    },
                    penelope_hal::Reference::Wrench(w) => ReferenceMsg::Wrench {
                        wrench: WrenchMsg::from(&w),
                    },
                    penelope_hal::Reference::Hybrid(h) => ReferenceMsg::Cartesian {
                        pose: PoseMsg::from(&h.motion.pose),
                    },
                }))
            }
        }
    }
}
