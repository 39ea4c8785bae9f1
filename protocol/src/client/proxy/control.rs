//! The proxies of the control side: a controller ([`ControllerProxy`]) and a trajectory
//! ([`TrajectoryProxy`]), with [`reference_of`] to read a trajectory's references.

#[cfg(doc)]
use crate::proto::CallError;
use penelope_hal::{CartesianReference, Frame, JointReference, JointVector, Reference, Twist};

use super::{Lifecycle, ObjectHandle, TypedProxy, bad, bad_reply};
use crate::client::unexpected;
use crate::net::conn::RpcError;
#[cfg(doc)]
use crate::proto::WireError;
use crate::proto::{
    Class, ControlStatus, ControllerMethod, Method, ReferenceMsg, Reply, TrajectoryMethod,
    joints_to_vector,
};

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
    /// [`CallError::UnknownName`], [`CallError::WrongClass`], [`CallError::InvalidTransition`]
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
    /// on another node (`/lab-b/sensors/wall`), which its node publishes on the data plane (its
    /// `publish` key) and the controller's sensor feed reads there.
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
    /// [`CallError::BadConfig`] for unknown keys or bad values; transport errors.
    pub fn set_gains(&self, gains: &str) -> Result<(), RpcError> {
        self.controller(ControllerMethod::SetGains {
            gains: gains.to_string(),
        })
    }

    /// Latches the emergency stop of the running loop, on a connection of its own (never
    /// behind another call of this client).
    ///
    /// # Errors
    /// [`CallError::NotReady`] when no loop runs; transport errors.
    pub fn estop(&self) -> Result<(), RpcError> {
        self.handle
            .unit_alone(Method::Controller(ControllerMethod::EStop))
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
    /// [`CallError::BadArgument`] for a NaN time; [`CallError::NotReady`] before configure.
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
