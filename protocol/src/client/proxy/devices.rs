//! The proxies of remote devices: a board's encoders and amplifiers ([`BoardProxy`]) and a force
//! sensor ([`SensorProxy`]).

#[cfg(doc)]
use crate::proto::CallError;
use nalgebra::Vector3;
use penelope_hal::{Frame, Pose, Wrench};

use super::{Lifecycle, ObjectHandle, TypedProxy, pose_msg, velocity_msg, wrench_of};
use crate::client::unexpected;
use crate::net::conn::RpcError;
#[cfg(doc)]
use crate::proto::WireError;
use crate::proto::{BoardMethod, Class, Method, Reply, SensorMethod};

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
    /// [`CallError::NotReady`] before configure; [`CallError::Device`]; transport errors.
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
    /// As [`BoardProxy::read_encoders`]; [`CallError::NotReady`] while a loop drives it.
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
    /// [`CallError::NotReady`] before configure; [`CallError::Device`]; transport errors.
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
    /// [`CallError::BadArgument`] for a NaN or non-orthonormal pose or a NaN velocity.
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
