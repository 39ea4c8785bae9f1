//! Lawrence's four-channel architecture (Lawrence 1993; Hashtrudi-Zaad & Salcudean 2001): the
//! general form of bilateral teleoperation, of which the classical laws are special cases.
//!
//! ```text
//!  master:  F_cm = -C_m v_m  + C_4 (x_s, v_s)  + C_2 F_e  + C_6 F_h      (this module)
//!  slave:   F_cs = -C_s v_s  + C_1 (x_m, v_m)  + C_5 F_e  + C_3 F_h
//! ```
//!
//! In Penelope's Cartesian form, on the master side ([`FourChannelMaster`]):
//!
//! - `C_m`, the master's local impedance: a damping on its tool twist
//!   ([`ForceDisplayConfig::damping`]);
//! - `C_2`, the force channel: the slave's sensed wrench, mapped and scaled by the channel's force
//!   gain, through the display's low-pass and dead bands, times `c2`;
//! - `C_4`, the position channel: a spring-damper toward the slave's mapped pose and twist
//!   ([`ImpedanceConfig`] stiffness and damping), times `c4`;
//! - `C_6`, local force feedback: the operator's wrench on the handle (the loop's sensor on the
//!   handle, turned into the base frame at the tool: [`contact_in_base`]), times `c6`.
//!
//! The sum is capped as one wrench (direction kept) and displayed as `tau = J^T F + g(q)`. On
//! the slave side ([`FourChannelSlave`](super::FourChannelSlave)), `C_1` is the stiff tracking of
//! the master's mapped pose, `C_3` the operator's wrench the master sends when its loop reads a
//! handle sensor, and `C_5` the slave's own contact.
//!
//! The special cases, which a test shows equal the classical laws sample for sample:
//!
//! | law | c2 | c4 | c6 | C_m | the same as |
//! |---|---|---|---|---|---|
//! | position-forward / force-back | 1 | 0 | 0 | the display's damping | [`ForceDisplay`](super::ForceDisplay) |
//! | position-error | 0 | 1 | 0 | 0 | [`PositionErrorMaster`](super::PositionErrorMaster) |
//!
//! A term whose coefficient is zero is not computed (so a zero-coefficient channel needs no
//! input: a position-error master needs no wrench in its reference).
//!
//! # Real-time
//! `activate` and `update`: no allocation, no blocking, constant time, no panics.

use nalgebra::Vector6;
use penelope_hal::{
    ControlInput, Controller, ControllerError, Frame, JacobianFrame, JointCommand, JointState,
    Pose, Reference, RobotModel, Timestamp, Wrench,
};

use super::display::{ForceDisplayConfig, display_torques, force_channel, reference_wrench};
use super::impedance::{ImpedanceConfig, spring};
use super::passivity::PassivityObserver;
use super::{TeleopConfigError, cap_wrench, contact_in_base, effort};

/// Settings of a [`FourChannelMaster`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FourChannelConfig {
    /// `C_2`: weight of the force channel (the slave's mapped wrench).
    pub c2: f64,
    /// `C_4`: weight of the position channel (the spring-damper to the slave's mapped pose).
    pub c4: f64,
    /// `C_6`: weight of the operator's wrench on the handle, fed back locally.
    pub c6: f64,
    /// The force channel's filter and dead bands, the local damping `C_m` (its `damping`), the
    /// caps on the whole wrench and the gravity compensation.
    pub display: ForceDisplayConfig,
    /// The position channel's stiffness and damping (its caps, ramp and gravity compensation are
    /// not used: the display's apply to the whole).
    pub spring: ImpedanceConfig,
    /// Where the handle's force sensor sits in the tool frame (`C_6` on a `Sensor`-frame reading
    /// needs it; the node sets it from the loop's sensor).
    pub sensor_mount: Option<Pose>,
}

impl FourChannelConfig {
    /// Position forward, force back: `c2 = 1`, with `display` as the force display's settings.
    pub fn force_position(display: ForceDisplayConfig) -> Self {
        FourChannelConfig {
            c2: 1.0,
            c4: 0.0,
            c6: 0.0,
            display,
            spring: ImpedanceConfig::master(),
            sensor_mount: None,
        }
    }

    /// Position error: `c4 = 1` with `spring` (its caps and gravity compensation too), no
    /// local damping.
    pub fn position_error(spring: ImpedanceConfig) -> Self {
        FourChannelConfig {
            c2: 0.0,
            c4: 1.0,
            c6: 0.0,
            display: ForceDisplayConfig {
                damping: [0.0; 6],
                max_force: spring.max_force,
                max_torque: spring.max_torque,
                gravity_compensation: spring.gravity_compensation,
                ..ForceDisplayConfig::default()
            },
            spring,
            sensor_mount: None,
        }
    }

    /// Checks the values.
    ///
    /// # Errors
    /// [`TeleopConfigError`] for a non-finite coefficient or invalid channel settings.
    pub fn validate(&self) -> Result<(), TeleopConfigError> {
        for (x, parameter) in [(self.c2, "c2"), (self.c4, "c4"), (self.c6, "c6")] {
            if !x.is_finite() {
                return Err(TeleopConfigError::NonFinite { parameter });
            }
        }
        self.display.validate()?;
        self.spring.validate()
    }
}

/// The master half of Lawrence's four-channel architecture. See the [module docs](self).
#[derive(Clone, Copy, Debug)]
pub struct FourChannelMaster {
    config: FourChannelConfig,
    filtered: Vector6<f64>,
    observer: PassivityObserver,
    last_wrench: Wrench,
}

impl FourChannelMaster {
    /// A master with these settings.
    ///
    /// # Errors
    /// As [`FourChannelConfig::validate`].
    pub fn new(config: FourChannelConfig) -> Result<Self, TeleopConfigError> {
        config.validate()?;
        Ok(FourChannelMaster {
            config,
            filtered: Vector6::zeros(),
            observer: PassivityObserver::new(),
            last_wrench: Wrench::zero(Frame::Base),
        })
    }

    /// The settings.
    pub fn config(&self) -> &FourChannelConfig {
        &self.config
    }

    /// Sets where the handle's force sensor sits in the tool frame (`C_6` on a `Sensor`-frame
    /// reading).
    pub fn set_sensor_mount(&mut self, mount: Option<Pose>) {
        self.config.sensor_mount = mount;
    }

    /// New settings while running (the filter and the observer keep their state; the sensor
    /// mount stays, it belongs to the loop's sensor).
    ///
    /// # Errors
    /// As [`FourChannelConfig::validate`]; the old settings stay.
    pub fn set_config(&mut self, config: FourChannelConfig) -> Result<(), TeleopConfigError> {
        config.validate()?;
        self.config = FourChannelConfig {
            sensor_mount: self.config.sensor_mount,
            ..config
        };
        Ok(())
    }

    /// The wrench displayed on the last tick (master base frame), after the cap.
    pub fn last_wrench(&self) -> &Wrench {
        &self.last_wrench
    }

    /// The energy observer of the master port (operator force `-F`, tool twist).
    pub fn passivity(&self) -> &PassivityObserver {
        &self.observer
    }
}

impl Controller for FourChannelMaster {
    fn kind(&self) -> &'static str {
        "four-channel-master"
    }

    fn port_energy(&self) -> Option<f64> {
        Some(self.observer.energy())
    }

    fn activate(&mut self, _now: Timestamp, _measured: &JointState, _model: &dyn RobotModel) {
        self.filtered = Vector6::zeros();
        self.observer.reset();
        self.last_wrench = Wrench::zero(Frame::Base);
    }

    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        if !input.state.is_finite() {
            return Err(ControllerError::NonFinite);
        }
        let c = &self.config;
        let model = input.model;
        let q = &input.state.position;
        let dt = input.period.as_secs_f64();
        let jac = model.jacobian(q, JacobianFrame::Base);
        let v = jac * input.state.velocity;
        let mut f = Vector6::zeros();
        if c.c2 != 0.0 {
            let wanted = reference_wrench(input)?;
            f += force_channel(&mut self.filtered, wanted.as_ref(), &c.display, dt) * c.c2;
        }
        if c.c4 != 0.0 {
            let motion = match input.reference {
                Reference::Cartesian(m) => m,
                Reference::Hybrid(h) => &h.motion,
                _ => return Err(ControllerError::UnsupportedReference),
            };
            f += spring(&c.spring, 1.0, motion, &model.forward(q), &v)? * c.c4;
        }
        if c.c6 != 0.0 {
            let hand = input
                .wrench
                .and_then(|w| contact_in_base(w, &model.forward(q), c.sensor_mount.as_ref()))
                .ok_or(ControllerError::MissingInput)?;
            f += hand * c.c6;
        }
        let local = Vector6::from(c.display.damping);
        if local.iter().any(|d| *d != 0.0) {
            f -= local.component_mul(&v);
        }
        let (f, _) = cap_wrench(&f, c.display.max_force, c.display.max_torque);
        // The operator applies about -f to the device: that is the power into the system.
        self.observer.observe(dt, &(-f), &v);
        let (tau, shown) = display_torques(input, &f, c.display.gravity_compensation)?;
        self.last_wrench = shown;
        effort(tau)
    }
}
