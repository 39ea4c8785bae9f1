//! The trajectories a node runs and the communication task that publishes their references.

use super::{GOTO_CAPACITY, SPLINE_CAPACITY};
use crate::objects::error::ObjectError;
use crate::objects::reference::ReferenceOut;
use crate::objects::runtime::RobotKinematics;
use crate::objects::teleop::TeleopComm;
use penelope_hal::{
    Frame, InverseKinematics, JacobianFrame, JointReference, JointSet, JointVector, Kinematics,
    MAX_JOINTS, Reference, Timestamp, Trajectory, TrajectoryError, Twist,
};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Fresh, Stamped, latest};
use penelope_rt_core::ring::ArcConsumer;
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_rt_core::trajectory::{
    CubicSpline, Goal, Ramp, SplineEnds, Step, Trapezoidal, Waypoint,
};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// The trajectories a node runs. Inline, not boxed: a GoTo swaps the variant in the
/// communication thread, which must not allocate or free.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum TrajectoryGenerator {
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

impl TrajectoryGenerator {
    fn inner(&mut self) -> &mut dyn Trajectory {
        match self {
            TrajectoryGenerator::Step(t) => t,
            TrajectoryGenerator::Ramp(t) => t,
            TrajectoryGenerator::Trapezoidal(t) => t,
            TrajectoryGenerator::Spline(t) => t,
            TrajectoryGenerator::GoTo(t) => t,
        }
    }

    /// The duration once started (`None` if unknown).
    pub fn duration(&self) -> Option<Duration> {
        match self {
            TrajectoryGenerator::Step(_) | TrajectoryGenerator::Ramp(_) => None,
            TrajectoryGenerator::Trapezoidal(t) => t.duration(),
            TrajectoryGenerator::Spline(t) => Some(t.duration()),
            TrajectoryGenerator::GoTo(t) => Some(t.duration()),
        }
    }

    /// A GoTo motion to `goal` lasting `duration`.
    ///
    /// # Errors
    /// [`ObjectError::BadArgument`] for a non-finite goal or a zero duration.
    pub fn go_to(goal: JointVector, duration: Duration) -> Result<Self, ObjectError> {
        CubicSpline::<1>::new(
            &[Waypoint {
                at: duration,
                goal: Goal::Joint(goal),
            }],
            SplineEnds::Clamped,
        )
        .map(TrajectoryGenerator::GoTo)
        .map_err(|e| ObjectError::BadArgument(format!("go-to motion: {e}")))
    }
}

impl Trajectory for TrajectoryGenerator {
    fn kind(&self) -> &'static str {
        match self {
            TrajectoryGenerator::GoTo(_) => "go-to",
            TrajectoryGenerator::Step(t) => t.kind(),
            TrajectoryGenerator::Ramp(t) => t.kind(),
            TrajectoryGenerator::Trapezoidal(t) => t.kind(),
            TrajectoryGenerator::Spline(t) => t.kind(),
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
            TrajectoryGenerator::Step(t) => t.is_finished(now),
            TrajectoryGenerator::Ramp(t) => t.is_finished(now),
            TrajectoryGenerator::Trapezoidal(t) => t.is_finished(now),
            TrajectoryGenerator::Spline(t) => t.is_finished(now),
            TrajectoryGenerator::GoTo(t) => t.is_finished(now),
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

/// The largest servo step (CRTK `servo_jp` / `servo_cp`): a target farther than this from the
/// current reference, on any joint, is refused, so a stream cannot jump the arm. 0.05 rad per
/// target is 50 rad/s at one target per millisecond: loose for a stream, tight for a mistake.
pub const MAX_SERVO_STEP_RAD: f64 = 0.05;

/// A move (GoTo, `move_jp`, `move_cp`) is over once its spline has ended and every joint is
/// within this of the goal, rad...
pub const MOVE_SETTLED_RAD: f64 = 1e-3;

/// ...or this long after its spline ended, settled or not (a robot pushing against something
/// never settles; a client waiting on `is_busy` must not wait forever).
pub const MOVE_SETTLE_TIMEOUT: Duration = Duration::from_secs(2);

/// A servo target (CRTK `servo_jp`; `servo_cp` after inverse kinematics): the reference jumps to
/// `q` and stays there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoTarget {
    /// Joint positions, rad.
    pub q: JointVector,
}

/// What the communication task tells the node about moves and servo targets: counters only,
/// atomics, so neither side waits for the other.
#[derive(Debug, Default)]
pub struct MotionStatus {
    /// Moves handed to the GoTo ring (counted by the node before the push).
    requested: AtomicU64,
    /// Moves the communication task took and saw end (reached, superseded, cancelled by a
    /// servo target, abandoned for a fault).
    completed: AtomicU64,
    /// Servo targets the communication task dropped because they were farther than
    /// [`MAX_SERVO_STEP_RAD`] from its reference when they arrived.
    servo_dropped: AtomicU64,
}

impl MotionStatus {
    /// Whether a move is queued or under way (CRTK `is_busy`).
    pub fn is_busy(&self) -> bool {
        self.completed.load(Ordering::Acquire) < self.requested.load(Ordering::Acquire)
    }

    /// Servo targets dropped by the communication task's own step check.
    pub fn servo_dropped(&self) -> u64 {
        self.servo_dropped.load(Ordering::Relaxed)
    }
}

/// The node's end of a loop's motion port: servo targets in, the motion status out.
pub struct MotionControl {
    servo: ArcLatestWriter<ServoTarget>,
    status: Arc<MotionStatus>,
}

impl MotionControl {
    /// Counts a move about to be pushed onto the GoTo ring (before the push, so that
    /// [`MotionStatus::is_busy`] is true from the moment the call returns).
    pub fn move_requested(&self) {
        self.status.requested.fetch_add(1, Ordering::AcqRel);
    }

    /// Takes back [`move_requested`](Self::move_requested) when the push failed.
    pub fn move_not_queued(&self) {
        self.status.requested.fetch_sub(1, Ordering::AcqRel);
    }

    /// Hands a servo target to the communication task (newest wins: one it has not taken yet is
    /// replaced).
    pub fn servo(&mut self, target: ServoTarget) {
        self.servo.write(target);
    }

    /// The motion status.
    pub fn status(&self) -> &MotionStatus {
        &self.status
    }
}

impl std::fmt::Debug for MotionControl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MotionControl")
            .field("status", &self.status)
            .finish_non_exhaustive()
    }
}

/// The communication task's end of a motion port.
pub struct MotionPort {
    servo: ArcLatestReader<ServoTarget>,
    status: Arc<MotionStatus>,
}

/// A new motion port, split into its two ends. Allocates here, once: a latest-value cell for
/// servo targets (newest wins, no queue to fill: a stream faster than the communication period
/// loses only superseded targets) and the shared counters.
pub fn motion_port() -> (MotionControl, MotionPort) {
    let (w, r) = latest();
    let status = Arc::new(MotionStatus::default());
    (
        MotionControl {
            servo: w,
            status: status.clone(),
        },
        MotionPort { servo: r, status },
    )
}

/// A move under way in a communication task.
#[derive(Clone, Copy, Debug)]
struct ActiveMove {
    goal: JointVector,
    /// When its spline ends.
    end: Timestamp,
}

/// Where a communication task's references come from.
// One per loop, built before its thread starts: inline, so a GoTo swaps it without allocating.
#[allow(clippy::large_enum_variant)]
enum ReferenceSource {
    /// A trajectory (and the GoTo motions that replace it).
    Trajectory(TrajectoryFeed),
    /// One end of a teleoperation channel.
    Teleop(Box<TeleopComm>),
    /// One trajectory per joint group (`controller/joint-groups`), merged joint by joint.
    Groups(Box<heapless::Vec<(JointSet, TrajectoryFeed), MAX_JOINTS>>),
}

/// One trajectory as a communication task runs it: started from the measured state (no jump),
/// replaced by GoTo motions, and, when its goals are tool poses and the law is a joint law,
/// followed through inverse kinematics.
pub struct TrajectoryFeed {
    trajectory: TrajectoryGenerator,
    /// The trajectory's goals are tool poses (it starts from the measured tool pose).
    tool_goals: bool,
    started: bool,
    last: Option<JointReference>,
    /// When `last` was produced by inverse kinematics (for its velocity).
    last_at: Option<Timestamp>,
    /// Tool references a joint law could not follow (no inverse kinematics solution near the
    /// last one): not published, so the loop's watchdog holds the robot if they persist.
    ik_failures: u64,
}

impl TrajectoryFeed {
    /// A feed of `trajectory`; `tool_goals` when its goals are tool poses.
    pub fn new(trajectory: TrajectoryGenerator, tool_goals: bool) -> Self {
        TrajectoryFeed {
            trajectory,
            tool_goals,
            started: false,
            last: None,
            last_at: None,
            ik_failures: 0,
        }
    }

    /// Where the trajectory (or a GoTo) starts: the last joint reference, else the measured
    /// joints; as a tool pose for tool goals.
    fn from(&self, measured: JointVector, model: &RobotKinematics) -> Reference {
        let joints = self.last.unwrap_or(JointReference {
            position: measured,
            ..JointReference::default()
        });
        if self.tool_goals {
            Reference::Cartesian(penelope_hal::CartesianReference {
                pose: model.forward(&joints.position),
                twist: Twist::default(),
            })
        } else {
            Reference::Joint(joints)
        }
    }

    /// Starts the trajectory on the first call.
    fn start_once(&mut self, now: Timestamp, measured: JointVector, model: &RobotKinematics) {
        if !self.started {
            let from = self.from(measured, model);
            self.trajectory.start(now, &from);
            self.started = true;
        }
    }

    /// Abandons the motion for a hold at `measured` (a motion interrupted by an e-stop or a
    /// fault is not resumed by the reset: only a new command moves the robot again).
    fn hold_at(&mut self, now: Timestamp, measured: JointVector) {
        if let Ok(mut hold) = TrajectoryGenerator::go_to(measured, Duration::from_millis(1)) {
            let here = Reference::Joint(JointReference {
                position: measured,
                ..JointReference::default()
            });
            hold.start(now, &here);
            self.trajectory = hold;
            self.tool_goals = false;
            self.started = true;
            self.last = None;
            self.last_at = None;
        }
    }

    /// Replaces the trajectory by a joint-space GoTo motion from the current reference.
    fn go_to(
        &mut self,
        mut motion: TrajectoryGenerator,
        now: Timestamp,
        measured: JointVector,
        model: &RobotKinematics,
    ) {
        self.tool_goals = false;
        let from = self.from(measured, model);
        motion.start(now, &from);
        self.trajectory = motion;
    }

    /// The reference at `now`: a joint reference, converted from a tool pose through inverse
    /// kinematics unless `cartesian` (a law that follows poses). `None` when there is nothing to
    /// publish (trajectory error, non-finite value, no inverse kinematics solution).
    fn next(
        &mut self,
        now: Timestamp,
        measured: JointVector,
        model: &RobotKinematics,
        cartesian: bool,
    ) -> Option<Reference> {
        let r = self.trajectory.reference(now).ok()?;
        if !r.is_finite() {
            return None;
        }
        match r {
            Reference::Joint(j) => {
                self.last = Some(j);
                Some(r)
            }
            // A tool reference for a joint law: the inverse kinematics branch nearest the last
            // joint reference, its velocity from the previous solution.
            Reference::Cartesian(c) if !cartesian => {
                let seed = self.last.map_or(measured, |j| j.position);
                let Ok(q) = model.inverse_near(&c.pose, &seed) else {
                    self.ik_failures += 1;
                    return None;
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
                Some(Reference::Joint(j))
            }
            other => Some(other),
        }
    }
}

/// A joint reference as a Cartesian law follows it: forward kinematics and `J qd`.
fn cartesian_of(model: &RobotKinematics, j: &JointReference) -> Reference {
    let pose = model.forward(&j.position);
    let v = model.jacobian(&j.position, JacobianFrame::Base) * j.velocity;
    Reference::Cartesian(penelope_hal::CartesianReference {
        pose,
        twist: Twist {
            linear: v.fixed_rows::<3>(0).into(),
            angular: v.fixed_rows::<3>(3).into(),
            frame: Frame::Base,
        },
    })
}

/// The per-tick body of a communication thread: starts the trajectory from the measured state
/// (no jump), swaps in GoTo motions from the current reference (no jump in position or velocity),
/// converts joint references to Cartesian ones for a Cartesian law (forward kinematics and
/// `J qd`), and publishes the stamped reference. Like rt-core's `CommLoop`, plus the conversion.
pub struct CommTask {
    source: ReferenceSource,
    writer: ReferenceOut,
    state: ArcLatestReader<TelemetrySample>,
    goto: ArcConsumer<GoToCommand, GOTO_CAPACITY>,
    model: RobotKinematics,
    cartesian: bool,
    measured: Option<JointVector>,
    published: u64,
    /// Since the loop latched a fault or e-stop, and until it runs again (or a GoTo comes):
    /// the motion was interrupted, the trajectory is a hold where the robot is.
    reanchoring: bool,
    /// Servo targets in, move status out (none for a task built without one).
    motion: Option<MotionPort>,
    /// Moves taken from the GoTo ring.
    moves_taken: u64,
    /// The move under way, until it ends.
    active_move: Option<ActiveMove>,
    /// In servo mode: when the newest servo target was taken. The reference is published with
    /// this stamp, so that the loop's watchdog sees a stream that stopped.
    servo_since: Option<Timestamp>,
    /// In servo mode: the newest target, with the velocity between it and the one before (a
    /// feed-forward, so that a joint law follows a stream without lagging it).
    servo_ref: Option<JointReference>,
    /// The joint reference published last.
    last_q: Option<JointVector>,
}

impl CommTask {
    /// A task publishing `trajectory` into `writer`; `cartesian` for a law that follows poses.
    pub fn new(
        trajectory: TrajectoryFeed,
        writer: ReferenceOut,
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
        writer: ReferenceOut,
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
            measured: None,
            published: 0,
            reanchoring: false,
            motion: None,
            moves_taken: 0,
            active_move: None,
            servo_since: None,
            servo_ref: None,
            last_q: None,
        }
    }

    /// The same task taking servo targets from `port` and reporting its moves there.
    pub fn with_motion(mut self, port: MotionPort) -> Self {
        self.motion = Some(port);
        self
    }

    /// The newest servo target not taken yet, if it is within [`MAX_SERVO_STEP_RAD`] of the
    /// current reference (`reference`); a farther one is dropped and counted.
    fn take_servo(&mut self, reference: JointVector) -> Option<JointVector> {
        let port = self.motion.as_mut()?;
        let Fresh::New(target) = port.servo.read() else {
            return None;
        };
        let n = self.model.joint_count().min(MAX_JOINTS);
        let within = (0..n).all(|j| {
            target.q[j].is_finite() && (target.q[j] - reference[j]).abs() <= MAX_SERVO_STEP_RAD
        });
        if within {
            Some(target.q)
        } else {
            port.status.servo_dropped.fetch_add(1, Ordering::Relaxed);
            None
        }
    }

    /// Ends the move under way (if any) and reports every move taken so far as ended.
    fn end_move(&mut self) {
        self.active_move = None;
        if let Some(port) = &self.motion {
            port.status
                .completed
                .store(self.moves_taken, Ordering::Release);
        }
    }

    /// Ends the move under way once its spline has ended and the robot settled at its goal
    /// (or [`MOVE_SETTLE_TIMEOUT`] after the spline's end).
    fn check_move(&mut self, now: Timestamp, measured: &JointVector) {
        let Some(m) = self.active_move else {
            return;
        };
        if now < m.end {
            return;
        }
        let n = self.model.joint_count().min(MAX_JOINTS);
        let settled = (0..n).all(|j| (measured[j] - m.goal[j]).abs() <= MOVE_SETTLED_RAD);
        if settled || now.saturating_since(m.end) >= MOVE_SETTLE_TIMEOUT {
            self.end_move();
        }
    }

    /// A task publishing one joint reference merged from one trajectory per joint group (each
    /// group's joints from its own trajectory), for a `controller/joint-groups` loop.
    ///
    /// # Errors
    /// [`ObjectError::BadArgument`] for more than [`MAX_JOINTS`] groups.
    pub fn groups(
        feeds: Vec<(JointSet, TrajectoryFeed)>,
        writer: ReferenceOut,
        state: ArcLatestReader<TelemetrySample>,
        goto: ArcConsumer<GoToCommand, GOTO_CAPACITY>,
        model: RobotKinematics,
    ) -> Result<Self, ObjectError> {
        let mut set = heapless::Vec::new();
        for feed in feeds {
            set.push(feed)
                .map_err(|_| ObjectError::BadArgument(format!("more than {MAX_JOINTS} groups")))?;
        }
        let source = ReferenceSource::Groups(Box::new(set));
        Ok(CommTask::with_source(
            source, writer, state, goto, model, false,
        ))
    }

    /// Tool references a joint law could not follow so far.
    pub fn ik_failures(&self) -> u64 {
        match &self.source {
            ReferenceSource::Trajectory(f) => f.ik_failures,
            ReferenceSource::Groups(g) => g.iter().map(|(_, f)| f.ik_failures).sum(),
            ReferenceSource::Teleop(_) => 0,
        }
    }

    /// A task running one end of a teleoperation channel instead of a trajectory (GoTo
    /// requests are refused by the creator before they reach it).
    pub fn teleop(
        teleop: TeleopComm,
        writer: ReferenceOut,
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
            _ => None,
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
        let sample = self.state.latest();
        if let Some(s) = sample {
            self.measured = Some(s.q);
        }
        // The loop has not measured yet: start from the measured state, not zeros.
        let Some(measured) = self.measured else {
            return;
        };
        let goto = self.goto.pop();
        if goto.is_some() {
            self.moves_taken += 1;
        }
        // A servo target (checked against the reference published last) cancels a move: CRTK's
        // servo commands take over from move commands. A GoTo taken in the same tick wins.
        let reference = self.last_q.unwrap_or(measured);
        let servo = self.take_servo(reference).filter(|_| goto.is_none());
        // A motion interrupted by a latched fault or e-stop is abandoned for a hold where the
        // robot is, re-taken every tick while latched and after the re-arm until the loop
        // follows it (the loop holds until a reference starts where it holds the robot): the
        // reset does not start motion, a new command (a GoTo) does.
        use penelope_rt_core::safety::SafetyState;
        let state = sample.map(|s| s.state);
        if matches!(state, Some(SafetyState::Fault | SafetyState::EStop)) {
            self.reanchoring = true;
        }
        if state == Some(SafetyState::Running) || goto.is_some() || servo.is_some() {
            self.reanchoring = false;
        }
        let reanchor = self.reanchoring;
        // A servo stream that stopped: the loop's watchdog saw the stale stamp and holds; the
        // task then holds where the robot is with fresh stamps, so the loop runs on, still,
        // instead of faulting after `stale_to_fault`.
        let stream_stopped = servo.is_none()
            && self.servo_since.is_some_and(|at| {
                sample.is_some_and(|s| s.state == SafetyState::Holding && s.time > at)
            });
        if reanchor || stream_stopped || goto.is_some() {
            self.servo_since = None;
            self.servo_ref = None;
        }
        // A fault abandons the move, a servo target cancels it.
        if reanchor || servo.is_some() {
            self.end_move();
        }
        if let Some(q) = servo {
            let velocity = match (self.servo_ref, self.servo_since) {
                (Some(previous), Some(at)) if now > at => {
                    (q - previous.position) / now.saturating_since(at).as_secs_f64()
                }
                _ => JointVector::zeros(),
            };
            self.servo_ref = Some(JointReference {
                position: q,
                velocity,
                acceleration: JointVector::zeros(),
            });
            self.servo_since = Some(now);
        }
        if let Some(cmd) = goto {
            self.servo_since = None;
            self.active_move = Some(ActiveMove {
                goal: cmd.goal,
                end: now + cmd.duration,
            });
        }
        let hold_here = reanchor || (stream_stopped && goto.is_none());
        let model = &self.model;
        let out = match &mut self.source {
            ReferenceSource::Teleop(_) => return,
            ReferenceSource::Trajectory(feed) => {
                if hold_here {
                    feed.hold_at(now, measured);
                }
                feed.start_once(now, measured, model);
                if let Some(q) = servo {
                    feed.hold_at(now, q);
                }
                if let Some(cmd) = goto
                    && let Ok(motion) = TrajectoryGenerator::go_to(cmd.goal, cmd.duration)
                {
                    feed.go_to(motion, now, measured, model);
                }
                match feed.next(now, measured, model, self.cartesian) {
                    Some(Reference::Joint(j)) if self.cartesian => cartesian_of(model, &j),
                    Some(r) => r,
                    None => return,
                }
            }
            ReferenceSource::Groups(feeds) => {
                let mut merged = JointReference {
                    position: measured,
                    ..JointReference::default()
                };
                for (joints, feed) in feeds.iter_mut() {
                    if hold_here {
                        feed.hold_at(now, measured);
                    }
                    feed.start_once(now, measured, model);
                    // A servo target moves the whole robot, as a GoTo does.
                    if let Some(q) = servo {
                        feed.hold_at(now, q);
                    }
                    // A GoTo moves the whole robot: every group to its joints of the goal.
                    if let Some(cmd) = goto
                        && let Ok(motion) = TrajectoryGenerator::go_to(cmd.goal, cmd.duration)
                    {
                        feed.go_to(motion, now, measured, model);
                    }
                    // Every group every tick, or nothing: a group without a reference leaves
                    // the loop's watchdog to hold the robot.
                    let Some(Reference::Joint(r)) = feed.next(now, measured, model, false) else {
                        return;
                    };
                    for j in joints.iter() {
                        merged.position[j] = r.position[j];
                        merged.velocity[j] = r.velocity[j];
                        merged.acceleration[j] = r.acceleration[j];
                    }
                }
                Reference::Joint(merged)
            }
        };
        // In servo mode the target itself, with its velocity (the feeds hold its position, for
        // when the mode ends).
        let out = match self.servo_ref {
            Some(j) if self.cartesian => cartesian_of(&self.model, &j),
            Some(j) => Reference::Joint(j),
            None => out,
        };
        match (&out, self.cartesian) {
            _ if self.servo_ref.is_some() => self.last_q = self.servo_ref.map(|j| j.position),
            (Reference::Joint(j), _) => self.last_q = Some(j.position),
            // A Cartesian law's joint trajectory was converted: its joints are the feed's.
            (Reference::Cartesian(_), true) => {
                self.last_q = match &self.source {
                    ReferenceSource::Trajectory(f) => f.last.map(|j| j.position),
                    _ => None,
                }
            }
            _ => self.last_q = None,
        }
        self.writer.write(Stamped {
            stamp: self.servo_since.unwrap_or(now),
            value: out,
        });
        self.published += 1;
        self.check_move(now, &measured);
        if self.active_move.is_none() {
            self.end_move();
        }
    }

    /// An early wake at `now`, between ticks (a teleoperation end's doorbell or socket): the
    /// end sends an urgent sample of its own and hands on one of the other side's
    /// ([`TeleopComm::early`]). Other sources have nothing to do between ticks.
    ///
    /// # Real-time
    /// As [`tick`](Self::tick).
    pub fn early(&mut self, now: Timestamp) {
        if let ReferenceSource::Teleop(t) = &mut self.source {
            let state = self.state.latest();
            t.early(now, state, &mut self.writer);
        }
    }

    /// What wakes this task's thread before its period: a teleoperation end's doorbell and
    /// socket; `None` for a trajectory (it only ticks).
    ///
    /// # Errors
    /// The OS's, when the socket's descriptor cannot be duplicated.
    pub fn wake_on(&self) -> std::io::Result<Option<penelope_rt_core::wake::WakeOn>> {
        match &self.source {
            ReferenceSource::Teleop(t) => t.wake_on(),
            _ => Ok(None),
        }
    }

    /// References published so far.
    pub fn published(&self) -> u64 {
        self.published
    }

    /// Whether this is a teleoperation end whose samples cross as they are made
    /// ([`Handoff::Event`](crate::objects::teleop::Handoff::Event)).
    pub fn is_event_driven(&self) -> bool {
        matches!(&self.source, ReferenceSource::Teleop(t) if t.is_event_driven())
    }

    /// The side of the teleoperation channel this task runs (`None` for a trajectory): its
    /// control loop's tick phase follows from it ([`Side::tick_phase`](crate::objects::teleop::Side::tick_phase)).
    pub fn teleop_side(&self) -> Option<crate::objects::teleop::Side> {
        match &self.source {
            ReferenceSource::Teleop(t) => Some(t.side()),
            _ => None,
        }
    }

    /// Samples a teleoperation end has sent to the other side so far (`None` for a
    /// trajectory).
    pub fn teleop_samples_sent(&self) -> Option<u64> {
        match &self.source {
            ReferenceSource::Teleop(t) => Some(t.samples_sent()),
            _ => None,
        }
    }
}
