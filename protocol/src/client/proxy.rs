//! Typed proxies of remote objects: the methods of the local objects (DESIGN.md section 1, the
//! paper's `Puma200` class), with the math types of `hal` at the edges, so that code using a
//! remote robot reads like code using a local one.
//!
//! Every proxy holds the object's reference (node address and name), resolved once; its class
//! was checked when the proxy was made. Arguments are checked before they are sent (a NaN joint
//! value, a non-orthonormal pose or a non-positive duration is refused with
//! [`CallError::BadArgument`] without a round trip). The joint count of a robot is learnt from
//! the node on first use and kept.

use nalgebra::{SMatrix, Vector3};
use penelope_hal::{Frame, JointVector, LifecycleState, Pose, Transition, Wrench};

use super::{Client, parse_address, unexpected};
use crate::net::conn::RpcError;
use crate::proto::{
    CallError, Class, MatrixMsg, Method, ObjectInfo, ObjectRef, PoseMsg, Reply, WireError,
    joints_to_vector, object_path,
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

    /// Calls `method` on a connection of its own ([`Client::call_alone`]), expecting
    /// [`Reply::Unit`]: for stops, which must not wait behind this client's other calls.
    pub(crate) fn unit_alone(&self, method: Method) -> Result<(), RpcError> {
        let call = crate::proto::Call::Object {
            object: self.reference.name.clone(),
            method,
        };
        match self.client.call_alone(self.address, call)? {
            Reply::Unit => Ok(()),
            other => Err(unexpected("nothing", &other)),
        }
    }

    /// Refuses a handle of another class than `expected`.
    fn expect(self, expected: Class) -> Result<ObjectHandle, RpcError> {
        if self.reference.class == expected {
            Ok(self)
        } else {
            Err(RpcError::Remote(WireError::Call(CallError::WrongClass {
                name: self.path(),
                expected,
                found: self.reference.class,
            })))
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
    /// [`CallError::WrongClass`] when the object is of another class.
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
    /// [`CallError::InvalidTransition`] from a state that does not allow it,
    /// [`CallError::NotReady`] when a relation is missing, and the node's other errors.
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
    RpcError::Remote(WireError::Call(CallError::BadArgument(message.into())))
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

// The proxies of each class, after `proxy_of_class!` (a `macro_rules!` macro is in scope only
// below its definition).
mod control;
mod devices;
mod robot;

pub use control::{ControllerProxy, TrajectoryProxy, reference_of};
pub use devices::{BoardProxy, SensorProxy};
pub use robot::{RobotDescription, RobotProxy, Setpoints};
