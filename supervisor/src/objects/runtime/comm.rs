//! The trajectories a node runs and the communication task that publishes their references.

use super::*;

/// The trajectories a node runs. Inline, not boxed: a GoTo swaps the variant in the
/// communication thread, which must not allocate or free.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum NodeTrajectory {
    /// A step.
    Step(Step),
    /// A ramp.
    Ramp(Ramp),
    /// A trapezoidal move.
    Trapezoidal(Trapezoidal),
    /// A configured spline.
    Spline(CubicSpline<SPLINE_CAPACITY>),
    /// A GoTo motion (clamped spline from the current reference).
    GoTo(CubicSpline<1>),
}

impl NodeTrajectory {
    fn inner(&mut self) -> &mut dyn Trajectory {
        match self {
            NodeTrajectory::Step(t) => t,
            NodeTrajectory::Ramp(t) => t,
            NodeTrajectory::Trapezoidal(t) => t,
            NodeTrajectory::Spline(t) => t,
            NodeTrajectory::GoTo(t) => t,
        }
    }

    /// The duration once started (`None` if unknown).
    pub fn duration(&self) -> Option<Duration> {
        match self {
            NodeTrajectory::Step(_) | NodeTrajectory::Ramp(_) => None,
            NodeTrajectory::Trapezoidal(t) => t.duration(),
            NodeTrajectory::Spline(t) => Some(t.duration()),
            NodeTrajectory::GoTo(t) => Some(t.duration()),
        }
    }

    /// A GoTo motion to `goal` lasting `duration`.
    ///
    /// # Errors
    /// [`WireError::BadArgument`] for a non-finite goal or a zero duration.
    pub fn go_to(goal: JointVector, duration: Duration) -> Result<Self, WireError> {
        CubicSpline::<1>::new(
            &[Waypoint {
                at: duration,
                goal: Goal::Joint(goal),
            }],
            SplineEnds::Clamped,
        )
        .map(NodeTrajectory::GoTo)
        .map_err(|e| WireError::BadArgument(format!("go-to motion: {e}")))
    }
}

impl Trajectory for NodeTrajectory {
    fn kind(&self) -> &'static str {
        match self {
            NodeTrajectory::GoTo(_) => "go-to",
            NodeTrajectory::Step(t) => t.kind(),
            NodeTrajectory::Ramp(t) => t.kind(),
            NodeTrajectory::Trapezoidal(t) => t.kind(),
            NodeTrajectory::Spline(t) => t.kind(),
        }
    }
    fn start(&mut self, now: Timestamp, from: &Reference) {
        self.inner().start(now, from);
    }
    fn reference(&mut self, now: Timestamp) -> Result<Reference, TrajectoryError> {
        self.inner().reference(now)
    }
    fn is_finished(&self, now: Timestamp) -> bool {
        match self {
            NodeTrajectory::Step(t) => t.is_finished(now),
            NodeTrajectory::Ramp(t) => t.is_finished(now),
            NodeTrajectory::Trapezoidal(t) => t.is_finished(now),
            NodeTrajectory::Spline(t) => t.is_finished(now),
            NodeTrajectory::GoTo(t) => t.is_finished(now),
        }
    }
}

/// A GoTo request to a communication task.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GoToCommand {
    /// Goal joints, rad.
    pub goal: JointVector,
    /// Duration.
    pub duration: Duration,
}

/// Where a communication task's references come from.
// One per loop, built before its thread starts: inline, so a GoTo swaps it without allocating.
#[allow(clippy::large_enum_variant)]
enum ReferenceSource {
    /// A trajectory (and the GoTo motions that replace it).
    Trajectory(NodeTrajectory),
    /// One end of a teleoperation channel.
    Teleop(Box<TeleopComm>),
}

/// The per-tick body of a communication thread: starts the trajectory from the measured state
/// (no jump), swaps in GoTo motions from the current reference (no jump in position or velocity),
/// converts joint references to Cartesian ones for a Cartesian law (forward kinematics and
/// `J qd`), and publishes the stamped reference. Like rt-core's `CommLoop`, plus the conversion.
pub struct CommTask {
    source: ReferenceSource,
    writer: RefWriter,
    state: ArcLatestReader<TelemetrySample>,
    goto: ArcConsumer<GoToCommand, GOTO_CAPACITY>,
    model: RobotKinematics,
    cartesian: bool,
    /// The trajectory's goals are tool poses (it starts from the measured tool pose).
    tool_goals: bool,
    started: bool,
    last: Option<JointReference>,
    /// When `last` was produced by inverse kinematics (for its velocity).
    last_at: Option<Timestamp>,
    measured: Option<JointVector>,
    published: u64,
    /// Tool references a joint law could not follow (no inverse kinematics solution near the
    /// last one): not published, so the loop's watchdog holds the robot if they persist.
    ik_failures: u64,
}

impl CommTask {
    /// A task publishing `trajectory` into `writer`; `cartesian` for a law that follows poses.
    pub fn new(
        trajectory: NodeTrajectory,
        writer: RefWriter,
        state: ArcLatestReader<TelemetrySample>,
        goto: ArcConsumer<GoToCommand, GOTO_CAPACITY>,
        model: RobotKinematics,
        cartesian: bool,
    ) -> Self {
        let source = ReferenceSource::Trajectory(trajectory);
        CommTask::with_source(source, writer, state, goto, model, cartesian)
    }

    fn with_source(
        source: ReferenceSource,
        writer: RefWriter,
        state: ArcLatestReader<TelemetrySample>,
        goto: ArcConsumer<GoToCommand, GOTO_CAPACITY>,
        model: RobotKinematics,
        cartesian: bool,
    ) -> Self {
        CommTask {
            source,
            writer,
            state,
            goto,
            model,
            cartesian,
            tool_goals: false,
            started: false,
            last: None,
            last_at: None,
            measured: None,
            published: 0,
            ik_failures: 0,
        }
    }

    /// Tells the task that the trajectory's goals are tool poses: it starts from the measured
    /// tool pose, and a joint law follows its references through inverse kinematics.
    pub fn with_tool_goals(mut self, tool_goals: bool) -> Self {
        self.tool_goals = tool_goals;
        self
    }

    /// Tool references a joint law could not follow so far.
    pub fn ik_failures(&self) -> u64 {
        self.ik_failures
    }

    /// A task running one end of a teleoperation channel instead of a trajectory (GoTo
    /// requests are refused by the creator before they reach it).
    pub fn teleop(
        teleop: TeleopComm,
        writer: RefWriter,
        state: ArcLatestReader<TelemetrySample>,
        goto: ArcConsumer<GoToCommand, GOTO_CAPACITY>,
        model: RobotKinematics,
    ) -> Self {
        CommTask::with_source(
            ReferenceSource::Teleop(Box::new(teleop)),
            writer,
            state,
            goto,
            model,
            true,
        )
    }

    /// The teleoperation channel's end, given back when the loop stops.
    pub fn into_teleop_end(self) -> Option<crate::objects::teleop::TeleopEnd> {
        match self.source {
            ReferenceSource::Teleop(t) => Some(t.into_end()),
            ReferenceSource::Trajectory(_) => None,
        }
    }

    fn from(&self) -> Reference {
        let joints = self.last.unwrap_or(JointReference {
            position: self.measured.unwrap_or_else(JointVector::zeros),
            ..JointReference::default()
        });
        if self.tool_goals {
            Reference::Cartesian(penelope_hal::CartesianReference {
                pose: self.model.forward(&joints.position),
                twist: Twist::default(),
            })
        } else {
            Reference::Joint(joints)
        }
    }

    /// One communication tick at `now`.
    ///
    /// # Real-time
    /// No allocation, no locks: cell reads and writes, one ring pop, bounded spline set-up.
    pub fn tick(&mut self, now: Timestamp) {
        if let ReferenceSource::Teleop(t) = &mut self.source {
            let state = self.state.latest();
            t.tick(now, state, &mut self.writer);
            self.published += 1;
            return;
        }
        if let Some(s) = self.state.latest() {
            self.measured = Some(s.q);
        }
        if self.measured.is_none() {
            return; // the loop has not measured yet: start from the measured state, not zeros
        }
        if !self.started {
            let from = self.from();
            if let ReferenceSource::Trajectory(t) = &mut self.source {
                t.start(now, &from);
            }
            self.started = true;
        }
        if let Some(cmd) = self.goto.pop()
            && let Ok(mut t) = NodeTrajectory::go_to(cmd.goal, cmd.duration)
        {
            // A GoTo moves in joint space, from the current joint reference.
            self.tool_goals = false;
            let from = self.from();
            t.start(now, &from);
            self.source = ReferenceSource::Trajectory(t);
        }
        let ReferenceSource::Trajectory(trajectory) = &mut self.source else {
            return;
        };
        let Ok(r) = trajectory.reference(now) else {
            return;
        };
        if !r.is_finite() {
            return;
        }
        let out = match r {
            Reference::Joint(j) => {
                self.last = Some(j);
                if self.cartesian {
                    let pose = self.model.forward(&j.position);
                    let v = self.model.jacobian(&j.position, JacobianFrame::Base) * j.velocity;
                    Reference::Cartesian(penelope_hal::CartesianReference {
                        pose,
                        twist: Twist {
                            linear: v.fixed_rows::<3>(0).into(),
                            angular: v.fixed_rows::<3>(3).into(),
                            frame: Frame::Base,
                        },
                    })
                } else {
                    r
                }
            }
            // A tool reference for a joint law: the inverse kinematics branch nearest the last
            // joint reference, its velocity from the previous solution.
            Reference::Cartesian(c) if !self.cartesian => {
                let seed = self
                    .last
                    .map(|j| j.position)
                    .or(self.measured)
                    .unwrap_or_else(JointVector::zeros);
                let Ok(q) = self.model.inverse_near(&c.pose, &seed) else {
                    self.ik_failures += 1;
                    return;
                };
                let velocity = match (self.last, self.last_at) {
                    (Some(l), Some(at)) if now > at => {
                        (q - l.position) / now.saturating_since(at).as_secs_f64()
                    }
                    _ => JointVector::zeros(),
                };
                let j = JointReference {
                    position: q,
                    velocity,
                    acceleration: JointVector::zeros(),
                };
                self.last = Some(j);
                self.last_at = Some(now);
                Reference::Joint(j)
            }
            other => other,
        };
        self.writer.write(Stamped {
            stamp: now,
            value: out,
        });
        self.published += 1;
    }

    /// References published so far.
    pub fn published(&self) -> u64 {
        self.published
    }
}
