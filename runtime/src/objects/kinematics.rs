//! The model a robot's loops compute with, chosen by the boards its joints are on: the float
//! model, or, for the FRHC on a `board/fpga`, the board's bit-exact FPGA kinematics and force
//! transformation with the float dynamics. Plants behind simulated boards are physics and always
//! use the float model.

use penelope_drivers::model::SerialRobotModel;
use penelope_fpga::FpgaKinematics;
use penelope_hal::robot::check_finite;
use penelope_hal::{
    Dynamics, IkSolutions, InverseKinematics, Jacobian, JacobianFrame, JointLimits,
    JointSpaceMatrix, JointVector, Kinematics, KinematicsError, Pose, RobotModel, Wrench,
};

/// A robot model with the kinematics its boards give it.
#[derive(Clone, Debug)]
pub enum RobotKinematics {
    /// Float kinematics and dynamics.
    Float(SerialRobotModel),
    /// The FRHC on a `board/fpga`: forward kinematics, Jacobian and `tau = J^T F` from the
    /// bit-exact model of the board's pipelines; inverse kinematics and dynamics from the float
    /// model.
    FpgaBoard {
        /// The board's kinematics.
        fpga: Box<FpgaKinematics>,
        /// The float model, for everything the board does not compute.
        float: SerialRobotModel,
    },
}

impl RobotKinematics {
    /// The board's kinematics for `float`, which must be the FRHC's model (what the board
    /// computes); `None` for any other model.
    pub fn on_fpga_board(float: SerialRobotModel) -> Option<Self> {
        (float.name() == "frhc").then(|| RobotKinematics::FpgaBoard {
            fpga: Box::new(FpgaKinematics::frhc()),
            float,
        })
    }

    /// The underlying float model (dynamics, named poses, encoder scaling).
    pub fn float(&self) -> &SerialRobotModel {
        match self {
            RobotKinematics::Float(m) => m,
            RobotKinematics::FpgaBoard { float, .. } => float,
        }
    }

    /// Whether the kinematics are an fpga board's.
    pub fn is_fpga_board(&self) -> bool {
        matches!(self, RobotKinematics::FpgaBoard { .. })
    }

    /// In words, for `describe` and reports.
    pub fn describe(&self) -> &'static str {
        match self {
            RobotKinematics::Float(_) => "float (f64 on the host)",
            RobotKinematics::FpgaBoard { .. } => {
                "fpga board (bit-exact FK and tau = J^T F on the board; IK and dynamics float)"
            }
        }
    }
}

impl Kinematics for RobotKinematics {
    fn joint_count(&self) -> usize {
        self.float().joint_count()
    }
    fn forward(&self, q: &JointVector) -> Pose {
        match self {
            RobotKinematics::Float(m) => m.forward(q),
            RobotKinematics::FpgaBoard { fpga, .. } => fpga.forward(q),
        }
    }
    fn jacobian(&self, q: &JointVector, frame: JacobianFrame) -> Jacobian {
        match self {
            RobotKinematics::Float(m) => m.jacobian(q, frame),
            RobotKinematics::FpgaBoard { fpga, .. } => fpga.jacobian(q, frame),
        }
    }
}

impl InverseKinematics for RobotKinematics {
    fn inverse_all(&self, target: &Pose, out: &mut IkSolutions) -> Result<usize, KinematicsError> {
        self.float().inverse_all(target, out)
    }
    fn inverse_near(
        &self,
        target: &Pose,
        seed: &JointVector,
    ) -> Result<JointVector, KinematicsError> {
        self.float().inverse_near(target, seed)
    }
}

impl Dynamics for RobotKinematics {
    fn gravity(&self, q: &JointVector) -> JointVector {
        self.float().gravity(q)
    }
    fn inertia(&self, q: &JointVector) -> JointSpaceMatrix {
        self.float().inertia(q)
    }
    fn inverse_dynamics(
        &self,
        q: &JointVector,
        qd: &JointVector,
        qdd: &JointVector,
    ) -> JointVector {
        self.float().inverse_dynamics(q, qd, qdd)
    }
    fn friction(&self, qd: &JointVector) -> JointVector {
        self.float().friction(qd)
    }
}

impl RobotModel for RobotKinematics {
    fn limits(&self) -> &JointLimits {
        self.float().limits()
    }

    /// On an fpga board: the board's force pipeline (a tool-side wrench is rotated to the base
    /// on the board). Else `J^T F` in f64.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    fn wrench_to_torques(
        &self,
        q: &JointVector,
        wrench: &Wrench,
    ) -> Result<JointVector, KinematicsError> {
        match self {
            RobotKinematics::Float(m) => m.wrench_to_torques(q, wrench),
            RobotKinematics::FpgaBoard { fpga, .. } => {
                check_finite(q)?;
                fpga.joint_torques(q, wrench)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use penelope_drivers::model;
    use penelope_hal::Frame;

    #[test]
    fn on_the_fpga_board_every_result_is_the_bit_exact_models() {
        let kin = RobotKinematics::on_fpga_board(model::frhc()).expect("the FRHC");
        let float = RobotKinematics::Float(model::frhc());
        let fpga = FpgaKinematics::frhc();
        let q = JointVector::from([0.3, 1.1, 2.2, -0.4, 0.7, 1.2]);
        let w = Wrench {
            force: Vector3::new(3.0, -2.0, 5.0),
            torque: Vector3::new(0.1, 0.2, -0.3),
            frame: Frame::Base,
        };
        assert_eq!(kin.forward(&q), fpga.forward(&q));
        assert_eq!(
            kin.jacobian(&q, JacobianFrame::Base),
            fpga.jacobian(&q, JacobianFrame::Base)
        );
        let tau = kin.wrench_to_torques(&q, &w).unwrap();
        assert_eq!(tau, fpga.joint_torques(&q, &w).unwrap());
        // Not the float J^T F: the board's words, within their quantization of it.
        let tau_float = float.wrench_to_torques(&q, &w).unwrap();
        assert_ne!(tau, tau_float);
        assert!((tau - tau_float).norm() < 1e-4, "{tau} vs {tau_float}");
        // Dynamics stay the float model's.
        assert_eq!(kin.gravity(&q), float.gravity(&q));
        let mut bad = q;
        bad[1] = f64::NAN;
        assert_eq!(
            kin.wrench_to_torques(&bad, &w),
            Err(KinematicsError::NonFinite)
        );
        assert!(RobotKinematics::on_fpga_board(model::puma560()).is_none());
    }
}
