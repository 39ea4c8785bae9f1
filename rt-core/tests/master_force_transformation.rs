//! The master laws turn their wrench into joint torques with the model's own force
//! transformation (`RobotModel::wrench_to_torques`), not with a Jacobian of their own: where the
//! robot's board computes `tau = J^T F` (the FRHC on its FPGA board), the law uses the board's
//! result.

#[path = "teleop_model.rs"]
mod model;

use core::time::Duration;

use model::DhArm;
use nalgebra::Vector3;
use penelope_hal::{
    CartesianReference, ControlInput, Controller, Dynamics, Frame, IkSolutions, InverseKinematics,
    Jacobian, JacobianFrame, JointCommand, JointLimits, JointSpaceMatrix, JointState, JointVector,
    Kinematics, KinematicsError, Pose, Reference, RobotModel, Timestamp, Twist, Wrench,
};
use penelope_rt_core::teleop::{
    ForceDisplay, ForceDisplayConfig, ImpedanceConfig, PositionErrorMaster,
};

/// The FRHC whose force transformation is "computed elsewhere": `J^T F` plus a marker, so a law
/// that uses it shows the marker in its torques and one that forms `J^T F` itself does not.
struct MarkedTorques(DhArm);

fn marker() -> JointVector {
    JointVector::from([0.001, -0.002, 0.003, -0.004, 0.005, -0.006])
}

impl Kinematics for MarkedTorques {
    fn joint_count(&self) -> usize {
        self.0.joint_count()
    }
    fn forward(&self, q: &JointVector) -> Pose {
        self.0.forward(q)
    }
    fn jacobian(&self, q: &JointVector, frame: JacobianFrame) -> Jacobian {
        self.0.jacobian(q, frame)
    }
}
impl InverseKinematics for MarkedTorques {
    fn inverse_all(&self, t: &Pose, out: &mut IkSolutions) -> Result<usize, KinematicsError> {
        self.0.inverse_all(t, out)
    }
    fn inverse_near(&self, t: &Pose, seed: &JointVector) -> Result<JointVector, KinematicsError> {
        self.0.inverse_near(t, seed)
    }
}
impl Dynamics for MarkedTorques {
    fn gravity(&self, q: &JointVector) -> JointVector {
        self.0.gravity(q)
    }
    fn inertia(&self, q: &JointVector) -> JointSpaceMatrix {
        self.0.inertia(q)
    }
    fn inverse_dynamics(&self, q: &JointVector, qd: &JointVector, a: &JointVector) -> JointVector {
        self.0.inverse_dynamics(q, qd, a)
    }
}
impl RobotModel for MarkedTorques {
    fn limits(&self) -> &JointLimits {
        self.0.limits()
    }
    fn wrench_to_torques(
        &self,
        q: &JointVector,
        wrench: &Wrench,
    ) -> Result<JointVector, KinematicsError> {
        Ok(self.0.wrench_to_torques(q, wrench)? + marker())
    }
}

fn torques(law: &mut dyn Controller, model: &dyn RobotModel, reference: &Reference) -> JointVector {
    let q = DhArm::frhc_home();
    let state = JointState::at_rest(q);
    law.activate(Timestamp::ZERO, &state, model);
    let input = ControlInput {
        now: Timestamp::from_nanos(1_000_000),
        period: Duration::from_millis(1),
        state: &state,
        reference,
        wrench: None,
        model,
    };
    match law.update(&input).unwrap() {
        JointCommand::Effort(t) => t,
        other => panic!("expected torques, got {other:?}"),
    }
}

#[test]
fn force_display_and_position_error_master_use_the_models_force_transformation() {
    let plain = DhArm::frhc();
    let marked = MarkedTorques(DhArm::frhc());
    let push = Reference::Wrench(Wrench {
        force: Vector3::new(2.0, -1.0, 3.0),
        torque: Vector3::zeros(),
        frame: Frame::Base,
    });
    let display = || ForceDisplay::new(ForceDisplayConfig::default()).unwrap();
    let a = torques(&mut display(), &plain, &push);
    let b = torques(&mut display(), &marked, &push);
    assert!(((b - a) - marker()).norm() < 1e-12, "{a} vs {b}");

    let pose = plain.forward(&DhArm::frhc_home());
    let mut target = pose;
    target.translation.vector += Vector3::new(0.0, 0.01, 0.0);
    let spring = Reference::Cartesian(CartesianReference {
        pose: target,
        twist: Twist::default(),
    });
    let master = || PositionErrorMaster::new(ImpedanceConfig::master()).unwrap();
    let a = torques(&mut master(), &plain, &spring);
    let b = torques(&mut master(), &marked, &spring);
    assert!(((b - a) - marker()).norm() < 1e-12, "{a} vs {b}");
}
