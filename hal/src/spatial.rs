//! Operational space: poses, twists, wrenches and the frames they are expressed in.

use nalgebra::{Isometry3, SMatrix, Vector3, Vector6};

use crate::joint::MAX_JOINTS;

/// A rigid transform: translation in metres, rotation as a unit quaternion. As a 4x4 homogeneous
/// matrix (`to_homogeneous()`), its rotation columns are the three orientation versors of the
/// paper's forward kinematics.
pub type Pose = Isometry3<f64>;

/// A geometric Jacobian: 6 rows `[v; omega]` (m/s and rad/s per rad/s of each joint), one column per
/// joint. Columns past the robot's joint count are zero.
pub type Jacobian = SMatrix<f64, 6, MAX_JOINTS>;

/// A joint-space matrix such as the inertia matrix (kg·m²).
pub type JointSpaceMatrix = SMatrix<f64, MAX_JOINTS, MAX_JOINTS>;

/// The frame a spatial quantity is expressed in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Frame {
    /// The robot's base frame.
    #[default]
    Base,
    /// The last link's frame (the mechanical flange).
    Flange,
    /// The tool frame (the flange composed with the tool transform).
    Tool,
    /// A sensor's own measuring frame.
    Sensor,
    /// The master device's base frame, as seen by the slave side after workspace mapping.
    Master,
}

/// A spatial velocity: linear (m/s) and angular (rad/s), in `frame`.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Twist {
    /// Linear velocity, m/s.
    pub linear: Vector3<f64>,
    /// Angular velocity, rad/s.
    pub angular: Vector3<f64>,
    /// The frame both vectors are expressed in.
    pub frame: Frame,
}

impl Twist {
    /// The twist as `[v; omega]`.
    pub fn to_vector(&self) -> Vector6<f64> {
        Vector6::new(
            self.linear.x,
            self.linear.y,
            self.linear.z,
            self.angular.x,
            self.angular.y,
            self.angular.z,
        )
    }
}

/// A force and a moment: N and N·m, in `frame`, about that frame's origin.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Wrench {
    /// Force, N.
    pub force: Vector3<f64>,
    /// Moment about the frame's origin, N·m.
    pub torque: Vector3<f64>,
    /// The frame both vectors are expressed in.
    pub frame: Frame,
}

impl Wrench {
    /// A zero wrench in `frame`.
    pub fn zero(frame: Frame) -> Self {
        Wrench {
            force: Vector3::zeros(),
            torque: Vector3::zeros(),
            frame,
        }
    }

    /// The wrench as `[f; m]`, the order `tau = J^T F` expects.
    pub fn to_vector(&self) -> Vector6<f64> {
        Vector6::new(
            self.force.x,
            self.force.y,
            self.force.z,
            self.torque.x,
            self.torque.y,
            self.torque.z,
        )
    }

    /// True when all six components are finite.
    pub fn is_finite(&self) -> bool {
        self.force
            .iter()
            .chain(self.torque.iter())
            .all(|x| x.is_finite())
    }

    /// This wrench re-expressed in a frame whose pose relative to the current one is `pose`
    /// (`pose` maps coordinates of the new frame into the current one). Rotates both vectors and
    /// moves the moment to the new origin: `m' = R^T (m - p x f)`, `f' = R^T f`.
    pub fn expressed_in(&self, pose: &Pose, frame: Frame) -> Wrench {
        let r_t = pose.rotation.inverse();
        let p = pose.translation.vector;
        Wrench {
            force: r_t * self.force,
            torque: r_t * (self.torque - p.cross(&self.force)),
            frame,
        }
    }
}

/// A robot's operational-space (Cartesian) state at its tool frame.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct OperationalState {
    /// Tool pose in the base frame.
    pub pose: Pose,
    /// Tool twist in the base frame.
    pub twist: Twist,
    /// Tool wrench (measured or commanded) in the base frame.
    pub wrench: Wrench,
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn wrench_round_trip_through_a_frame_change() {
        let pose = Pose::from_parts(
            Translation3::new(0.1, -0.2, 0.3),
            UnitQuaternion::from_euler_angles(0.3, -0.5, 1.1),
        );
        let w = Wrench {
            force: Vector3::new(1.0, 2.0, -3.0),
            torque: Vector3::new(0.5, -0.1, 0.2),
            frame: Frame::Base,
        };
        let there = w.expressed_in(&pose, Frame::Tool);
        let back = there.expressed_in(&pose.inverse(), Frame::Base);
        assert!((back.to_vector() - w.to_vector()).norm() < 1e-12);
        // The force magnitude is frame-independent; the moment changes with the origin.
        assert!((there.force.norm() - w.force.norm()).abs() < 1e-12);
    }
}
