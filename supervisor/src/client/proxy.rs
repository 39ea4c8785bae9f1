//! Typed proxies of remote objects: the methods of the local objects (DESIGN.md section 1, the
//! paper's `Puma200` class), with the math types of `hal` at the edges, so that code using a
//! remote robot reads like code using a local one.
//!
//! Every proxy holds the object's reference (node address and name), resolved once; its class
//! was checked when the proxy was made. Arguments are checked before they are sent (a NaN joint
//! value, a non-orthonormal pose or a non-positive duration is refused with
//! [`WireError::BadArgument`] without a round trip). The joint count of a robot is learnt from
//! the node on first use and kept.

use std::sync::OnceLock;

use nalgebra::{SMatrix, Vector3};
use penelope_hal::{
    CartesianReference, Frame, Jacobian, JointReference, JointSpaceMatrix, JointVector,
    LifecycleState, MAX_JOINTS, NamedPose, OperationalState, Pose, Reference, Transition, Twist,
    Wrench,
};

use super::{Client, parse_address, unexpected};
use crate::net::conn::RpcError;
use crate::proto::{
    BoardMethod, Class, ControlStatus, ControllerMethod, JointAxis, Joints, MatrixMsg, Method,
    ObjectInfo, ObjectRef, PoseMsg, ReferenceMsg, Reply, RobotMethod, SensorMethod,
    TrajectoryMethod, WireError, WrenchMsg, joints_from_vector, joints_to_vector, object_path,
};

/// A reference to one remote object and the client that reaches it: what every proxy wraps.
#[derive(Clone, Debug)]
pub struct ObjectHandle {
    client: Client,
    reference: ObjectRef,
    address: std::net::SocketAddr,
}

impl ObjectHandle {
    /// A handle of the object `reference` names.
    ///
    /// # Errors
    /// [`RpcError::Protocol`] when the reference's address is unusable.
    pub fn new(client: Client, reference: ObjectRef) -> Result<ObjectHandle, RpcError> {
        let address = parse_address(&reference)?;
        Ok(ObjectHandle {
            client,
            reference,
            address,
        })
    }

    /// What the naming service said about the object.
    pub fn reference(&self) -> &ObjectRef {
        &self.reference
    }

    /// The object's name on its node.
    pub fn name(&self) -> &str {
        &self.reference.name
    }

    /// The object's class.
    pub fn class(&self) -> Class {
        self.reference.class
    }

    /// The object's naming path, `/<node>/<class context>/<name>`.
    pub fn path(&self) -> String {
        object_path(
            &self.reference.node,
            self.reference.class,
            &self.reference.name,
        )
    }

    /// The client the handle calls through.
    pub fn client(&self) -> &Client {
        &self.client
    }

    /// Calls `method` on the object.
    ///
    /// # Errors
    /// The object's error ([`RpcError::Remote`]) or a transport error.
    pub fn call(&self, method: Method) -> Result<Reply, RpcError> {
        self.client.call_at(
            self.address,
            crate::proto::Call::Object {
                object: self.reference.name.clone(),
                method,
            },
        )
    }

    /// Calls `method`, expecting [`Reply::Unit`].
    fn unit(&self, method: Method) -> Result<(), RpcError> {
        match self.call(method)? {
            Reply::Unit => Ok(()),
            other => Err(unexpected("nothing", &other)),
        }
    }

    /// Refuses a handle of another class than `expected`.
    fn expect(self, expected: Class) -> Result<ObjectHandle, RpcError> {
        if self.reference.class == expected {
            Ok(self)
        } else {
            Err(RpcError::Remote(WireError::WrongClass {
                name: self.path(),
                expected,
                found: self.reference.class,
            }))
        }
    }
}

/// A proxy of one class, made from a handle after checking the class.
pub trait TypedProxy: Sized {
    /// The class the proxy speaks (`None`: any class).
    const CLASS: Option<Class>;

    /// The proxy of the object `handle` refers to.
    ///
    /// # Errors
    /// [`WireError::WrongClass`] when the object is of another class.
    fn from_handle(handle: ObjectHandle) -> Result<Self, RpcError>;
}

/// What every object answers: its description and the lifecycle transitions (ROS 2 words). The
/// transitions run on the node's non-real-time side and return the object's new description.
pub trait Lifecycle {
    /// The handle of the object.
    fn handle(&self) -> &ObjectHandle;

    /// The object's naming path.
    fn path(&self) -> String {
        self.handle().path()
    }

    /// What the object is now: kind, class, state, relations.
    ///
    /// # Errors
    /// The node's error or a transport error.
    fn describe(&self) -> Result<ObjectInfo, RpcError> {
        match self.handle().call(Method::Describe)? {
            Reply::Object(info) => Ok(info),
            other => Err(unexpected("an object description", &other)),
        }
    }

    /// The object's lifecycle state now.
    ///
    /// # Errors
    /// As [`Lifecycle::describe`].
    fn state(&self) -> Result<LifecycleState, RpcError> {
        Ok(self.describe()?.state)
    }

    /// Runs `transition`.
    ///
    /// # Errors
    /// [`WireError::InvalidTransition`] from a state that does not allow it,
    /// [`WireError::NotReady`] when a relation is missing, and the node's other errors.
    fn transition(&self, transition: Transition) -> Result<ObjectInfo, RpcError> {
        match self.handle().call(Method::Transition(transition))? {
            Reply::Object(info) => Ok(info),
            other => Err(unexpected("an object description", &other)),
        }
    }

    /// `unconfigured -> inactive`: checks the relations and builds the object.
    ///
    /// # Errors
    /// As [`Lifecycle::transition`].
    fn configure(&self) -> Result<ObjectInfo, RpcError> {
        self.transition(Transition::Configure)
    }

    /// `inactive -> active`: a controller starts its real-time loop from the measured state.
    ///
    /// # Errors
    /// As [`Lifecycle::transition`].
    fn activate(&self) -> Result<ObjectInfo, RpcError> {
        self.transition(Transition::Activate)
    }

    /// `active -> inactive`: a controller stops its loop safely (amplifiers off).
    ///
    /// # Errors
    /// As [`Lifecycle::transition`].
    fn deactivate(&self) -> Result<ObjectInfo, RpcError> {
        self.transition(Transition::Deactivate)
    }

    /// `inactive -> unconfigured`.
    ///
    /// # Errors
    /// As [`Lifecycle::transition`].
    fn cleanup(&self) -> Result<ObjectInfo, RpcError> {
        self.transition(Transition::Cleanup)
    }

    /// Any state but `finalized` `-> finalized`.
    ///
    /// # Errors
    /// As [`Lifecycle::transition`].
    fn shutdown(&self) -> Result<ObjectInfo, RpcError> {
        self.transition(Transition::Shutdown)
    }

    /// `error -> unconfigured`: the explicit re-arm after a fault.
    ///
    /// # Errors
    /// As [`Lifecycle::transition`].
    fn reset(&self) -> Result<ObjectInfo, RpcError> {
        self.transition(Transition::Reset)
    }
}

/// Implements [`TypedProxy`] and [`Lifecycle`] for a proxy with a `handle` field.
macro_rules! proxy_of_class {
    ($proxy:ident, $class:expr, { $($field:ident: $init:expr),* }) => {
        impl TypedProxy for $proxy {
            const CLASS: Option<Class> = $class;

            fn from_handle(handle: ObjectHandle) -> Result<Self, RpcError> {
                let handle = match Self::CLASS {
                    Some(class) => handle.expect(class)?,
                    None => handle,
                };
                Ok($proxy { handle $(, $field: $init)* })
            }
        }

        impl Lifecycle for $proxy {
            fn handle(&self) -> &ObjectHandle {
                &self.handle
            }
        }
    };
}

/// An object of any class: its lifecycle and description only.
#[derive(Clone, Debug)]
pub struct ObjectProxy {
    handle: ObjectHandle,
}
proxy_of_class!(ObjectProxy, None, {});

/// A bad argument found before sending.
fn bad(message: impl Into<String>) -> RpcError {
    RpcError::Remote(WireError::BadArgument(message.into()))
}

/// A malformed value in a reply.
fn bad_reply(what: &str, e: &WireError) -> RpcError {
    RpcError::Protocol(format!("the node answered a bad {what}: {e}"))
}

/// A joint vector from a [`Reply::Joints`].
fn joints_of(reply: Reply) -> Result<JointVector, RpcError> {
    match reply {
        Reply::Joints(q) => {
            joints_to_vector(&q, q.len()).map_err(|e| bad_reply("joint vector", &e))
        }
        other => Err(unexpected("joint values", &other)),
    }
}

/// A wrench in `frame` from a [`Reply::Wrench`].
fn wrench_of(reply: Reply, frame: Frame) -> Result<Wrench, RpcError> {
    match reply {
        Reply::Wrench(w) => w.to_wrench(frame).map_err(|e| bad_reply("wrench", &e)),
        other => Err(unexpected("a wrench", &other)),
    }
}

/// A pose on the wire, checked (finite, orthonormal) as the node will.
fn pose_msg(pose: &Pose) -> Result<PoseMsg, RpcError> {
    let msg = PoseMsg::from(pose);
    msg.to_pose().map_err(RpcError::Remote)?;
    Ok(msg)
}

/// A finite velocity on the wire.
fn velocity_msg(v: &Vector3<f64>) -> Result<[f64; 3], RpcError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok([v.x, v.y, v.z])
    } else {
        Err(bad("velocity has a NaN or infinite value"))
    }
}

/// A matrix of at most `R` × `C` from a [`Reply::Matrix`] of exactly `rows` × `cols`, the rest
/// zero (or the identity's diagonal with `identity_rest`).
fn matrix_of<const R: usize, const C: usize>(
    reply: Reply,
    rows: usize,
    cols: usize,
    identity_rest: bool,
) -> Result<SMatrix<f64, R, C>, RpcError> {
    let m: MatrixMsg = match reply {
        Reply::Matrix(m) => m,
        other => return Err(unexpected("a matrix", &other)),
    };
    let (r, c) = (usize::from(m.rows), usize::from(m.cols));
    if r != rows || c != cols || r > R || c > C || m.data.len() != r * c {
        return Err(RpcError::Protocol(format!(
            "expected a {rows}x{cols} matrix, got {r}x{c} with {} values",
            m.data.len()
        )));
    }
    if !m.data.iter().all(|x| x.is_finite()) {
        return Err(RpcError::Protocol(
            "the node answered a matrix with NaN or infinite values".into(),
        ));
    }
    let mut out = if identity_rest {
        SMatrix::<f64, R, C>::identity()
    } else {
        SMatrix::<f64, R, C>::zeros()
    };
    for i in 0..r {
        for j in 0..c {
            out[(i, j)] = m.data[i * c + j];
        }
    }
    Ok(out)
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
    /// [`WireError::NotReady`] before the robot is configured; transport errors.
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
    /// [`WireError::NotReady`] without a sensor; transport errors.
    pub fn tool_wrench(&self) -> Result<Wrench, RpcError> {
        wrench_of(self.robot(RobotMethod::ToolWrench)?, Frame::Base)
    }

    /// Forward kinematics: the tool pose in the base frame at `q` (rad; `None`: measured). The
    /// rotation's columns are the three orientation versors `n, o, a`.
    ///
    /// # Errors
    /// [`WireError::BadArgument`] for a NaN joint value; the node's errors; transport errors.
    pub fn forward_kinematics(&self, q: Option<&JointVector>) -> Result<Pose, RpcError> {
        let q = self.q_msg(q)?;
        match self.robot(RobotMethod::ForwardKinematics { q })? {
            Reply::Pose(p) => p.to_pose().map_err(|e| bad_reply("pose", &e)),
            other => Err(unexpected("a pose", &other)),
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
    /// [`WireError::BadArgument`] for a NaN or non-orthonormal pose; the node's errors.
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
    /// [`WireError::BadArgument`] for a NaN wrench or joint value; the node's errors.
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
    /// [`WireError::BadArgument`] for a wrong count; the node's errors.
    pub fn counts_to_radians(&self, counts: &[i64]) -> Result<JointVector, RpcError> {
        joints_of(self.robot(RobotMethod::CountsToRadians {
            counts: counts.to_vec(),
        })?)
    }

    /// Joint positions (rad) to the nearest encoder counts.
    ///
    /// # Errors
    /// [`WireError::BadArgument`] for a NaN value; the node's errors.
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
    /// [`WireError::BadArgument`] for a duration that is not finite and positive;
    /// [`WireError::NotReady`] when no active controller drives the robot.
    pub fn go_to(&self, pose: NamedPose, duration_s: f64) -> Result<(), RpcError> {
        if !(duration_s.is_finite() && duration_s > 0.0) {
            return Err(bad(format!(
                "duration must be finite and > 0 s, got {duration_s}"
            )));
        }
        self.handle
            .unit(Method::Robot(RobotMethod::GoTo { pose, duration_s }))
    }

    /// Maps joints onto axes of the board `board` (a name on the robot's node), as
    /// `(joint, axis)` pairs, both 0-based. A robot may use several boards.
    ///
    /// # Errors
    /// [`WireError::BadArgument`] for an index past 255 (and the node's own range checks),
    /// [`WireError::UnknownName`] for no such board.
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

/// A remote board: encoders and amplifiers.
#[derive(Clone, Debug)]
pub struct BoardProxy {
    handle: ObjectHandle,
}
proxy_of_class!(BoardProxy, Some(Class::Board), {});

impl BoardProxy {
    fn board(&self, method: BoardMethod) -> Result<Reply, RpcError> {
        self.handle.call(Method::Board(method))
    }

    /// Number of axes.
    ///
    /// # Errors
    /// The node's errors; transport errors.
    pub fn axis_count(&self) -> Result<usize, RpcError> {
        match self.board(BoardMethod::AxisCount)? {
            Reply::Count(n) => usize::try_from(n)
                .map_err(|_| RpcError::Protocol(format!("axis count {n} does not fit"))),
            other => Err(unexpected("a count", &other)),
        }
    }

    /// Encoder positions of every axis, counts.
    ///
    /// # Errors
    /// [`WireError::NotReady`] before configure; [`WireError::Device`]; transport errors.
    pub fn read_encoders(&self) -> Result<Vec<i64>, RpcError> {
        match self.board(BoardMethod::ReadEncoders)? {
            Reply::Counts(c) => Ok(c),
            other => Err(unexpected("encoder counts", &other)),
        }
    }

    /// Whether the amplifiers are enabled. *NOTE*: the board's word, not a measurement of the
    /// power stage.
    ///
    /// # Errors
    /// As [`BoardProxy::read_encoders`].
    pub fn amplifiers_enabled(&self) -> Result<bool, RpcError> {
        match self.board(BoardMethod::AmplifiersEnabled)? {
            Reply::Flag(f) => Ok(f),
            other => Err(unexpected("a flag", &other)),
        }
    }

    /// Asks the board to leave a fault it latched itself (a lost Galil line), once the cause is
    /// gone. A board driven by a running loop is re-armed through its controller instead.
    ///
    /// # Errors
    /// As [`BoardProxy::read_encoders`]; [`WireError::NotReady`] while a loop drives it.
    pub fn rearm(&self) -> Result<(), RpcError> {
        match self.board(BoardMethod::Rearm)? {
            Reply::Unit => Ok(()),
            other => Err(unexpected("nothing", &other)),
        }
    }
}

/// A remote force sensor.
#[derive(Clone, Debug)]
pub struct SensorProxy {
    handle: ObjectHandle,
}
proxy_of_class!(SensorProxy, Some(Class::Sensor), {});

impl SensorProxy {
    /// The newest reading: the wrench in the sensor frame, N and N·m.
    ///
    /// # Errors
    /// [`WireError::NotReady`] before configure; [`WireError::Device`]; transport errors.
    pub fn read(&self) -> Result<Wrench, RpcError> {
        wrench_of(
            self.handle.call(Method::Sensor(SensorMethod::Read))?,
            Frame::Sensor,
        )
    }

    /// Takes the current reading as the zero.
    ///
    /// # Errors
    /// As [`SensorProxy::read`].
    pub fn bias(&self) -> Result<(), RpcError> {
        self.handle.unit(Method::Sensor(SensorMethod::Bias))
    }

    /// Tells the sensor where its probe is: for `sensor/virtual`, the tool pose (base frame) and
    /// linear velocity (m/s) the environment model pushes against.
    ///
    /// # Errors
    /// [`WireError::BadArgument`] for a NaN or non-orthonormal pose or a NaN velocity.
    pub fn set_probe(&self, pose: &Pose, velocity: &Vector3<f64>) -> Result<(), RpcError> {
        let (pose, velocity) = (pose_msg(pose)?, velocity_msg(velocity)?);
        self.handle
            .unit(Method::Sensor(SensorMethod::SetProbe { pose, velocity }))
    }

    /// The wrench for a probe at `pose` moving at `velocity` (m/s), in one round trip: the data
    /// path of a remote sensor. The wrench is in the sensor frame, as [`SensorProxy::read`].
    ///
    /// # Errors
    /// As [`SensorProxy::set_probe`].
    pub fn measure(&self, pose: &Pose, velocity: &Vector3<f64>) -> Result<Wrench, RpcError> {
        let (pose, velocity) = (pose_msg(pose)?, velocity_msg(velocity)?);
        wrench_of(
            self.handle
                .call(Method::Sensor(SensorMethod::Measure { pose, velocity }))?,
            Frame::Sensor,
        )
    }
}

/// A remote controller (the paper's `ControllerImpl`).
#[derive(Clone, Debug)]
pub struct ControllerProxy {
    handle: ObjectHandle,
}
proxy_of_class!(ControllerProxy, Some(Class::Controller), {});

impl ControllerProxy {
    fn controller(&self, method: ControllerMethod) -> Result<(), RpcError> {
        self.handle.unit(Method::Controller(method))
    }

    /// Binds the robot it drives (a name on the controller's node).
    ///
    /// # Errors
    /// [`WireError::UnknownName`], [`WireError::WrongClass`], [`WireError::InvalidTransition`]
    /// while active; transport errors.
    pub fn set_robot(&self, robot: &str) -> Result<(), RpcError> {
        self.controller(ControllerMethod::SetRobot {
            robot: robot.to_string(),
        })
    }

    /// Binds the trajectory it follows (a name on the controller's node).
    ///
    /// # Errors
    /// As [`ControllerProxy::set_robot`].
    pub fn set_trajectory(&self, trajectory: &str) -> Result<(), RpcError> {
        self.controller(ControllerMethod::SetTrajectory {
            trajectory: trajectory.to_string(),
        })
    }

    /// Binds the force sensor: a name on the controller's node, or the naming path of a sensor
    /// on another node (`/lab-b/sensors/wall`), read by the controller's communication thread.
    ///
    /// # Errors
    /// As [`ControllerProxy::set_robot`].
    pub fn set_sensor(&self, sensor: &str) -> Result<(), RpcError> {
        self.controller(ControllerMethod::SetSensor {
            sensor: sensor.to_string(),
        })
    }

    /// Replaces gains at run time: TOML text with the kind's keys, such as
    /// `kp = [100, 100, 100, 10, 10, 10]`.
    ///
    /// # Errors
    /// [`WireError::BadConfig`] for unknown keys or bad values; transport errors.
    pub fn set_gains(&self, gains: &str) -> Result<(), RpcError> {
        self.controller(ControllerMethod::SetGains {
            gains: gains.to_string(),
        })
    }

    /// Latches the emergency stop of the running loop.
    ///
    /// # Errors
    /// [`WireError::NotReady`] when no loop runs; transport errors.
    pub fn estop(&self) -> Result<(), RpcError> {
        self.controller(ControllerMethod::EStop)
    }

    /// Re-arms the controller: a running loop clears its latched fault or e-stop (and its
    /// boards' own latches) and activates again from the measured state; a loop whose threads
    /// failed (`error`) is started anew, from the measured state.
    ///
    /// # Errors
    /// As [`ControllerProxy::estop`].
    pub fn rearm(&self) -> Result<(), RpcError> {
        self.controller(ControllerMethod::Rearm)
    }

    /// The running loop's newest sample and its counters.
    ///
    /// # Errors
    /// The node's errors; transport errors.
    pub fn status(&self) -> Result<ControlStatus, RpcError> {
        match self
            .handle
            .call(Method::Controller(ControllerMethod::Status))?
        {
            Reply::Status(s) => Ok(s),
            other => Err(unexpected("a controller status", &other)),
        }
    }
}

/// A remote trajectory.
#[derive(Clone, Debug)]
pub struct TrajectoryProxy {
    handle: ObjectHandle,
}
proxy_of_class!(TrajectoryProxy, Some(Class::Trajectory), {});

impl TrajectoryProxy {
    /// The reference at `t_s` seconds after the start (the paper's `getReferiment`). A joint
    /// reference carries positions and velocities (accelerations zero); a Cartesian one the pose
    /// (twist zero); a wrench one is in the base frame.
    ///
    /// # Errors
    /// [`WireError::BadArgument`] for a NaN time; [`WireError::NotReady`] before configure.
    pub fn reference(&self, t_s: f64) -> Result<Reference, RpcError> {
        if !t_s.is_finite() {
            return Err(bad(format!("time must be finite, got {t_s}")));
        }
        let reply = self
            .handle
            .call(Method::Trajectory(TrajectoryMethod::Reference { t_s }))?;
        match reply {
            Reply::Reference(r) => reference_of(&r),
            other => Err(unexpected("a reference", &other)),
        }
    }

    /// The total duration, s (`None` for an endless trajectory).
    ///
    /// # Errors
    /// The node's errors; transport errors.
    pub fn duration(&self) -> Result<Option<f64>, RpcError> {
        match self
            .handle
            .call(Method::Trajectory(TrajectoryMethod::Duration))?
        {
            Reply::Duration(d) => Ok(d),
            other => Err(unexpected("a duration", &other)),
        }
    }
}

/// The `hal` reference of a wire reference.
pub fn reference_of(r: &ReferenceMsg) -> Result<Reference, RpcError> {
    Ok(match r {
        ReferenceMsg::Joint { q, qd } => {
            let position = joints_to_vector(q, q.len()).map_err(|e| bad_reply("reference", &e))?;
            let velocity =
                joints_to_vector(qd, qd.len()).map_err(|e| bad_reply("reference", &e))?;
            Reference::Joint(JointReference {
                position,
                velocity,
                acceleration: JointVector::zeros(),
            })
        }
        ReferenceMsg::Cartesian { pose } => Reference::Cartesian(CartesianReference {
            pose: pose.to_pose().map_err(|e| bad_reply("reference", &e))?,
            twist: Twist::default(),
        }),
        ReferenceMsg::Wrench { wrench } => Reference::Wrench(
            wrench
                .to_wrench(Frame::Base)
                .map_err(|e| bad_reply("reference", &e))?,
        ),
    })
}
