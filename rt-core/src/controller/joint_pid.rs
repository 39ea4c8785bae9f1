//! Joint-space PID with gravity compensation.

use core::time::Duration;

use penelope_hal::joint::all_finite;
use penelope_hal::{
    ControlInput, Controller, ControllerError, JointCommand, JointState, JointVector, Reference,
    RobotModel, Timestamp,
};

/// Gains of a [`JointPid`], per joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointPidGains {
    /// Proportional gain, N·m/rad.
    pub kp: JointVector,
    /// Integral gain, N·m/(rad·s).
    pub ki: JointVector,
    /// Derivative gain (on the velocity error), N·m·s/rad.
    pub kd: JointVector,
    /// Largest torque the integral term may contribute, N·m (anti-windup clamp).
    pub integral_limit: JointVector,
    /// Add the model's gravity torque `g(q)`.
    pub gravity_compensation: bool,
    /// Add `M(q) qdd_ref`, the inertia times the reference acceleration.
    pub acceleration_feedforward: bool,
}

impl JointPidGains {
    /// PD gains with gravity compensation and no integral action.
    pub fn pd(kp: JointVector, kd: JointVector) -> Self {
        JointPidGains {
            kp,
            ki: JointVector::zeros(),
            kd,
            integral_limit: JointVector::zeros(),
            gravity_compensation: true,
            acceleration_feedforward: false,
        }
    }
}

/// Joint-space PID plus gravity compensation:
/// `tau = kp e + ki ∫e + kd (qd_ref - qd) + g(q) [+ M(q) qdd_ref]`, with `e = q_ref - q`.
///
/// Follows [`Reference::Joint`]; other references are [`ControllerError::UnsupportedReference`].
///
/// # Real-time
/// [`Controller::update`] and [`Controller::activate`] are allocation-free and constant-time
/// (one gravity evaluation, one inertia evaluation with acceleration feed-forward).
#[derive(Clone, Debug)]
pub struct JointPid {
    gains: JointPidGains,
    integral: JointVector,
}

impl JointPid {
    /// A controller with `gains`.
    pub fn new(gains: JointPidGains) -> Self {
        JointPid {
            gains,
            integral: JointVector::zeros(),
        }
    }

    /// The gains.
    pub fn gains(&self) -> &JointPidGains {
        &self.gains
    }

    /// Replaces the gains (keeps the integral).
    pub fn set_gains(&mut self, gains: JointPidGains) {
        self.gains = gains;
    }
}

impl Controller for JointPid {
    fn kind(&self) -> &'static str {
        "joint-pid"
    }

    fn activate(&mut self, _now: Timestamp, _measured: &JointState, _model: &dyn RobotModel) {
        self.integral = JointVector::zeros();
    }

    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        let Reference::Joint(r) = input.reference else {
            return Err(ControllerError::UnsupportedReference);
        };
        let g = &self.gains;
        let q = &input.state.position;
        let qd = &input.state.velocity;
        let dt = duration_secs(input.period);
        let e = r.position - q;
        let ed = r.velocity - qd;
        let mut integral = self.integral + e * dt;
        // Anti-windup: the integral term stays within +- integral_limit.
        for j in 0..integral.len() {
            let limit = if g.ki[j] > 0.0 {
                g.integral_limit[j] / g.ki[j]
            } else {
                0.0
            };
            integral[j] = integral[j].clamp(-limit, limit);
        }
        let mut tau =
            g.kp.component_mul(&e) + g.ki.component_mul(&integral) + g.kd.component_mul(&ed);
        if g.gravity_compensation {
            tau += input.model.gravity(q);
        }
        if g.acceleration_feedforward {
            tau += input.model.inertia(q) * r.acceleration;
        }
        if !all_finite(&tau) || !all_finite(&integral) {
            return Err(ControllerError::NonFinite);
        }
        self.integral = integral;
        Ok(JointCommand::Effort(tau))
    }
}

fn duration_secs(d: Duration) -> f64 {
    d.as_secs() as f64 + f64::from(d.subsec_nanos()) * 1e-9
}
