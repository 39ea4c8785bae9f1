//! The robot model a lab robot runs on: the float model, or (for the FRHC) the bit-exact FPGA
//! kinematics with the float dynamics.

use penelope_drivers::model::DhRobotModel;
use penelope_hal::{
    Dynamics, IkSolutions, InverseKinematics, JacobianFrame, Jacobian, JointLimits, JointSpaceMatrix,
    JointVector, Kinematics, KinematicsError, Pose, RobotModel,
};

/// A robot model chosen by configuration.
#[derive(Clone, Debug)]
pub enum LabModel {
    /// Float kinematics and dynamics.
    Float(DhRobotModel),
}

impl LabModel {
    /// The underlying float model (dynamics, named poses, encoder scaling).
    pub fn float(&self) -> &DhRobotModel {
        match self {
            LabModel::Float(m) => m,
        }
    }
}

impl Kinematics for LabModel {
    fn joint_count(&self) -> usize {
        self.float().joint_count()
    }
    fn forward(&self, q: &JointVector) -> Pose {
        match self {
            LabModel::Float(m) => m.forward(q),
        }
    }
    fn jacobian(&self, q: &JointVector, frame: JacobianFrame) -> Jacobian {
        match self {
            LabModel::Float(m) => m.jacobian(q, frame),
        }
    }
}

impl InverseKinematics for LabModel {
    fn inverse_all(&self, target: &Pose, out: &mut IkSolutions) -> Result<usize, KinematicsError> {
        self.float().inverse_all(target, out)
    }
    fn inverse_near(&self, target: &Pose, seed: &JointVector) -> Result<JointVector, KinematicsError> {
        self.float().inverse_near(target, seed)
    }
}

impl Dynamics for LabModel {
    fn gravity(&self, q: &JointVector) -> JointVector {
        self.float().gravity(q)
    }
    fn inertia(&self, q: &JointVector) -> JointSpaceMatrix {
        self.float().inertia(q)
    }
    fn inverse_dynamics(&self, q: &JointVector, qd: &JointVector, qdd: &JointVector) -> JointVector {
        self.float().inverse_dynamics(q, qd, qdd)
    }
    fn friction(&self, qd: &JointVector) -> JointVector {
        self.float().friction(qd)
    }
}

impl RobotModel for LabModel {
    fn limits(&self) -> &JointLimits {
        self.float().limits()
    }
}
