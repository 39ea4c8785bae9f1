#![doc = include_str!("../README.md")]
//!
//! # A tour
//!
//! - [`time`]: [`Timestamp`], the monotonic instant every real-time call takes as a parameter
//!   (time is passed in, never read inside logic).
//! - [`joint`]: joint-space vectors, state and limits (radians, rad/s, N·m).
//! - [`spatial`]: poses, twists and wrenches, each tagged with the [`Frame`] it is expressed in.
//! - [`reference`](mod@reference): what a trajectory hands a controller: joint, Cartesian, wrench or hybrid.
//! - [`lifecycle`]: the ROS 2 lifecycle (`unconfigured -> inactive -> active -> finalized`, + `error`).
//! - [`error`]: the embedded-hal style [`ErrorKind`] every device error maps onto.
//! - The five object traits: [`board`], [`robot`] (with [`robot::Kinematics`] and
//!   [`robot::Dynamics`]), [`sensor`], [`controller`], [`trajectory`].
#![no_std]
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod board;
pub mod controller;
pub mod error;
pub mod joint;
pub mod lifecycle;
pub mod reference;
pub mod robot;
pub mod sensor;
pub mod spatial;
pub mod time;
pub mod trajectory;

pub use board::{AxisCommand, AxisState, Board, MAX_AXES};
pub use controller::{ControlInput, Controller, ControllerError, JointCommand};
pub use error::{Error, ErrorKind};
pub use joint::{JointLimits, JointSet, JointState, JointVector, MAX_JOINTS};
pub use lifecycle::{LifecycleError, LifecycleState, Transition};
pub use reference::{CartesianReference, HybridReference, JointReference, Reference};
pub use robot::{
    Dynamics, IkSolution, IkSolutions, InverseKinematics, JacobianFrame, Kinematics,
    KinematicsError, NamedPose, Robot, RobotModel,
};
pub use sensor::{ForceSensor, Sensor};
pub use spatial::{Frame, Jacobian, JointSpaceMatrix, OperationalState, Pose, Twist, Wrench};
pub use time::Timestamp;
pub use trajectory::{Trajectory, TrajectoryError};

/// Re-export of the linear-algebra crate the shared types are built on, so users name the same
/// version.
pub use nalgebra;
