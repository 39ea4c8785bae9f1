//! Robots: kinematic chains driven through boards (manipulators and joysticks alike).
//!
//! The interface follows the paper's `Puma200` class, split so that each part can be implemented
//! and swapped on its own:
//!
//! - [`Kinematics`]: forward kinematics and the geometric Jacobian. This is *the* kinematics trait:
//!   the float models in `penelope-drivers` and the bit-exact FPGA model in `penelope-fpga`
//!   both implement it, and configuration chooses between them.
//! - [`InverseKinematics`]: every branch of the closed form where one exists, or a numerical
//!   solution near a seed.
//! - [`Dynamics`]: gravity, inertia and inverse dynamics.
//! - [`Robot`]: a model plus its measured state, limits, encoder scaling and named poses.
//!
//! # Real-time
//! Every method here is meant for the control thread: implementations must not allocate, lock or
//! block, and must run in bounded time (iterative solvers cap their iterations).

use core::fmt;

use heapless::Vec as FixedVec;

use crate::error::{Error, ErrorKind};
use crate::joint::{JointLimits, JointState, JointVector, MAX_JOINTS};
use crate::spatial::{Frame, Jacobian, JointSpaceMatrix, OperationalState, Pose, Twist, Wrench};

/// The largest number of inverse-kinematics branches any model returns (8 for a PUMA-type arm).
pub const MAX_IK_SOLUTIONS: usize = 8;

/// Which frame a Jacobian's rows are expressed in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum JacobianFrame {
    /// Rows are the tool's linear and angular velocity in the base frame.
    #[default]
    Base,
    /// Rows are the tool's linear and angular velocity in the tool frame.
    Tool,
}

/// Why a kinematic or dynamic computation could not give an answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum KinematicsError {
    /// An input held NaN or infinity.
    NonFinite,
    /// The pose is outside the reachable workspace.
    Unreachable,
    /// The configuration is singular and no branch could be resolved.
    Singular,
    /// The numerical solver ran out of iterations before reaching tolerance.
    NoConvergence,
    /// No solution respects the joint limits.
    OutOfLimits,
}

impl fmt::Display for KinematicsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            KinematicsError::NonFinite => "input is NaN or infinite",
            KinematicsError::Unreachable => "pose is outside the workspace",
            KinematicsError::Singular => "configuration is singular",
            KinematicsError::NoConvergence => "inverse kinematics did not converge",
            KinematicsError::OutOfLimits => "no solution within joint limits",
        })
    }
}

impl Error for KinematicsError {
    fn kind(&self) -> ErrorKind {
        match self {
            KinematicsError::NonFinite => ErrorKind::NonFinite,
            KinematicsError::Unreachable | KinematicsError::NoConvergence => ErrorKind::Unreachable,
            KinematicsError::Singular => ErrorKind::Singular,
            KinematicsError::OutOfLimits => ErrorKind::OutOfLimits,
        }
    }
}

/// Forward kinematics and the geometric Jacobian of a serial chain.
///
/// Joint vectors hold radians (prismatic joints: metres); entries past
/// [`joint_count`](Kinematics::joint_count) are ignored.
pub trait Kinematics {
    /// Number of joints actually used (at most [`MAX_JOINTS`]).
    fn joint_count(&self) -> usize;

    /// The tool pose in the base frame at joint positions `q` (rad). Positions in metres; the
    /// rotation's columns are the tool's x, y, z versors in the base frame.
    ///
    /// NaN in `q` gives NaN out; validate inputs at the edge (see [`check_finite`]).
    fn forward(&self, q: &JointVector) -> Pose;

    /// The geometric Jacobian at `q`, rows `[v; omega]`, for the tool frame's origin, expressed in
    /// `frame`. Columns past `joint_count()` are zero.
    fn jacobian(&self, q: &JointVector, frame: JacobianFrame) -> Jacobian;
}

/// One inverse-kinematics branch.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct IkSolution {
    /// The branch's name, for example `"left-up-noflip"`; `"numerical"` for iterative solutions.
    pub branch: &'static str,
    /// Joint positions, rad; each chosen as the 2π-equivalent inside the joint limits when one
    /// exists.
    pub q: JointVector,
    /// True when every joint of `q` is within its limits.
    pub within_limits: bool,
}

/// All the branches of one inverse-kinematics query, on the stack.
pub type IkSolutions = FixedVec<IkSolution, MAX_IK_SOLUTIONS>;

/// Inverse kinematics.
pub trait InverseKinematics: Kinematics {
    /// Every branch reaching `target` (tool pose in the base frame), written into `out` (cleared
    /// first). Returns how many were found.
    ///
    /// # Errors
    /// [`KinematicsError::NonFinite`] for a NaN target, [`KinematicsError::Unreachable`] when no
    /// branch exists.
    fn inverse_all(&self, target: &Pose, out: &mut IkSolutions) -> Result<usize, KinematicsError>;

    /// The solution reaching `target` closest to `seed` (branch continuity for tracking), within
    /// the joint limits.
    ///
    /// # Errors
    /// As [`inverse_all`](InverseKinematics::inverse_all), plus [`KinematicsError::OutOfLimits`]
    /// when every branch violates a limit and [`KinematicsError::NoConvergence`] for an
    /// iterative solver that ran out of iterations.
    fn inverse_near(
        &self,
        target: &Pose,
        seed: &JointVector,
    ) -> Result<JointVector, KinematicsError>;
}

/// Rigid-body dynamics of the chain.
///
/// Conventions (those of the Robotics Toolbox, so results compare directly):
/// [`gravity`](Dynamics::gravity) is the torque that *holds* the arm still (the negative of the
/// torque gravity exerts); [`inertia`](Dynamics::inertia) includes the reflected motor inertia
/// `Jm G²` on its diagonal.
pub trait Dynamics: Kinematics {
    /// Joint torques (N·m) that hold the arm at `q` against gravity.
    fn gravity(&self, q: &JointVector) -> JointVector;

    /// The joint-space inertia matrix at `q`, kg·m², symmetric positive definite on the used
    /// joints; unused rows and columns hold the identity so the matrix stays invertible.
    fn inertia(&self, q: &JointVector) -> JointSpaceMatrix;

    /// Joint torques (N·m) that produce acceleration `qdd` at `q`, `qd`: recursive Newton-Euler,
    /// gravity and reflected motor inertia included, friction excluded.
    fn inverse_dynamics(&self, q: &JointVector, qd: &JointVector, qdd: &JointVector)
    -> JointVector;

    /// Joint friction torques (N·m) at speed `qd`, opposing motion (viscous + Coulomb, at the
    /// joint side). Zero for a model without friction data.
    fn friction(&self, qd: &JointVector) -> JointVector {
        let _ = qd;
        JointVector::zeros()
    }
}

/// A complete robot model: kinematics both ways and dynamics. Object-safe, so a controller can
/// take `&dyn RobotModel`.
pub trait RobotModel: InverseKinematics + Dynamics {
    /// The joint envelope.
    fn limits(&self) -> &JointLimits;

    /// Joint torques (N·m) that balance `wrench` applied at the tool: `tau = J^T F`. The wrench
    /// must be expressed in [`Frame::Base`] (about the tool origin) or [`Frame::Tool`]; other
    /// frames must be converted by the caller.
    ///
    /// # Errors
    /// [`KinematicsError::NonFinite`] for a NaN wrench or configuration.
    fn wrench_to_torques(
        &self,
        q: &JointVector,
        wrench: &Wrench,
    ) -> Result<JointVector, KinematicsError> {
        check_finite(q)?;
        if !wrench.is_finite() {
            return Err(KinematicsError::NonFinite);
        }
        let frame = match wrench.frame {
            Frame::Tool | Frame::Flange | Frame::Sensor => JacobianFrame::Tool,
            Frame::Base | Frame::Master => JacobianFrame::Base,
        };
        Ok(self.jacobian(q, frame).transpose() * wrench.to_vector())
    }

    /// The damped least-squares inverse of the base-frame Jacobian,
    /// `J^T (J J^T + lambda² I)^-1`: joint velocity per unit tool twist, bounded near singularities.
    fn jacobian_damped_inverse(
        &self,
        q: &JointVector,
        lambda: f64,
    ) -> nalgebra::SMatrix<f64, MAX_JOINTS, 6> {
        let j = self.jacobian(q, JacobianFrame::Base);
        let jjt = j * j.transpose() + nalgebra::Matrix6::identity() * (lambda * lambda);
        // J J^T + lambda² I is symmetric positive definite for lambda > 0; fall back to zero motion
        // if a caller passes lambda = 0 at a singularity.
        match jjt.cholesky() {
            Some(ch) => j.transpose() * ch.inverse(),
            None => nalgebra::SMatrix::<f64, MAX_JOINTS, 6>::zeros(),
        }
    }

    /// The tool's operational-space state from a joint state: pose and twist (`J qd`) in the base
    /// frame, and the wrench the joint efforts would exert (left zero here; robots with a wrist
    /// sensor fill it in).
    fn operational_state(&self, joints: &JointState) -> OperationalState {
        let pose = self.forward(&joints.position);
        let v = self.jacobian(&joints.position, JacobianFrame::Base) * joints.velocity;
        OperationalState {
            pose,
            twist: Twist {
                linear: v.fixed_rows::<3>(0).into(),
                angular: v.fixed_rows::<3>(3).into(),
                frame: Frame::Base,
            },
            wrench: Wrench::zero(Frame::Base),
        }
    }
}

/// The paper's named poses (goNested, goStart, goWork).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum NamedPose {
    /// Folded for transport and power-off.
    Nest,
    /// Where every session starts.
    Start,
    /// Ready for the task.
    Work,
}

impl NamedPose {
    /// Every named pose.
    pub const ALL: [NamedPose; 3] = [NamedPose::Nest, NamedPose::Start, NamedPose::Work];

    /// The lower-case name users type.
    pub const fn as_str(self) -> &'static str {
        match self {
            NamedPose::Nest => "nest",
            NamedPose::Start => "start",
            NamedPose::Work => "work",
        }
    }

    /// Parses `nest`, `start` or `work`.
    pub fn parse(name: &str) -> Option<NamedPose> {
        NamedPose::ALL.into_iter().find(|p| p.as_str() == name)
    }
}

/// A robot: a [`RobotModel`] together with its measured state, encoder scaling and named poses.
/// Its joints are driven through one or more boards; the mapping lives in configuration, and the
/// control loop converts encoder counts with [`counts_to_radians`](Robot::counts_to_radians).
pub trait Robot: RobotModel {
    /// The robot's kind, for example `"puma560"`.
    fn kind(&self) -> &'static str;

    /// The latest measured joint state.
    fn joint_state(&self) -> &JointState;

    /// Stores a newly measured joint state (called by the control loop after reading the boards).
    fn set_joint_state(&mut self, state: JointState);

    /// Encoder counts per radian of joint motion for joint `joint` (gear ratio included; the sign
    /// gives the counting direction).
    fn counts_per_radian(&self, joint: usize) -> f64;

    /// Joint position (rad) for an encoder reading on `joint`.
    fn counts_to_radians(&self, joint: usize, counts: i64) -> f64 {
        counts as f64 / self.counts_per_radian(joint)
    }

    /// The nearest encoder reading (counts) to joint position `radians` on `joint`.
    fn radians_to_counts(&self, joint: usize, radians: f64) -> i64 {
        let counts = radians * self.counts_per_radian(joint);
        // `as` saturates at the i64 range and maps NaN to 0; callers check finiteness first.
        libm_round(counts) as i64
    }

    /// The joint positions of a named pose.
    fn named_pose(&self, pose: NamedPose) -> JointVector;
}

/// Rounds half away from zero without `std`.
fn libm_round(x: f64) -> f64 {
    let t = x as i64 as f64; // truncation toward zero; saturating
    if (x - t).abs() >= 0.5 {
        t + x.signum()
    } else {
        t
    }
}

/// Checks that every joint value is finite.
///
/// # Errors
/// [`KinematicsError::NonFinite`] otherwise.
pub fn check_finite(q: &JointVector) -> Result<(), KinematicsError> {
    if crate::joint::all_finite(q) {
        Ok(())
    } else {
        Err(KinematicsError::NonFinite)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_is_half_away_from_zero() {
        assert_eq!(libm_round(2.5), 3.0);
        assert_eq!(libm_round(-2.5), -3.0);
        assert_eq!(libm_round(2.49), 2.0);
        assert_eq!(libm_round(-0.2), 0.0);
    }

    #[test]
    fn named_poses_parse_back() {
        for p in NamedPose::ALL {
            assert_eq!(NamedPose::parse(p.as_str()), Some(p));
        }
        assert_eq!(NamedPose::parse("home"), None);
    }
}
