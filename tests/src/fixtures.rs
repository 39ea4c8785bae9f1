//! Small stand-ins the fault-injection tests plug into a control loop.

use penelope_hal::{
    ControlInput, Controller, ControllerError, JointCommand, JointState, JointVector, RobotModel,
    Timestamp,
};
use penelope_rt_core::telemetry::{TelemetrySample, TelemetrySink};

/// A law that asks for the same torque on every joint, whatever the state: a loop that drives
/// its board by effort, for the watchdog and stop tests.
pub struct ConstantTorque(pub f64);

impl Controller for ConstantTorque {
    fn kind(&self) -> &'static str {
        "constant-torque"
    }
    fn activate(&mut self, _now: Timestamp, _measured: &JointState, _model: &dyn RobotModel) {}
    fn update(&mut self, _input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        Ok(JointCommand::Effort(JointVector::repeat(self.0)))
    }
}

/// A telemetry port that keeps nothing.
pub struct Discard;

impl TelemetrySink for Discard {
    fn push(&mut self, _sample: &TelemetrySample) -> bool {
        true
    }
}
