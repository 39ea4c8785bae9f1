//! Workspace mapping between master and slave, with a clutch (indexing).
//!
//! # Formulas
//!
//! With anchors `(p_m0, R_m0)` on the master and `(p_s0, R_s0)` on the slave, the rotation
//! `R_ms` from the master's base axes to the slave's base axes and the position scale `sigma`:
//!
//! ```text
//! p_s = p_s0 + sigma R_ms (p_m - p_m0)
//! R_s = R_ms (R_m R_m0^T) R_ms^T R_s0          relative rotation, expressed in the slave base, unscaled
//! v_s = sigma R_ms v_m,   omega_s = R_ms omega_m
//! inverse: p_m = p_m0 + R_ms^T (p_s - p_s0) / sigma,   R_m = R_ms^T (R_s R_s0^T) R_ms R_m0
//! f_m = k_f R_ms^T f_s,   m_m = k_t R_ms^T m_s     (slave base wrench -> master base wrench)
//! ```
//!
//! The wrench sent back is the one the *environment exerts on the slave tool*, so the operator
//! feels the wall push back; a sensor reporting the opposite (the tool on the environment) is
//! flipped with [`MappingConfig::negate_wrench`]. With `k_f = sigma` the coupling is power
//! consistent; the reference suggests `k_f` 0.2 .. 0.5 in practice.
//!
//! # Clutch
//!
//! While the clutch is held the slave reference holds where it was and the force feedback fades
//! out linearly over [`MappingConfig::clutch_fade`]; the operator repositions the master freely.
//! On release all four anchors are re-taken: the master anchor to the current master pose, the
//! slave anchor to the held slave reference, so the slave continues from where it stopped, without
//! a jump, and the force fades back in.

use core::time::Duration;

use nalgebra::UnitQuaternion;
use penelope_hal::{Frame, Pose, Timestamp, Twist, Wrench};

use super::{TeleopConfigError, check_gain};
use core::fmt;
use penelope_hal::{Error, ErrorKind};

/// How master motion maps onto the slave and slave wrenches back onto the master.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MappingConfig {
    /// Position scale `sigma`: slave displacement per master displacement (> 0; 0.5 = the slave
    /// moves half as far).
    pub scale: f64,
    /// `R_ms`: the rotation taking vectors in the master's base frame into the slave's base frame.
    pub rotation: UnitQuaternion<f64>,
    /// `k_f`: master force per slave force (>= 0).
    pub force_gain: f64,
    /// `k_t`: master moment per slave moment (>= 0).
    pub torque_gain: f64,
    /// Flip the wrench's sign: set when the sensor reports the wrench the tool exerts on the
    /// environment rather than the one the environment exerts on the tool.
    pub negate_wrench: bool,
    /// How long the force feedback takes to fade out when the clutch is pressed (and back in when
    /// it is released).
    pub clutch_fade: Duration,
}

impl Default for MappingConfig {
    /// `sigma = 1`, `R_ms = I`, `k_f = k_t = 0.3`, no sign flip, 200 ms fade.
    fn default() -> Self {
        MappingConfig {
            scale: 1.0,
            rotation: UnitQuaternion::identity(),
            force_gain: 0.3,
            torque_gain: 0.3,
            negate_wrench: false,
            clutch_fade: Duration::from_millis(200),
        }
    }
}

impl MappingConfig {
    /// Checks the values.
    ///
    /// # Errors
    /// [`TeleopConfigError`] for a scale `<= 0`, negative gains or non-finite values.
    pub fn validate(&self) -> Result<(), TeleopConfigError> {
        if !self.scale.is_finite() {
            return Err(TeleopConfigError::NonFinite { parameter: "scale" });
        }
        if self.scale <= 0.0 {
            return Err(TeleopConfigError::OutOfRange { parameter: "scale" });
        }
        if !self.rotation.coords.iter().all(|x| x.is_finite()) {
            return Err(TeleopConfigError::NonFinite {
                parameter: "rotation",
            });
        }
        check_gain(self.force_gain, "force_gain")?;
        check_gain(self.torque_gain, "torque_gain")
    }
}

/// The four anchors of the mapping, as two poses (each a position and an orientation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Anchors {
    /// `(p_m0, R_m0)`, in the master's base frame.
    pub master: Pose,
    /// `(p_s0, R_s0)`, in the slave's base frame.
    pub slave: Pose,
}

/// Why a pose could not be mapped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MappingError {
    /// No anchors yet: call [`WorkspaceMapping::anchor`] (the teleop channel does it on start).
    NotAnchored,
}

impl fmt::Display for MappingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("workspace mapping has no anchors yet")
    }
}

impl Error for MappingError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::WrongState
    }
}

/// A linear fade of the force-feedback factor between 0 and 1.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Fade {
    from: f64,
    to: f64,
    since: Timestamp,
}

impl Fade {
    fn value(&self, now: Timestamp, length: Duration) -> f64 {
        let len = length.as_secs_f64();
        if len <= 0.0 {
            return self.to;
        }
        let x = (now.saturating_since(self.since).as_secs_f64() / len).min(1.0);
        self.from + (self.to - self.from) * x
    }
}

/// The master-slave workspace mapping with clutch. See the [module docs](self) for the formulas.
///
/// # Real-time
/// Every method: no allocation, no blocking, constant time.
#[derive(Clone, Copy, Debug)]
pub struct WorkspaceMapping {
    config: MappingConfig,
    anchors: Option<Anchors>,
    /// The clutch button as last seen.
    pressed: bool,
    /// The slave reference held while the clutch is pressed.
    held: Option<Pose>,
    fade: Fade,
}

impl WorkspaceMapping {
    /// A mapping without anchors yet.
    ///
    /// # Errors
    /// As [`MappingConfig::validate`].
    pub fn new(config: MappingConfig) -> Result<Self, TeleopConfigError> {
        config.validate()?;
        Ok(WorkspaceMapping {
            config,
            anchors: None,
            pressed: false,
            held: None,
            fade: Fade {
                from: 1.0,
                to: 1.0,
                since: Timestamp::ZERO,
            },
        })
    }

    /// The configuration.
    pub fn config(&self) -> &MappingConfig {
        &self.config
    }

    /// Sets all four anchors: `master` maps onto `slave`. While the clutch is held, the slave
    /// reference then holds at `slave`.
    pub fn anchor(&mut self, master: &Pose, slave: &Pose) {
        self.anchors = Some(Anchors {
            master: *master,
            slave: *slave,
        });
        self.held = if self.pressed { Some(*slave) } else { None };
    }

    /// The anchors, once set.
    pub fn anchors(&self) -> Option<&Anchors> {
        self.anchors.as_ref()
    }

    /// True once anchored.
    pub fn is_anchored(&self) -> bool {
        self.anchors.is_some()
    }

    /// Forgets the anchors and the clutch state; the force scale returns to 1.
    pub fn reset(&mut self) {
        self.anchors = None;
        self.pressed = false;
        self.held = None;
        self.fade = Fade {
            from: 1.0,
            to: 1.0,
            since: Timestamp::ZERO,
        };
    }

    /// The slave pose a master pose maps onto (ignoring the clutch).
    ///
    /// # Errors
    /// [`MappingError::NotAnchored`].
    pub fn master_to_slave(&self, master: &Pose) -> Result<Pose, MappingError> {
        let a = self.anchors.as_ref().ok_or(MappingError::NotAnchored)?;
        let r_ms = self.config.rotation;
        let p = a.slave.translation.vector
            + r_ms * (master.translation.vector - a.master.translation.vector) * self.config.scale;
        let r = r_ms
            * (master.rotation * a.master.rotation.inverse())
            * r_ms.inverse()
            * a.slave.rotation;
        Ok(Pose::from_parts(p.into(), r))
    }

    /// The master pose that maps onto a slave pose (the inverse of
    /// [`master_to_slave`](Self::master_to_slave)): the slave seen from the master, `x_s / sigma`.
    ///
    /// # Errors
    /// [`MappingError::NotAnchored`].
    pub fn slave_to_master(&self, slave: &Pose) -> Result<Pose, MappingError> {
        let a = self.anchors.as_ref().ok_or(MappingError::NotAnchored)?;
        let r_sm = self.config.rotation.inverse();
        let p = a.master.translation.vector
            + r_sm * (slave.translation.vector - a.slave.translation.vector) / self.config.scale;
        let r = r_sm
            * (slave.rotation * a.slave.rotation.inverse())
            * self.config.rotation
            * a.master.rotation;
        Ok(Pose::from_parts(p.into(), r))
    }

    /// A master twist (base frame) as a slave twist (base frame): `sigma R_ms v`, `R_ms omega`.
    pub fn twist_to_slave(&self, t: &Twist) -> Twist {
        Twist {
            linear: self.config.rotation * t.linear * self.config.scale,
            angular: self.config.rotation * t.angular,
            frame: Frame::Base,
        }
    }

    /// A slave twist (base frame) as a master twist (base frame): `R_ms^T v / sigma`,
    /// `R_ms^T omega`.
    pub fn twist_to_master(&self, t: &Twist) -> Twist {
        let r_sm = self.config.rotation.inverse();
        Twist {
            linear: r_sm * t.linear / self.config.scale,
            angular: r_sm * t.angular,
            frame: Frame::Base,
        }
    }

    /// A slave base-frame wrench (about the tool origin) as the master base-frame wrench to
    /// display: `k_f R_ms^T f`, `k_t R_ms^T m` (sign flipped with `negate_wrench`). No clutch fade
    /// (see [`force_scale`](Self::force_scale)).
    pub fn wrench_to_master(&self, w: &Wrench) -> Wrench {
        let r_sm = self.config.rotation.inverse();
        let sign = if self.config.negate_wrench { -1.0 } else { 1.0 };
        Wrench {
            force: r_sm * w.force * (sign * self.config.force_gain),
            torque: r_sm * w.torque * (sign * self.config.torque_gain),
            frame: Frame::Base,
        }
    }

    /// A master base-frame wrench as a slave base-frame wrench: the inverse of
    /// [`wrench_to_master`](Self::wrench_to_master) (a zero gain maps to zero).
    pub fn wrench_to_slave(&self, w: &Wrench) -> Wrench {
        let inv = |g: f64| if g > 0.0 { 1.0 / g } else { 0.0 };
        let sign = if self.config.negate_wrench { -1.0 } else { 1.0 };
        Wrench {
            force: self.config.rotation * w.force * (sign * inv(self.config.force_gain)),
            torque: self.config.rotation * w.torque * (sign * inv(self.config.torque_gain)),
            frame: Frame::Base,
        }
    }

    /// One step of the clutch-aware mapping: the slave reference for master pose `master` with
    /// the clutch `clutch` held or not, at `now`.
    ///
    /// - clutch pressed (rising edge): the slave reference is held at the current mapped pose and
    ///   the force fades out;
    /// - clutch held: the held pose;
    /// - clutch released (falling edge): re-anchors (`master` onto the held pose), returns the held
    ///   pose, and the force fades back in;
    /// - otherwise: [`master_to_slave`](Self::master_to_slave).
    ///
    /// Both sides of a link can run their own mapping: fed the same master poses and clutch
    /// states, they re-anchor identically.
    ///
    /// # Errors
    /// [`MappingError::NotAnchored`].
    pub fn update(
        &mut self,
        now: Timestamp,
        master: &Pose,
        clutch: bool,
    ) -> Result<Pose, MappingError> {
        // The clutch state and the force fade are tracked even without anchors (a master that
        // only displays wrenches never anchors).
        let pressed = clutch && !self.pressed;
        let released = !clutch && self.pressed;
        self.pressed = clutch;
        if pressed {
            self.start_fade(now, 0.0);
            self.held = self.master_to_slave(master).ok();
        }
        if released {
            self.start_fade(now, 1.0);
            if let Some(held) = self.held.take() {
                self.anchor(master, &held);
                return Ok(held);
            }
        }
        match self.held {
            Some(held) if clutch => Ok(held),
            _ => self.master_to_slave(master),
        }
    }

    fn start_fade(&mut self, now: Timestamp, to: f64) {
        let from = self.fade.value(now, self.config.clutch_fade);
        self.fade = Fade {
            from,
            to,
            since: now,
        };
    }

    /// True while the clutch is held.
    pub fn is_clutched(&self) -> bool {
        self.pressed
    }

    /// The slave reference held while the clutch is pressed.
    pub fn held(&self) -> Option<&Pose> {
        self.held.as_ref()
    }

    /// The force-feedback factor at `now`, `0..=1`: 1 in normal operation, fading to 0 over
    /// `clutch_fade` while the clutch is held and back to 1 after release.
    pub fn force_scale(&self, now: Timestamp) -> f64 {
        self.fade
            .value(now, self.config.clutch_fade)
            .clamp(0.0, 1.0)
    }
}
