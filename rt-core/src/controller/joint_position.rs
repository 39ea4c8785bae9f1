//! Joint positions for the board's own servo: the law for boards that close the position loop
//! themselves (a Galil DMC), where a torque loop over a slow link cannot hold the arm.

use penelope_hal::{
    ControlInput, Controller, ControllerError, JointCommand, JointState, JointVector, Reference,
    RobotModel, Timestamp,
};

/// Sends the joint reference's positions to the board's servo ([`JointCommand::Position`]),
/// moving the target at most `max_velocity` per second, so a reference that jumps (a step, a
/// re-activation) becomes a ramp the servo can follow. Starts from the measured positions.
#[derive(Clone, Debug)]
pub struct JointPositionServo {
    max_velocity: JointVector,
    target: JointVector,
}

impl JointPositionServo {
    /// A servo law whose target moves at most `max_velocity` (rad/s, per joint; non-finite or
    /// non-positive entries mean no limit).
    pub fn new(max_velocity: JointVector) -> Self {
        JointPositionServo {
            max_velocity,
            target: JointVector::zeros(),
        }
    }

    /// The velocity limits, rad/s.
    pub fn max_velocity(&self) -> &JointVector {
        &self.max_velocity
    }
}

impl Controller for JointPositionServo {
    fn kind(&self) -> &'static str {
        "joint-position"
    }

    fn activate(&mut self, _now: Timestamp, measured: &JointState, _model: &dyn RobotModel) {
        self.target = measured.position;
    }

    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        let Reference::Joint(r) = input.reference else {
            return Err(ControllerError::UnsupportedReference);
        };
        if !r.position.iter().all(|x| x.is_finite()) {
            return Err(ControllerError::NonFinite);
        }
        let dt = input.period.as_secs_f64();
        let mut target = self.target;
        for j in 0..target.len() {
            let limit = self.max_velocity[j];
            let step = r.position[j] - target[j];
            target[j] = if limit.is_finite() && limit > 0.0 {
                target[j] + step.clamp(-limit * dt, limit * dt)
            } else {
                r.position[j]
            };
        }
        self.target = target;
        Ok(JointCommand::Position(target))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::time::Duration;
    use penelope_hal::{Frame, JointReference, Wrench};
    use penelope_testbed::DecoupledChain;

    #[test]
    fn the_target_starts_at_the_measured_pose_and_ramps_to_the_reference() {
        let model = DecoupledChain::six_joint();
        let mut law = JointPositionServo::new(JointVector::repeat(1.0));
        let mut measured = JointState::default();
        measured.position[0] = 0.5;
        law.activate(Timestamp::ZERO, &measured, &model);
        let mut goal = JointVector::zeros();
        goal[0] = 0.5 + 0.0105;
        goal[1] = -0.002;
        let reference = Reference::Joint(JointReference {
            position: goal,
            ..JointReference::default()
        });
        let wrench = Wrench::zero(Frame::Base);
        let input = ControlInput {
            now: Timestamp::ZERO,
            period: Duration::from_millis(1),
            state: &measured,
            reference: &reference,
            wrench: Some(&wrench),
            model: &model,
        };
        // 1 rad/s at 1 ms: 1 mrad per tick, so joint 0 needs 11 ticks, joint 1 two.
        let mut last = JointVector::zeros();
        for tick in 1..=11 {
            let Ok(JointCommand::Position(t)) = law.update(&input) else {
                panic!("a position command");
            };
            assert!((t[0] - (0.5 + 0.001 * f64::from(tick)).min(goal[0])).abs() < 1e-12);
            last = t;
        }
        assert!((last - goal).norm() < 1e-12);
        let cartesian = Reference::Cartesian(penelope_hal::CartesianReference::default());
        let input = ControlInput {
            reference: &cartesian,
            ..input
        };
        assert_eq!(
            law.update(&input),
            Err(ControllerError::UnsupportedReference)
        );
    }
}
