//! The law a controller runs, from its configuration: its gains (a joint PID's defaults are
//! the robot's torque limits) and the rt-core law of each controller kind.

use penelope_drivers::model::SerialRobotModel;
use penelope_hal::{JointVector, Kinematics};
use penelope_rt_core::controller::{JointPid, JointPidGains, JointPositionServo};
use penelope_rt_core::teleop::CartesianImpedance;

use crate::objects::error::ObjectError;
use crate::objects::registry::{ControllerConfig, JointPidConfig, finite_effort, impedance};
use crate::objects::runtime::ControlLaw;

/// The default joint gains `(kp, kd)` of a robot: a joint PID's when its configuration leaves
/// them out, and what a loop on a simulated body holds its pose with (10 and 0.5 times each
/// joint's torque limit, per rad and per rad/s).
pub(super) fn default_joint_gains(
    model: &SerialRobotModel,
    n: usize,
) -> (JointVector, JointVector) {
    let mut kp = JointVector::zeros();
    let mut kd = JointVector::zeros();
    for j in 0..n {
        kp[j] = 10.0 * finite_effort(model, j);
        kd[j] = 0.5 * finite_effort(model, j);
    }
    (kp, kd)
}

/// The law of a controller configured as `law` (not a joint-groups controller) for `model`;
/// `hold` is the robot's default joint gains `(kp, kd)`.
pub(super) fn node_law(
    law: &ControllerConfig,
    kind: &str,
    model: &SerialRobotModel,
    hold: (JointVector, JointVector),
) -> Result<ControlLaw, ObjectError> {
    let n = model.joint_count();
    Ok(match law {
        ControllerConfig::Pid(p) => {
            ControlLaw::Pid(JointPid::new(pid_gains(p, kind, n, hold.0, hold.1)?))
        }
        ControllerConfig::Impedance(i) => {
            ControlLaw::Impedance(CartesianImpedance::new(impedance(i)).map_err(|e| {
                ObjectError::BadConfig {
                    kind: kind.into(),
                    message: format!("{e:?}"),
                }
            })?)
        }
        ControllerConfig::Position(p) => {
            let max_velocity = p
                .max_velocity
                .resolve(kind, "max_velocity", n, 1e-3, 100.0)?;
            ControlLaw::Position(JointPositionServo::new(max_velocity))
        }
        ControllerConfig::ForceDisplay(c) => ControlLaw::ForceDisplay(c.law(kind)?),
        ControllerConfig::PositionError(c) => ControlLaw::PositionErrorMaster(c.law(kind)?),
        ControllerConfig::FourChannel(c) => ControlLaw::FourChannel(c.law(kind)?),
        ControllerConfig::Tracking(c, servo) => ControlLaw::SlaveTracking(c.law(kind, *servo)?),
        ControllerConfig::FourChannelSlave(c) => ControlLaw::FourChannelSlave(c.law(kind)?),
        ControllerConfig::WaveMaster(c) => ControlLaw::ForceDisplay(c.law(kind)?),
        ControllerConfig::WaveSlave(c) => ControlLaw::SlaveTracking(c.law(kind)?),
        ControllerConfig::Groups(_) => {
            return Err(ObjectError::Internal(
                "a joint group inside a joint group".into(),
            ));
        }
    })
}

/// A joint PID's gains from its configuration, each left-out gain the robot's default.
pub(super) fn pid_gains(
    p: &JointPidConfig,
    kind: &str,
    n: usize,
    kp_default: JointVector,
    kd_default: JointVector,
) -> Result<JointPidGains, ObjectError> {
    let kp = match &p.kp {
        Some(k) => k.resolve(kind, "kp", n, 0.0, 1e7)?,
        None => kp_default,
    };
    let kd = match &p.kd {
        Some(k) => k.resolve(kind, "kd", n, 0.0, 1e6)?,
        None => kd_default,
    };
    Ok(JointPidGains {
        kp,
        ki: p.ki.resolve(kind, "ki", n, 0.0, 1e7)?,
        kd,
        integral_limit: p
            .integral_limit
            .resolve(kind, "integral_limit", n, 0.0, 1e5)?,
        gravity_compensation: p.gravity_compensation,
        acceleration_feedforward: p.acceleration_feedforward,
    })
}
