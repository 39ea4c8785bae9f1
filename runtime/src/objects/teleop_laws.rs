//! The halves of the classical teleoperation laws as object kinds: their configuration keys
//! (what `ctl kinds` lists for them, from the doc comments), and the checked laws they make (force-display and
//! slave-tracking for force-position; position-error-master, with the same slave half, for
//! position-error).

use penelope_rt_core::teleop::{
    ForceDisplay, ForceDisplayConfig, FourChannelConfig, FourChannelMaster, FourChannelSlave,
    FourChannelSlaveConfig, ImpedanceConfig, PassivityForm, PositionErrorMaster, SlaveTracking,
    TrackingConfig, TrackingOutput, TwoPortConfig,
};

use super::config::KindConfig;
use super::teleop_passivity::PortLaw;
use crate::objects::error::ObjectError;

crate::objects::config::loop_keys!(ForceDisplayToml {
    max_force: f64 = ForceDisplayConfig::default().max_force, #[doc = "The largest displayed force, N (the robot's role caps it too)."]
    max_torque: f64 = ForceDisplayConfig::default().max_torque, #[doc = "The largest displayed moment, N·m."]
    damping: [f64; 6] = ForceDisplayConfig::default().damping, #[doc = "Added damping on the tool twist, N·s/m then N·m·s/rad."]
    force_deadband: f64 = ForceDisplayConfig::default().force_deadband, #[doc = "Smaller forces (sensor noise) are not displayed, N."]
    torque_deadband: f64 = ForceDisplayConfig::default().torque_deadband, #[doc = "Moments below this are not displayed, N·m."]
    filter_cutoff_hz: f64 = ForceDisplayConfig::default().filter_cutoff_hz, #[doc = "Low-pass on the displayed wrench, Hz (0: none)."]
    gravity_compensation: bool = true, #[doc = "Add g(q)."]
    passivity: String = "off".into(), #[doc = "The channel's two-port passivity controller at the master port, `off` or `impedance`: time-domain passivity, the two-port delayed form: the channel's end damps the displayed force by exactly the energy the master port would give out beyond what the slave put in (at most 200 N·s/m). With `admittance` on the slave half: passive under any delay. The observer always runs: telemetry's `channel_energy`."]
});

impl KindConfig for ForceDisplayToml {}

crate::objects::config::loop_keys!(PositionErrorToml {
    stiffness: [f64; 6] = ImpedanceConfig::master().stiffness, #[doc = "Spring to the mapped slave pose, N/m then N·m/rad (the slave half follows the master stiffly: in contact this spring is what the operator feels of the wall, capped by max_force)."]
    damping: [f64; 6] = ImpedanceConfig::master().damping, #[doc = "N·s/m then N·m·s/rad."]
    max_force: f64 = ImpedanceConfig::master().max_force, #[doc = "Force cap, N."]
    max_torque: f64 = ImpedanceConfig::master().max_torque, #[doc = "Moment cap, N·m."]
    gravity_compensation: bool = true, #[doc = "Add g(q)."]
});

impl KindConfig for PositionErrorToml {}

crate::objects::config::loop_keys!(FourChannelToml {
    c2: f64 = 1.0, #[doc = "C2, the force channel: the slave's sensed wrench x the channel's force gain."]
    c4: f64 = 0.0, #[doc = "C4, the position channel: the spring-damper to the slave's mapped pose."]
    c6: f64 = 0.0, #[doc = "C6: the operator's wrench on the handle, fed back (needs a handle sensor: the loop's `sensor`; without one the loop faults: zero force)."]
    damping: [f64; 6] = ForceDisplayConfig::default().damping, #[doc = "C_m: local damping on the tool twist, N·s/m then N·m·s/rad."]
    stiffness: [f64; 6] = ImpedanceConfig::master().stiffness, #[doc = "The position channel's spring, N/m then N·m/rad."]
    spring_damping: [f64; 6] = ImpedanceConfig::master().damping, #[doc = "The position channel's damper on the twist error."]
    max_force: f64 = ForceDisplayConfig::default().max_force, #[doc = "Cap on the whole wrench, N."]
    max_torque: f64 = ForceDisplayConfig::default().max_torque, #[doc = "Cap on the whole moment, N·m."]
    force_deadband: f64 = ForceDisplayConfig::default().force_deadband, #[doc = "The force channel's dead band, N."]
    torque_deadband: f64 = ForceDisplayConfig::default().torque_deadband, #[doc = "The force channel's moment dead band, N·m."]
    filter_cutoff_hz: f64 = ForceDisplayConfig::default().filter_cutoff_hz, #[doc = "The force channel's low-pass, Hz (0: none)."]
    gravity_compensation: bool = true, #[doc = "Add g(q)."]
});

impl KindConfig for FourChannelToml {}

crate::objects::config::loop_keys!(FourChannelSlaveToml {
    c1: f64 = 1.0, #[doc = "C1, the position channel: the tracking's feedback gains x c1."]
    c3: f64 = 0.0, #[doc = "C3: the operator's wrench on the handle, sent by the master when its loop reads a handle sensor (a `sensor` on the master's controller), divided by the channel's force gain; without it the loop faults (it holds). Pushing a wall with c1 = 0 the wall gets c3 / (1 + c5) of the operator's push."]
    c5: f64 = 0.0, #[doc = "C5: the slave's own contact (its `sensor`), fed back locally; above -1."]
    kp: [f64; 6] = TrackingConfig::default().kp, #[doc = "Position gain per joint, 1/s²."]
    kd: [f64; 6] = TrackingConfig::default().kd, #[doc = "Velocity gain per joint, 1/s."]
    ki: [f64; 6] = TrackingConfig::default().ki, #[doc = "Integral gain per joint, 1/s³."]
    max_force: f64 = FourChannelSlaveConfig::default().max_force, #[doc = "Cap on c3 F_hand + c5 F_contact, N."]
    max_torque: f64 = FourChannelSlaveConfig::default().max_torque, #[doc = "Cap on the force channels' moment, N·m."]
    passivity: String = "off".into(), #[doc = "The channel's two-port passivity controller at the slave port, `off` or `admittance`, as slave-tracking's."]
});

impl KindConfig for FourChannelSlaveToml {}

crate::objects::config::loop_keys!(SlaveTrackingToml {
    kp: [f64; 6] = TrackingConfig::default().kp, #[doc = "Computed-torque position gain per joint, 1/s² ((80 rad/s)²)."]
    kd: [f64; 6] = TrackingConfig::default().kd, #[doc = "Velocity gain per joint, 1/s (critically damped)."]
    ki: [f64; 6] = TrackingConfig::default().ki, #[doc = "Integral gain per joint, 1/s³."]
    passivity: String = "off".into(), #[doc = "The channel's two-port passivity controller at the slave port, `off` or `admittance`: time-domain passivity, the two-port delayed form: the channel's end slows the reference motion by exactly the energy the slave port would give out (into the contact) beyond what the master put in; the slave then stops short of the master's pose (drift). Needs a force-display master (its energy counters)."]
});

impl KindConfig for SlaveTrackingToml {}

fn bad_law(kind: &str, e: impl std::fmt::Debug) -> ObjectError {
    ObjectError::BadConfig {
        kind: kind.into(),
        message: format!("{e:?}"),
    }
}

impl ForceDisplayToml {
    /// The law, checked.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn law(&self, kind: &str) -> Result<ForceDisplay, ObjectError> {
        self.port_law(kind)?;
        ForceDisplay::new(ForceDisplayConfig {
            max_force: self.max_force,
            max_torque: self.max_torque,
            damping: self.damping,
            force_deadband: self.force_deadband,
            torque_deadband: self.torque_deadband,
            filter_cutoff_hz: self.filter_cutoff_hz,
            gravity_compensation: self.gravity_compensation,
        })
        .map_err(|e| bad_law(kind, e))
    }

    /// What the channel's master end runs for this half: the two-port observer, with the
    /// impedance-form controller when `passivity` asks for it.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] for another word.
    pub fn port_law(&self, kind: &str) -> Result<PortLaw, ObjectError> {
        two_port(kind, &self.passivity, PassivityForm::Impedance, "impedance")
    }
}

impl PositionErrorToml {
    /// The law, checked.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn law(&self, kind: &str) -> Result<PositionErrorMaster, ObjectError> {
        PositionErrorMaster::new(ImpedanceConfig {
            stiffness: self.stiffness,
            damping: self.damping,
            max_force: self.max_force,
            max_torque: self.max_torque,
            gravity_compensation: self.gravity_compensation,
            ..ImpedanceConfig::master()
        })
        .map_err(|e| bad_law(kind, e))
    }
}

impl FourChannelToml {
    /// The law, checked.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn law(&self, kind: &str) -> Result<FourChannelMaster, ObjectError> {
        FourChannelMaster::new(FourChannelConfig {
            c2: self.c2,
            c4: self.c4,
            c6: self.c6,
            display: ForceDisplayConfig {
                max_force: self.max_force,
                max_torque: self.max_torque,
                damping: self.damping,
                force_deadband: self.force_deadband,
                torque_deadband: self.torque_deadband,
                filter_cutoff_hz: self.filter_cutoff_hz,
                gravity_compensation: self.gravity_compensation,
            },
            spring: ImpedanceConfig {
                stiffness: self.stiffness,
                damping: self.spring_damping,
                ..ImpedanceConfig::master()
            },
            sensor_mount: None,
        })
        .map_err(|e| bad_law(kind, e))
    }
}

impl FourChannelSlaveToml {
    /// The law, checked (its sensor mount is set when a loop runs it).
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn law(&self, kind: &str) -> Result<FourChannelSlave, ObjectError> {
        self.port_law(kind)?;
        FourChannelSlave::new(FourChannelSlaveConfig {
            c1: self.c1,
            c3: self.c3,
            c5: self.c5,
            tracking: TrackingConfig {
                kp: self.kp,
                kd: self.kd,
                ki: self.ki,
                ..TrackingConfig::default()
            },
            max_force: self.max_force,
            max_torque: self.max_torque,
            sensor_mount: None,
        })
        .map_err(|e| bad_law(kind, e))
    }

    /// What the channel's slave end runs for this half, as for slave-tracking.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] for another word.
    pub fn port_law(&self, kind: &str) -> Result<PortLaw, ObjectError> {
        slave_port_law(kind, &self.passivity)
    }
}

impl SlaveTrackingToml {
    /// The law, checked: torques (`board_servo` false) or position targets for a board's own
    /// servo.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn law(&self, kind: &str, board_servo: bool) -> Result<SlaveTracking, ObjectError> {
        self.port_law(kind)?;
        SlaveTracking::new(TrackingConfig {
            kp: self.kp,
            kd: self.kd,
            ki: self.ki,
            output: if board_servo {
                TrackingOutput::BoardServo
            } else {
                TrackingOutput::Torque
            },
            ..TrackingConfig::default()
        })
        .map_err(|e| bad_law(kind, e))
    }

    /// What the channel's slave end runs for this half: the two-port observer, with the
    /// admittance-form controller when `passivity` asks for it.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] for another word.
    pub fn port_law(&self, kind: &str) -> Result<PortLaw, ObjectError> {
        slave_port_law(kind, &self.passivity)
    }
}

/// The energy each port of the channel may give out beyond what it received before its
/// passivity controller acts, J. Acting on every sign of deficit damps the sensor's noise at zero
/// delay (tracking 0.25 mm against 0.17 mm for the plain law, display 2.7 % off against 2.5 %);
/// 10 mJ leaves the zero-delay task as the plain law runs it and changes nothing from 50 ms up
/// (`penelope experiment delay`, BENCHMARKS.md).
pub const TWO_PORT_INITIAL_ENERGY: f64 = 0.01;

/// A slave half's two-port observer for `passivity` = `word` (`off` or `admittance`).
fn slave_port_law(kind: &str, word: &str) -> Result<PortLaw, ObjectError> {
    two_port(kind, word, PassivityForm::Admittance, "admittance")
}

/// The two-port observer for `word`: `off`, or `on` (the one form the port's causality allows).
fn two_port(kind: &str, word: &str, form: PassivityForm, on: &str) -> Result<PortLaw, ObjectError> {
    let form = match word {
        "off" => PassivityForm::Off,
        w if w == on => form,
        other => {
            return Err(bad_law(
                kind,
                format!("`passivity` = {other:?}: \"off\" or \"{on}\" (the port's causality)"),
            ));
        }
    };
    Ok(PortLaw::TwoPort(TwoPortConfig {
        form,
        initial_energy: TWO_PORT_INITIAL_ENERGY,
        ..TwoPortConfig::default()
    }))
}
