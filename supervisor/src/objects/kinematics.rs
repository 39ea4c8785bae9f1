//! The model a robot's loops compute with, chosen by the robot's `kinematics` key: the float
//! model, or (for the FRHC) the bit-exact FPGA kinematics with the float dynamics. Plants behind
//! simulated boards are physics and always use the float model.

use penelope_drivers::model::DhRobotModel;
use penelope_fpga::FpgaKinematics;
use penelope_hal::{
    Dynamics, IkSolutions, InverseKinematics, Jacobian, JacobianFrame, JointLimits,
    JointSpaceMatrix, JointVector, Kinematics, KinematicsError, Pose, RobotModel,
};

/// A robot model with the kinematics its configuration chose.
#[derive(Clone, Debug)]
pub enum RobotKinematics {
    /// Float kinematics and dynamics.
    Float(DhRobotModel),
    /// Forward kinematics and Jacobian from the bit-exact model of the FPGA board; inverse
    /// kinematics and dynamics from the float model.
    Fpga {
        /// The FPGA model.
        fpga: Box<FpgaKinematics>,
        /// The float model, for everything the FPGA does not compute.
        float: DhRobotModel,
    },
}

/// The FPGA kinematics were asked for a robot the FPGA board does not model.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NoFpgaModel(pub String);

impl std::fmt::Display for NoFpgaModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "kinematics = \"fpga\" models the FRHC's FPGA board; robot model `{}` has none",
            self.0
        )
    }
}

impl std::error::Error for NoFpgaModel {}

impl RobotKinematics {
    /// The model for `float` with the kinematics the configuration chose.
    ///
    /// # Errors
    /// [`NoFpgaModel`] when `fpga` is asked for a robot other than the FRHC.
    pub fn new(float: DhRobotModel, fpga: bool) -> Result<Self, NoFpgaModel> {
        if !fpga {
            return Ok(RobotKinematics::Float(float));
        }
        if float.name() != "frhc" {
            return Err(NoFpgaModel(float.name().to_string()));
        }
        Ok(RobotKinematics::Fpga {
            fpga: Box::new(FpgaKinematics::frhc()),
            float,
        })
    }

    /// The underlying float model (dynamics, named poses, encoder scaling).
    pub fn float(&self) -> &DhRobotModel {
        match self {
            RobotKinematics::Float(m) => m,
            RobotKinematics::Fpga { float, .. } => float,
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
            RobotKinematics::Fpga { fpga, .. } => fpga.forward(q),
        }
    }
    fn jacobian(&self, q: &JointVector, frame: JacobianFrame) -> Jacobian {
        match self {
            RobotKinematics::Float(m) => m.jacobian(q, frame),
            RobotKinematics::Fpga { fpga, .. } => fpga.jacobian(q, frame),
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
}
