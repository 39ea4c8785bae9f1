//! Cartesian impedance, and the position-error (position-position) master built on it.

use core::time::Duration;

use nalgebra::{Matrix3, Vector6};
use penelope_hal::{
    CartesianReference, ControlInput, Controller, ControllerError, Frame, JacobianFrame,
    JointCommand, JointState, Pose, Reference, RobotModel, Timestamp, Wrench,
};

use super::display::display_torques;
use super::passivity::PassivityObserver;
use super::{
    TeleopConfigError, bottom, cap_wrench, check_cap, check_gains, effort, pose_error, top,
    twist_in_base, wrench_in_base,
};

/// Settings of a [`CartesianImpedance`] (and of a [`PositionErrorMaster`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImpedanceConfig {
    /// Diagonal stiffness `[x, y, z, rx, ry, rz]` in the base frame: N/m, then N·m/rad.
    pub stiffness: [f64; 6],
    /// Diagonal damping on the twist error: N·s/m, then N·m·s/rad.
    pub damping: [f64; 6],
    /// Add the model's gravity torque `g(q)`.
    pub gravity_compensation: bool,
    /// Largest force the law commands, N (`f64::INFINITY`: no cap). The whole wrench is scaled
    /// down together, so its direction is kept.
    pub max_force: f64,
    /// Largest moment the law commands, N·m (`f64::INFINITY`: no cap).
    pub max_torque: f64,
    /// After activation the stiffness rises linearly from 0 over this time (damping and gravity
    /// compensation act at once). Zero: full stiffness at once.
    pub ramp_in: Duration,
}

impl Default for ImpedanceConfig {
    /// A PUMA-sized slave: 2000 N/m and 50 N·m/rad, 150 N·s/m and 3 N·m·s/rad, gravity
    /// compensated, no caps, no ramp.
    fn default() -> Self {
        ImpedanceConfig {
            stiffness: [2000.0, 2000.0, 2000.0, 50.0, 50.0, 50.0],
            damping: [150.0, 150.0, 150.0, 3.0, 3.0, 3.0],
            gravity_compensation: true,
            max_force: f64::INFINITY,
            max_torque: f64::INFINITY,
            ramp_in: Duration::ZERO,
        }
    }
}

impl ImpedanceConfig {
    /// An FRHC-sized master for position-error: 1000 N/m and 2 N·m/rad, 20 N·s/m and
    /// 0.05 N·m·s/rad, gravity compensated, capped at 10 N and 0.5 N·m.
    pub fn master() -> Self {
        ImpedanceConfig {
            stiffness: [1000.0, 1000.0, 1000.0, 2.0, 2.0, 2.0],
            damping: [20.0, 20.0, 20.0, 0.05, 0.05, 0.05],
            gravity_compensation: true,
            max_force: 10.0,
            max_torque: 0.5,
            ramp_in: Duration::ZERO,
        }
    }

    /// Checks the values.
    ///
    /// # Errors
    /// [`TeleopConfigError`] for negative or non-finite gains, or NaN/negative caps.
    pub fn validate(&self) -> Result<(), TeleopConfigError> {
        check_gains(&self.stiffness, "stiffness")?;
        check_gains(&self.damping, "damping")?;
        check_cap(self.max_force, "max_force")?;
        check_cap(self.max_torque, "max_torque")
    }
}

/// Cartesian impedance: `tau = J^T (K e + D (v_ref - v)) + g(q)`, with `e` the pose error
/// `[p_ref - p; log(R_ref R^T)]` (axis-angle, base frame), `J` the base-frame geometric Jacobian
/// and `v = J qd`.
///
/// Follows `Reference::Cartesian` and `Reference::Hybrid`: along the hybrid reference's force
/// axes (in its wrench's frame, `Base` or `Tool`) the commanded wrench component is the
/// reference wrench (the wrench the tool applies to the environment) instead of the spring-damper.
/// It is also the slave half of position-error teleoperation, following the mapped master pose
/// (`F_s = K (sigma x_m - x_s) + D (sigma v_m - v_s)`).
///
/// # Real-time
/// `activate` and `update`: no allocation, no blocking, constant time (one forward kinematics,
/// one Jacobian, one gravity evaluation), no panics.
#[derive(Clone, Copy, Debug)]
pub struct CartesianImpedance {
    config: ImpedanceConfig,
    activated_at: Timestamp,
    last_wrench: Wrench,
    /// Energy into the law at the tool (the robot's push `-f` on the spring, tool twist).
    observer: PassivityObserver,
}

impl CartesianImpedance {
    /// A controller with these settings.
    ///
    /// # Errors
    /// As [`ImpedanceConfig::validate`].
    pub fn new(config: ImpedanceConfig) -> Result<Self, TeleopConfigError> {
        config.validate()?;
        Ok(CartesianImpedance {
            config,
            activated_at: Timestamp::ZERO,
            last_wrench: Wrench::zero(Frame::Base),
            observer: PassivityObserver::new(),
        })
    }

    /// The settings.
    pub fn config(&self) -> &ImpedanceConfig {
        &self.config
    }

    /// New settings while running (the stiffness ramp goes on from the activation instant).
    ///
    /// # Errors
    /// As [`ImpedanceConfig::validate`]; the old settings stay.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn set_config(&mut self, config: ImpedanceConfig) -> Result<(), TeleopConfigError> {
        config.validate()?;
        self.config = config;
        Ok(())
    }

    /// The energy observer at the tool (the robot's push on the spring, tool twist): negative
    /// when the law has given the robot more energy than it took from it.
    pub fn passivity(&self) -> &PassivityObserver {
        &self.observer
    }

    /// The wrench commanded on the last tick (base frame, about the tool origin), after caps.
    pub fn last_wrench(&self) -> &Wrench {
        &self.last_wrench
    }

    /// The law: the commanded wrench and `v` (the measured tool twist), both base frame.
    fn wrench(
        &self,
        input: &ControlInput<'_>,
    ) -> Result<(Vector6<f64>, Vector6<f64>), ControllerError> {
        let model = input.model;
        let q = &input.state.position;
        if !input.state.is_finite() {
            return Err(ControllerError::NonFinite);
        }
        let (motion, hybrid) = match input.reference {
            Reference::Cartesian(c) => (c, None),
            Reference::Hybrid(h) => (&h.motion, Some(h)),
            _ => return Err(ControllerError::UnsupportedReference),
        };
        let pose = model.forward(q);
        let jac = model.jacobian(q, JacobianFrame::Base);
        let v = jac * input.state.velocity;
        let ramp = ramp_factor(self.config.ramp_in, self.activated_at, input.now);
        let mut f = spring(&self.config, ramp, motion, &pose, &v)?;
        if let Some(h) = hybrid {
            // Selection in the wrench's frame: rotate in, substitute the force axes, rotate back.
            let rot: Matrix3<f64> = match h.wrench.frame {
                Frame::Base | Frame::Master => Matrix3::identity(),
                Frame::Tool | Frame::Flange => *pose.rotation.to_rotation_matrix().matrix(),
                Frame::Sensor => return Err(ControllerError::UnsupportedReference),
            };
            let wanted =
                wrench_in_base(&h.wrench, &pose).ok_or(ControllerError::UnsupportedReference)?;
            let rt = rot.transpose();
            let (mut lin, mut ang) = (rt * top(&f), rt * bottom(&f));
            let (wl, wa) = (rt * top(&wanted), rt * bottom(&wanted));
            for i in 0..3 {
                if h.force_axes[i] {
                    lin[i] = wl[i];
                }
                if h.force_axes[i + 3] {
                    ang[i] = wa[i];
                }
            }
            f = super::stack(&(rot * lin), &(rot * ang));
        }
        let (f, _) = cap_wrench(&f, self.config.max_force, self.config.max_torque);
        Ok((f, v))
    }

    fn torques(
        &mut self,
        input: &ControlInput<'_>,
    ) -> Result<(JointCommand, Vector6<f64>, Vector6<f64>), ControllerError> {
        let (f, v) = self.wrench(input)?;
        let (tau, wrench) = display_torques(input, &f, self.config.gravity_compensation)?;
        self.last_wrench = wrench;
        Ok((effort(tau)?, f, v))
    }
}

/// The spring-damper `K e ramp + D (v_ref - v)` toward `motion` from the tool at `pose` moving
/// at `v` (base frame): the Cartesian impedance's law, and the position channel of the
/// four-channel master.
///
/// # Errors
/// [`ControllerError::UnsupportedReference`] for a twist in the sensor frame.
pub(crate) fn spring(
    config: &ImpedanceConfig,
    ramp: f64,
    motion: &CartesianReference,
    pose: &Pose,
    v: &Vector6<f64>,
) -> Result<Vector6<f64>, ControllerError> {
    let v_ref =
        twist_in_base(&motion.twist, &motion.pose).ok_or(ControllerError::UnsupportedReference)?;
    let e = pose_error(&motion.pose, pose);
    let k = Vector6::from(config.stiffness);
    let d = Vector6::from(config.damping);
    Ok(k.component_mul(&e) * ramp + d.component_mul(&(v_ref - v)))
}

fn ramp_factor(ramp: Duration, since: Timestamp, now: Timestamp) -> f64 {
    let len = ramp.as_secs_f64();
    if len <= 0.0 {
        1.0
    } else {
        (now.saturating_since(since).as_secs_f64() / len).min(1.0)
    }
}

impl Controller for CartesianImpedance {
    fn kind(&self) -> &'static str {
        "cartesian-impedance"
    }

    /// Stateless but for the stiffness ramp: with a reference at the measured pose (a trajectory
    /// started from it, or a freshly anchored teleop channel) the first command is the gravity
    /// torque minus the damping of the measured motion.
    fn activate(&mut self, now: Timestamp, _measured: &JointState, _model: &dyn RobotModel) {
        self.activated_at = now;
        self.last_wrench = Wrench::zero(Frame::Base);
        self.observer.reset();
    }

    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        let (cmd, f, v) = self.torques(input)?;
        // The robot pushes the spring with -f: the power into the law at this port.
        self.observer.observe(input.period.as_secs_f64(), &(-f), &v);
        Ok(cmd)
    }

    fn port_energy(&self) -> Option<f64> {
        Some(self.observer.energy())
    }
}

/// The master half of position-error (position-position) teleoperation:
/// `F_m = -Kp (x_m - x_s/sigma) - Kd (v_m - v_s/sigma)`, capped at the device limits, plus the
/// master's gravity compensation, `tau = J^T F_m + g(q)`.
///
/// Its reference is the slave's pose and twist mapped into the master's base frame (`x_s/sigma`
/// with rotation and anchors), which a `SlaveToMaster` [`TeleopChannel`](super::TeleopChannel)
/// produces from the slave's pose samples (`Reference::Cartesian`, or the motion part of a
/// `Hybrid`). So the law is a capped [`CartesianImpedance`] toward that pose; the slave side is a
/// [`CartesianImpedance`] toward the mapped master pose (a `MasterToSlave` channel), so both sides
/// feel the same spring. For a symmetric coupling choose `K_slave = K_master * k_f / sigma` and
/// likewise for the damping.
///
/// A [`PassivityObserver`] watches the master port (operator force `-F_m`, tool twist).
///
/// # Real-time
/// As [`CartesianImpedance`].
#[derive(Clone, Copy, Debug)]
pub struct PositionErrorMaster {
    law: CartesianImpedance,
    observer: PassivityObserver,
}

impl PositionErrorMaster {
    /// A master law; [`ImpedanceConfig::master`] is a starting point for an FRHC.
    ///
    /// # Errors
    /// As [`ImpedanceConfig::validate`].
    pub fn new(config: ImpedanceConfig) -> Result<Self, TeleopConfigError> {
        Ok(PositionErrorMaster {
            law: CartesianImpedance::new(config)?,
            observer: PassivityObserver::new(),
        })
    }

    /// The settings.
    pub fn config(&self) -> &ImpedanceConfig {
        self.law.config()
    }

    /// New settings while running (the energy observer keeps its state).
    ///
    /// # Errors
    /// As [`ImpedanceConfig::validate`]; the old settings stay.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn set_config(&mut self, config: ImpedanceConfig) -> Result<(), TeleopConfigError> {
        self.law.set_config(config)
    }

    /// The wrench displayed on the last tick (master base frame), after caps.
    pub fn last_wrench(&self) -> &Wrench {
        self.law.last_wrench()
    }

    /// The energy observer of the master port.
    pub fn passivity(&self) -> &PassivityObserver {
        &self.observer
    }
}

impl Controller for PositionErrorMaster {
    fn kind(&self) -> &'static str {
        "position-error-master"
    }

    fn activate(&mut self, now: Timestamp, measured: &JointState, model: &dyn RobotModel) {
        self.law.activate(now, measured, model);
        self.observer.reset();
    }

    fn port_energy(&self) -> Option<f64> {
        Some(self.observer.energy())
    }

    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        // The spring to the slave's pose only: a hybrid reference's wrench (the slave's sensed
        // force, on its way to a force display) is not this law's to show.
        let motion;
        let input = match input.reference {
            Reference::Hybrid(h) => {
                motion = Reference::Cartesian(h.motion);
                &ControlInput {
                    reference: &motion,
                    ..*input
                }
            }
            _ => input,
        };
        let (cmd, f, v) = self.law.torques(input)?;
        self.observer.observe(input.period.as_secs_f64(), &(-f), &v);
        Ok(cmd)
    }
}
