//! Building a controller's loop from its objects, and taking a stopped loop back.

use super::laws::{default_joint_gains, node_law};
use super::trajectories::{build_trajectory, spec_is_tool};
use crate::dataplane::sensor_stream::SensorSubscriber;
use crate::objects::error::ObjectError;
use crate::objects::registry::{
    ControllerConfig, Launch, LoopTiming, RobotKinematics, TeleopObj, bad_arg, not_ready,
    unsupported,
};
use crate::objects::runtime::{
    CellSensor, ControlLaw, ControlTask, GalilSet, GoToCommand, JointBoard, LoopSensorReader,
    RobotLoop, RoutedGains, SimDrive, TelemetryPort, TrajectoryFeed,
};
use crate::objects::teleop::TeleopComm;
use crate::objects::teleop_end::Side;
use crate::objects::{KindState, Registry};
use penelope_drivers::galil::GalilBoard;
use penelope_drivers::model::SerialRobotModel;
use penelope_drivers::sim::force_sensor::{ForceSensorConfig, VirtualForceSensor};
use penelope_drivers::sim::tap::TapWriter;
use penelope_hal::{
    JointSet, JointVector, Kinematics, LifecycleState, MAX_JOINTS, RobotModel, Transition,
};
use penelope_protocol::proto::Class;
use penelope_rt_core::control::{
    AxisBinding, ControlCommand, ControlConfig, ControlLoop, ControlPorts,
};
use penelope_rt_core::controller::JointGroups;
use penelope_rt_core::safety::{HoldMode, SafetyConfig, TeleopRole};

impl Registry {
    /// Builds the loop of controller `name` (configured, inactive) without starting threads.
    /// Takes the robot's board(s) and marks every object it uses.
    pub fn build_loop(&mut self, name: &str, launch: &Launch<'_>) -> Result<Built, ObjectError> {
        let plan = self.loop_plan(name)?;
        self.check_robot_free(&plan.robot)?;
        let inputs = self.sensor_inputs(&plan, launch)?;
        let plant_sensor = self.plant_sensor(&plan, &inputs)?;
        let r = self.robot(&plan.robot)?;
        let model = r.model.clone();
        let kinematics = r.kinematics.clone();
        let (role, caps) = (r.role, r.caps);
        let n = model.joint_count();
        let start = r.start;
        // Controller, and the gains a simulated body holds its pose with.
        let hold = default_joint_gains(&model, n);
        // The objects that become users.
        let mut used = vec![plan.robot.clone()];
        let (source, mut controller) = self.loop_source_and_law(&plan, &model, hold, &mut used)?;
        // A law that adds the sensed wrench turns the sensor's reading into the tool's.
        controller.set_sensor_mount(plant_sensor.map(|c| c.mount).or(inputs.mount));

        let r = self.robot(&plan.robot)?;
        let on_sim = r.body.is_some();
        let maps = r.maps.clone();
        let config = control_config(&plan, role, caps, &model, start, hold, on_sim)?;
        let taken = self.take_boards(&plan.robot, &maps, &model, on_sim, plant_sensor.is_some())?;

        // Ports.
        use penelope_rt_core::cell::latest;
        use penelope_rt_core::ring::ring;
        let (ref_w, ref_r) = crate::objects::reference::reference_port();
        let (tel_w, tel_r) = ring();
        let (comm_w, comm_r) = latest();
        let (probe_w, probe_r) = latest();
        let (mut cmd_w, cmd_r) = ring();
        let stop = std::sync::Arc::new(penelope_rt_core::stop::StopLatch::new());
        let (goto_w, goto_r) = ring();
        let (gains_w, gains_r) = ring();
        let (doorbell, every_sample) = self.teleop_doorbell(&plan, &source);
        let sink = TelemetryPort::new(tel_w, comm_w, probe_w, taken.truth)
            .with_clutch(self.clutch_of(&plan.robot))
            .with_doorbell(doorbell)
            .ringing_every_sample(every_sample);
        let ports = ControlPorts {
            reference: ref_r,
            telemetry: sink,
            commands: penelope_rt_core::stop::StopAwareCommands::new(cmd_r, stop.clone()),
        };
        let cartesian = controller.is_cartesian();
        let lp =
            match ControlLoop::new(config, taken.board, kinematics.clone(), [controller], ports) {
                Ok(l) => l,
                Err(e) => return Err(ObjectError::Internal(format!("control loop: {e}").into())),
            };
        let (lp, wrench_w) = with_sensor(
            lp,
            plant_sensor.zip(taken.contact),
            inputs.replayed,
            inputs.device,
            plan.sensor.is_some(),
            plan.timing,
        );
        let _ = cmd_w.push(ControlCommand::Activate);
        let feed = CommFeed {
            reference: ref_w,
            probe: comm_r,
            goto: goto_r,
            cartesian,
            sensor_mount: plant_sensor.map(|c| c.mount).or(inputs.mount),
        };
        let (motion_w, motion_r) = crate::objects::runtime::motion_port();
        let comm = self
            .comm_task(&plan, source, feed, &kinematics)?
            .with_motion(motion_r);
        let source = match (&plan.sensor, inputs.local) {
            (Some(_), None) => inputs.stream,
            (_, Some(_)) if plant_sensor.is_some() => None,
            (_, Some((local, _))) => Some(crate::objects::runtime::SensorSource::Local(local)),
            _ => None,
        };
        self.mark_users(name, used, &maps, plan.sensor.as_deref());
        Ok(Built {
            control: ControlTask::new(lp, gains_r),
            comm,
            telemetry: tel_r,
            commands: cmd_w,
            stop,
            goto: goto_w,
            motion: motion_w,
            gains: gains_w,
            probe: probe_r,
            wrench: wrench_w,
            source,
            model: kinematics,
            joints: n,
            timing: plan.timing,
        })
    }

    /// Step 1: controller `name` may be activated (a controller, inactive), configured; what
    /// its configuration names.
    fn loop_plan(&mut self, name: &str) -> Result<LoopPlan, ObjectError> {
        let o = self.get(name)?;
        if o.kind.class() != Class::Controller {
            return Err(unsupported(o.kind, "activate"));
        }
        if o.state != LifecycleState::Inactive {
            return Err(ObjectError::InvalidTransition {
                name: name.to_string(),
                state: o.shown_state(),
                transition: Transition::Activate,
            });
        }
        self.configure_controller(name)?;
        let c = self.controller_mut(name)?;
        let timing = c.timing;
        let robot = c.robot.clone().unwrap_or_default();
        let trajectory = c.trajectory.clone().unwrap_or_default();
        let sensor = c.sensor.clone();
        let law = c.config.clone();
        let kind = self.get(name)?.kind.as_str();
        Ok(LoopPlan {
            timing,
            robot,
            trajectory,
            sensor,
            law,
            kind,
        })
    }

    /// Step 2: the robot is configured, used by no loop, and none of its boards' axes is
    /// driven by another loop; its Galil boards are open.
    fn check_robot_free(&self, robot_name: &str) -> Result<(), ObjectError> {
        let robot_obj = self.get(robot_name)?;
        if robot_obj.state != LifecycleState::Inactive {
            return Err(not_ready(format!("robot `{robot_name}` is not configured")));
        }
        if let Some(d) = robot_obj.users.iter().next() {
            return Err(ObjectError::InUse {
                name: robot_name.to_string(),
                dependents: vec![d.clone()],
            });
        }
        let r = self.robot(robot_name)?;
        for (board, joints) in &r.maps {
            for (other_name, other) in &self.objects {
                let KindState::Robot(or) = &other.body else {
                    continue;
                };
                if other_name == robot_name || other.users.is_empty() {
                    continue;
                }
                for (ob, oj) in &or.maps {
                    if ob == board && oj.iter().any(|x| joints.iter().any(|y| x.axis == y.axis)) {
                        return Err(ObjectError::InUse {
                            name: board.clone(),
                            dependents: other.users.iter().cloned().collect(),
                        });
                    }
                }
            }
            if let KindState::Galil(g) = &self.get(board)?.body
                && g.board.is_none()
            {
                let b = self.get(board)?;
                return Err(ObjectError::InUse {
                    name: board.clone(),
                    dependents: b.users.iter().cloned().collect(),
                });
            }
        }
        Ok(())
    }

    /// Step 3: the trajectory and the sensor are configured, and what the loop reads its
    /// wrench from: a local virtual sensor, a recorded stream, a Net F/T, or a sensor on another
    /// node (its stream's reader, made before anything is taken).
    fn sensor_inputs(
        &self,
        plan: &LoopPlan,
        launch: &Launch<'_>,
    ) -> Result<SensorInputs, ObjectError> {
        let grouped = matches!(plan.law, ControllerConfig::Groups(_));
        if !grouped && self.get(&plan.trajectory)?.state == LifecycleState::Unconfigured {
            return Err(not_ready(format!(
                "trajectory `{}` is not configured",
                plan.trajectory
            )));
        }
        let on_this_node = plan.sensor.as_deref().filter(|s| !s.starts_with('/'));
        let local = match on_this_node {
            Some(s) => {
                let so = self.get(s)?;
                if so.state == LifecycleState::Unconfigured {
                    return Err(not_ready(format!("sensor `{s}` is not configured")));
                }
                match &so.body {
                    KindState::Sensor(x) => Some((x.state.clone(), x.config.clone())),
                    _ => None,
                }
            }
            None => None,
        };
        if plan.sensor.as_deref().is_some_and(|s| s.starts_with('/')) && launch.remote.is_none() {
            return Err(not_ready(
                "no remote link to other nodes on this creator (set_remote)",
            ));
        }
        // A recorded wrench stream (`sensor/replay`), played in the loop.
        let replayed = match on_this_node {
            Some(s) => self.replay_sensor(s)?,
            None => None,
        };
        // A sensor kind read in the loop's own thread (a Net F/T): its reader.
        let device = match on_this_node {
            Some(s) => self.loop_sensor_reader(s)?,
            None => None,
        };
        let mount = replayed
            .as_ref()
            .map(penelope_hal::ForceSensor::mount)
            .or(device.as_ref().map(LoopSensorReader::mount));
        let stream = match &plan.sensor {
            Some(path) if path.starts_with('/') => {
                Some(self.sensor_subscriber(path, launch.sensor_stream)?)
            }
            _ => None,
        };
        Ok(SensorInputs {
            local,
            replayed,
            device,
            mount,
            stream,
        })
    }

    /// Step 4: a wrist sensor reading a robot's plant is read in the loop, and only that
    /// robot's.
    fn plant_sensor(
        &self,
        plan: &LoopPlan,
        inputs: &SensorInputs,
    ) -> Result<Option<ForceSensorConfig>, ObjectError> {
        let robot_name = &plan.robot;
        let sensor = || plan.sensor.as_deref().unwrap_or_default();
        Ok(match &inputs.local {
            Some((_, cfg)) => match &cfg.robot {
                Some(r) if r != robot_name => {
                    return Err(bad_arg(format!(
                        "sensor `{}` reads robot `{r}`'s plant, not `{robot_name}`'s",
                        sensor()
                    )));
                }
                Some(_) if self.robot(robot_name)?.body.is_none() => {
                    return Err(bad_arg(format!(
                        "sensor `{}` reads the simulated plant of `{robot_name}`, which is not on \
                         a simulated board",
                        sensor()
                    )));
                }
                Some(_) => Some(cfg.plant_sensor()),
                None => None,
            },
            None => None,
        })
    }

    /// Step 5: what feeds the loop (a trajectory, one end of a teleoperation channel for the
    /// halves of the laws, or one trajectory per joint group) and the law it runs; the objects
    /// they use are added to `used`.
    fn loop_source_and_law(
        &self,
        plan: &LoopPlan,
        model: &SerialRobotModel,
        hold: (JointVector, JointVector),
        used: &mut Vec<String>,
    ) -> Result<(LoopSource, ControlLaw), ObjectError> {
        let (kind, traj_name, law) = (plan.kind, &plan.trajectory, &plan.law);
        if let ControllerConfig::Groups(groups) = law {
            let members = self.group_members(groups, &plan.robot, model, hold)?;
            let (mut laws, mut feeds) = (Vec::new(), Vec::new());
            for m in members {
                laws.push((m.joints, m.law));
                feeds.push((m.joints, m.feed));
                used.push(m.name);
                used.push(m.trajectory);
            }
            let groups = JointGroups::new(model.joint_count(), laws).map_err(|e| {
                ObjectError::BadConfig {
                    kind: kind.into(),
                    message: e.to_string(),
                }
            })?;
            return Ok((
                LoopSource::Groups(feeds),
                ControlLaw::Groups(Box::new(groups)),
            ));
        }
        used.push(traj_name.clone());
        let source = match (&self.get(traj_name)?.body, law.teleop_side()) {
            (KindState::Trajectory(t), None) => LoopSource::Trajectory(TrajectoryFeed::new(
                build_trajectory(&t.spec, model, kind)?,
                spec_is_tool(&t.spec),
            )),
            (KindState::Teleop(t), Some(side)) => {
                check_teleop_end(traj_name, t, side, &plan.robot)?;
                LoopSource::Teleop(
                    side,
                    t.config.mapping(),
                    t.config.link_timeout(plan.timing.comm_period),
                    law.port_law(kind)?,
                )
            }
            (KindState::Teleop(_), None) => {
                return Err(bad_arg(format!(
                    "`{traj_name}` is a teleoperation channel: it is followed by the \
                     halves of the teleoperation laws (force-display, \
                     position-error-master, four-channel-master, slave-tracking, \
                     slave-position, four-channel-slave, wave-master, wave-slave), not by \
                     {kind}"
                )));
            }
            (_, Some(_)) => {
                return Err(bad_arg(format!(
                    "{kind} follows a trajectory/teleop channel; `{traj_name}` is not one"
                )));
            }
            _ => return Err(ObjectError::internal("trajectory body")),
        };
        Ok((source, node_law(law, kind, model, hold)?))
    }

    /// Step 6: takes the robot's board(s): its simulated body (with a fresh tap: the plant's
    /// truth for telemetry, and its contact for a wrist sensor), or its Galil boards, each axis'
    /// effort signed by the model's torque directions.
    fn take_boards(
        &mut self,
        robot_name: &str,
        maps: &[(String, Vec<penelope_protocol::proto::JointAxis>)],
        model: &SerialRobotModel,
        on_sim: bool,
        wrist_on_plant: bool,
    ) -> Result<TakenBoards, ObjectError> {
        if on_sim {
            let KindState::Robot(r) = &mut self.get_mut(robot_name)?.body else {
                return Err(ObjectError::internal("robot body"));
            };
            let mut body = r
                .body
                .take()
                .ok_or_else(|| ObjectError::internal("sim body"))?;
            let mut tap = TapWriter::new();
            let tap_failed = |_| ObjectError::internal("plant tap");
            let truth = Some(tap.reader().map_err(tap_failed)?);
            let contact = if wrist_on_plant {
                Some(tap.reader().map_err(tap_failed)?)
            } else {
                None
            };
            body.set_tap(tap);
            let board = if r.kinematics.is_fpga_board() {
                JointBoard::Fpga(SimDrive::new(body))
            } else {
                JointBoard::Sim(SimDrive::new(body))
            };
            return Ok(TakenBoards {
                board,
                truth,
                contact,
            });
        }
        let n = model.joint_count();
        let mut boards: Vec<(String, GalilBoard)> = Vec::new();
        let mut map = [(0u8, 0u8); MAX_JOINTS];
        for (board, joints) in maps {
            let index = boards.len() as u8;
            let KindState::Galil(g) = &mut self.get_mut(board)?.body else {
                return Err(ObjectError::internal("galil body"));
            };
            let Some(mut b) = g.board.take() else {
                // Put back what was taken before refusing.
                self.give_back(
                    JointBoard::Galil(Box::new(GalilSet::new(boards, map, n))),
                    robot_name,
                );
                return Err(not_ready(format!("board `{board}` is not open")));
            };
            let bindings: Vec<AxisBinding> = joints
                .iter()
                .map(|ja| AxisBinding::new(ja.axis, model.counts_per_radian(ja.joint.into())))
                .collect();
            b.orient(&bindings);
            boards.push((board.clone(), b));
            for ja in joints {
                map[usize::from(ja.joint)] = (index, ja.axis);
            }
        }
        Ok(TakenBoards {
            board: JointBoard::Galil(Box::new(GalilSet::new(boards, map, n))),
            truth: None,
            contact: None,
        })
    }

    /// A teleoperation end's thread wakes on its loop's new safety events, and with
    /// event-driven handoff on every sample: the doorbell of the end `source` takes, if it is
    /// one, and whether every sample rings it (not for a wave-variable law, whose transform
    /// steps once per communication period).
    fn teleop_doorbell(
        &self,
        plan: &LoopPlan,
        source: &LoopSource,
    ) -> (
        Option<std::sync::Arc<penelope_rt_core::wake::Doorbell>>,
        bool,
    ) {
        let LoopSource::Teleop(side, _, _, law) = source else {
            return (None, false);
        };
        match self.objects.get(&plan.trajectory).map(|o| &o.body) {
            Some(KindState::Teleop(t)) => (
                t.link.as_ref().and_then(|l| l.doorbell(*side)),
                t.config.handoff == crate::objects::teleop::Handoff::Event
                    && !matches!(law, crate::objects::teleop_passivity::PortLaw::Wave(_)),
            ),
            _ => (None, false),
        }
    }

    /// Step 7: the communication task: a trajectory's, the joint groups', or a teleoperation
    /// end's (taken from its channel), writing the loop's references.
    fn comm_task(
        &mut self,
        plan: &LoopPlan,
        source: LoopSource,
        feed: CommFeed,
        kinematics: &RobotKinematics,
    ) -> Result<crate::objects::runtime::CommTask, ObjectError> {
        Ok(match source {
            LoopSource::Trajectory(trajectory) => crate::objects::runtime::CommTask::new(
                trajectory,
                feed.reference,
                feed.probe,
                feed.goto,
                kinematics.clone(),
                feed.cartesian,
            ),
            LoopSource::Groups(feeds) => crate::objects::runtime::CommTask::groups(
                feeds,
                feed.reference,
                feed.probe,
                feed.goto,
                kinematics.clone(),
            )?,
            LoopSource::Teleop(side, mapping, link_timeout, port_law) => {
                // The master's clutch is its operator's hand's button, if a hand holds it.
                let clutch = match side {
                    Side::Master => self.clutch_of(&plan.robot),
                    _ => None,
                };
                let Some(KindState::Teleop(t)) =
                    self.objects.get_mut(&plan.trajectory).map(|o| &mut o.body)
                else {
                    return Err(ObjectError::internal("teleop body"));
                };
                let link = t
                    .link
                    .as_mut()
                    .ok_or_else(|| ObjectError::internal("teleop link"))?;
                let end = link
                    .take(side)
                    .ok_or_else(|| ObjectError::internal("teleop end"))?;
                let handoff = t.config.handoff;
                crate::objects::runtime::CommTask::teleop(
                    TeleopComm::new(end, mapping, kinematics.clone())?
                        .with_port_law(port_law, &mapping)?
                        .with_clutch(clutch)
                        .with_sensor_mount(feed.sensor_mount)
                        .with_hand_wrench(side == Side::Master && plan.sensor.is_some())
                        .with_link_timeout(link_timeout)
                        .with_handoff(handoff, plan.timing.period, plan.timing.comm_period),
                    feed.reference,
                    feed.probe,
                    feed.goto,
                    kinematics.clone(),
                )
            }
        })
    }

    /// Step 8: every object the loop uses shows controller `name` as a user: the robot, the
    /// trajectories, the boards and a sensor on this node.
    fn mark_users(
        &mut self,
        name: &str,
        mut used: Vec<String>,
        maps: &[(String, Vec<penelope_protocol::proto::JointAxis>)],
        sensor: Option<&str>,
    ) {
        used.extend(maps.iter().map(|(b, _)| b.clone()));
        if let Some(s) = sensor
            && !s.starts_with('/')
        {
            used.push(s.to_string());
        }
        for u in &used {
            if let Some(o) = self.objects.get_mut(u) {
                o.users.insert(name.to_string());
            }
        }
    }
}

/// What feeds a loop its references (built once per activation: its size costs nothing).
#[allow(clippy::large_enum_variant)]
enum LoopSource {
    /// A trajectory.
    Trajectory(TrajectoryFeed),
    /// One end of a teleoperation channel, the channel's mapping, and how long its link to
    /// another node may be silent.
    Teleop(
        Side,
        penelope_rt_core::teleop::MappingConfig,
        std::time::Duration,
        crate::objects::teleop_passivity::PortLaw,
    ),
    /// One trajectory per joint group.
    Groups(Vec<(JointSet, TrajectoryFeed)>),
}

/// Checks that the controller on `robot` may run `side` of channel `name`, and that the end is
/// free.
fn check_teleop_end(name: &str, t: &TeleopObj, side: Side, robot: &str) -> Result<(), ObjectError> {
    let (expected, word) = match side {
        Side::Master => (&t.config.master, "master"),
        Side::Slave => (&t.config.slave, "slave"),
    };
    if expected != robot {
        return Err(bad_arg(format!(
            "this law is a {word} half, and the {word} of `{name}` is `{expected}`, not `{robot}`"
        )));
    }
    let link = t
        .link
        .as_ref()
        .ok_or_else(|| not_ready(format!("channel `{name}` is not configured")))?;
    if !link.is_local(side) {
        return Err(bad_arg(format!(
            "the {word} end of `{name}` is on another node (its `peer`); run the {word} half there"
        )));
    }
    let free = match side {
        Side::Master => link.master.is_some(),
        Side::Slave => link.slave.is_some(),
    };
    if !free {
        return Err(not_ready(format!(
            "the {word} end of `{name}` is held by a running loop"
        )));
    }
    Ok(())
}

/// What a controller's activation works from: its settings and the names it was configured
/// with.
struct LoopPlan {
    timing: LoopTiming,
    robot: String,
    trajectory: String,
    sensor: Option<String>,
    law: ControllerConfig,
    kind: &'static str,
}

/// Where a loop's wrench comes from (at most one of them is used).
struct SensorInputs {
    /// A virtual sensor on this node: its probe state and configuration.
    local: Option<(
        std::sync::Arc<std::sync::Mutex<crate::objects::runtime::VirtualSensor>>,
        crate::objects::kinds::SensorConfig,
    )>,
    /// A recorded wrench stream.
    replayed: Option<crate::objects::replay::ReplaySensor>,
    /// The reader of a sensor kind read in the loop's own thread (a Net F/T).
    device: Option<LoopSensorReader>,
    /// The mount of the replayed or device sensor.
    mount: Option<penelope_hal::Pose>,
    /// A sensor on another node: its stream's reader.
    stream: Option<crate::objects::runtime::SensorSource>,
}

/// The board a loop drives, and the simulated plant's taps (truth and contact), if any.
struct TakenBoards {
    board: JointBoard,
    truth: Option<penelope_drivers::sim::tap::TapReader>,
    contact: Option<penelope_drivers::sim::tap::TapReader>,
}

/// The communication task's ports and what it needs of the loop.
struct CommFeed {
    reference: crate::objects::reference::ReferenceOut,
    probe: penelope_rt_core::cell::ArcLatestReader<penelope_rt_core::telemetry::TelemetrySample>,
    goto: penelope_rt_core::ring::ArcConsumer<
        GoToCommand,
        { crate::objects::runtime::GOTO_CAPACITY },
    >,
    cartesian: bool,
    sensor_mount: Option<penelope_hal::Pose>,
}

/// Step 5b: the loop's configuration: safety by role (a master: display caps, zero force on
/// a stale reference, amplifiers off on a fault; a slave holds its pose), and axis bindings
/// (encoder zero at the start pose on real boards).
fn control_config(
    plan: &LoopPlan,
    role: TeleopRole,
    caps: (f64, f64),
    model: &SerialRobotModel,
    start: penelope_hal::NamedPose,
    hold: (JointVector, JointVector),
    on_sim: bool,
) -> Result<ControlConfig, ObjectError> {
    let n = model.joint_count();
    let mut safety = match role {
        TeleopRole::Master => {
            let mut s = SafetyConfig::master(n, *model.limits());
            (s.max_force, s.max_moment) = caps;
            s
        }
        TeleopRole::Slave => SafetyConfig::slave(n, *model.limits()),
    };
    safety.watchdog = plan.timing.watchdog;
    let mut config = ControlConfig::new(plan.timing.period, safety);
    let zero = model.named_pose(start);
    for j in 0..n {
        let cpr = model.counts_per_radian(j);
        let mut b = AxisBinding::new(j as u8, cpr);
        if !on_sim {
            b.offset_counts = -((zero[j] * cpr).round() as i64);
        }
        config = config.with_axis(j, b);
    }
    config.safety.hold = if on_sim {
        HoldMode::Pd {
            kp: hold.0,
            kd: hold.1,
        }
    } else {
        HoldMode::BoardServo
    };
    config.validate(n).map_err(|e| ObjectError::BadConfig {
        kind: plan.kind.into(),
        message: e.to_string(),
    })?;
    Ok(config)
}

/// Step 6b: the loop with the sensor it reads in its own thread (the plant's wrist sensor, a
/// replayed stream, a device such as a Net F/T), or with a cell the sensor feed writes (`sensed`: a sensor
/// elsewhere), or none; the cell's writer when there is one.
fn with_sensor(
    lp: crate::objects::runtime::Loop<penelope_rt_core::control::NoSensor>,
    plant: Option<(ForceSensorConfig, penelope_drivers::sim::tap::TapReader)>,
    replayed: Option<crate::objects::replay::ReplaySensor>,
    device: Option<LoopSensorReader>,
    sensed: bool,
    timing: LoopTiming,
) -> (
    RobotLoop,
    Option<
        penelope_rt_core::cell::ArcLatestWriter<
            penelope_rt_core::cell::Stamped<penelope_hal::Wrench>,
        >,
    >,
) {
    if let Some((cfg, contact)) = plant {
        let sensor = VirtualForceSensor::new(cfg, contact);
        (RobotLoop::Plant(Box::new(lp.with_sensor(sensor))), None)
    } else if let Some(sensor) = replayed {
        (RobotLoop::Replayed(Box::new(lp.with_sensor(sensor))), None)
    } else if let Some(sensor) = device {
        (RobotLoop::Device(Box::new(lp.with_sensor(sensor))), None)
    } else if sensed {
        let (w, r) = penelope_rt_core::cell::latest();
        (
            RobotLoop::Sensed(Box::new(
                lp.with_sensor(CellSensor::new(r, timing.sensor_timeout)),
            )),
            Some(w),
        )
    } else {
        (RobotLoop::Plain(Box::new(lp)), None)
    }
}

/// Everything an activation built, before threads start.
pub(crate) struct Built {
    pub control: ControlTask,
    pub comm: crate::objects::runtime::CommTask,
    pub telemetry: penelope_rt_core::ring::ArcConsumer<
        crate::objects::tick::TickRecord,
        { crate::objects::runtime::TELEMETRY_CAPACITY },
    >,
    pub commands: penelope_rt_core::ring::ArcProducer<
        ControlCommand,
        { crate::objects::runtime::COMMAND_CAPACITY },
    >,
    /// The loop's stop latch: an e-stop that needs no room in `commands`.
    pub stop: std::sync::Arc<penelope_rt_core::stop::StopLatch>,
    pub goto: penelope_rt_core::ring::ArcProducer<
        GoToCommand,
        { crate::objects::runtime::GOTO_CAPACITY },
    >,
    /// Servo targets to the communication task, and its moves' status.
    pub motion: crate::objects::runtime::MotionControl,
    pub gains: penelope_rt_core::ring::ArcProducer<
        RoutedGains,
        { crate::objects::runtime::GAINS_CAPACITY },
    >,
    pub probe:
        penelope_rt_core::cell::ArcLatestReader<penelope_rt_core::telemetry::TelemetrySample>,
    pub wrench: Option<
        penelope_rt_core::cell::ArcLatestWriter<
            penelope_rt_core::cell::Stamped<penelope_hal::Wrench>,
        >,
    >,
    pub source: Option<crate::objects::runtime::SensorSource>,
    pub model: RobotKinematics,
    pub joints: usize,
    pub timing: LoopTiming,
}

impl Registry {
    /// The loop's reader of sensor `name`, if it is a kind read in the loop's own thread.
    fn loop_sensor_reader(&self, name: &str) -> Result<Option<LoopSensorReader>, ObjectError> {
        match self.objects.get(name).map(|o| &o.body) {
            Some(KindState::LoopSensor(s)) => s.loop_reader().map(Some),
            _ => Ok(None),
        }
    }

    /// The reader of the sensor at naming `path` on another node, published at `address`.
    ///
    /// # Errors
    /// [`ObjectError::NotReady`] without an address, [`ObjectError::BadArgument`] for a stream off
    /// loopback on a node without a secret, [`ObjectError::Device`] when no socket can be bound.
    fn sensor_subscriber(
        &self,
        path: &str,
        address: Option<std::net::SocketAddr>,
    ) -> Result<crate::objects::runtime::SensorSource, ObjectError> {
        let address = address.ok_or_else(|| {
            not_ready(format!(
                "sensor `{path}`: its data-plane address is not known (SensorMethod::Stream)"
            ))
        })?;
        if !address.ip().is_loopback() && self.datagram_key.is_none() {
            return Err(bad_arg(format!(
                "sensor `{path}` is published off loopback ({address}): the nodes need a \
                 secret (--secret-file) so that its datagrams are authenticated"
            )));
        }
        let keys = self
            .datagram_key
            .as_ref()
            .map(|k| crate::dataplane::sensor_stream::sensor_reader_keys(k, path));
        let subscriber = SensorSubscriber::connect_directed(address, keys)
            .map_err(|e| ObjectError::device(format!("data plane: reader of `{path}`"), e))?;
        Ok(crate::objects::runtime::SensorSource::Stream(Box::new(
            subscriber,
        )))
    }
}
