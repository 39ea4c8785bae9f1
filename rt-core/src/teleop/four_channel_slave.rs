//! The slave half of Lawrence's four-channel architecture (see [`four_channel`](super::four_channel)
//! for the master half and the whole picture):
//!
//! ```text
//!  slave:   F_cs = C_1 (x_m, v_m)  + C_3 F_h  + C_5 F_e
//! ```
//!
//! In Penelope's Cartesian form ([`FourChannelSlave`]):
//!
//! - `C_1`, the position channel: the stiff tracking of the master's mapped pose by inverse
//!   kinematics and computed torque ([`SlaveTracking`]), its feedback gains times `c1` (the
//!   model's gravity, Coriolis and friction terms stay whole: `c1 = 0` leaves a gravity-balanced
//!   arm moved by the force channels alone);
//! - `C_3`, the force channel forward: the operator's wrench on the master's handle, which the
//!   master sends beside its pose when its loop reads a handle sensor (`Reference::Hybrid`), mapped
//!   into the slave base and divided by the channel's force gain, times `c3`;
//! - `C_5`, local force feedback: the environment's wrench on the slave (its wrist sensor, turned
//!   into the base frame at the tool: [`contact_in_base`]), times `c5`.
//!
//! Signs: both wrenches are what the world applies to the robot, and the slave's motors add
//! `c3 F_h + c5 F_e` at the tool. Pushing a wall with the tracking off (`c1 = 0`), the slave
//! settles where `c3 F_h + (1 + c5) F_e = 0`: the wall receives the operator's push times
//! `c3 / (1 + c5)`. `c5 = -1` would cancel the contact's effect on the arm and is refused
//! (`c5` must be above -1).
//!
//! The force terms are capped as one wrench (direction kept), added as `J^T F`, and the sum is
//! clipped to the joints' effort limits. `c1 = 1, c3 = c5 = 0` is [`SlaveTracking`] with the same
//! gains, bit for bit (a test shows it): a term whose coefficient is zero is not computed, so it
//! needs no input.
//!
//! # Real-time
//! `activate` and `update`: no allocation, no blocking, bounded time (the tracking's inverse
//! kinematics is), no panics.

use nalgebra::Vector6;
use penelope_hal::{
    ControlInput, Controller, ControllerError, Frame, JacobianFrame, JointCommand, JointState,
    MAX_JOINTS, Pose, Reference, RobotModel, Timestamp, Wrench,
};

use super::passivity::PassivityObserver;
use super::tracking::{SlaveTracking, TrackingConfig, TrackingOutput};
use super::{TeleopConfigError, bottom, cap_wrench, contact_in_base, effort, top, wrench_in_base};

/// Settings of a [`FourChannelSlave`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FourChannelSlaveConfig {
    /// `C_1`: weight of the position channel (the tracking's feedback gains).
    pub c1: f64,
    /// `C_3`: weight of the operator's wrench sent by the master.
    pub c3: f64,
    /// `C_5`: weight of the slave's own sensed contact wrench (above -1).
    pub c5: f64,
    /// The position channel: gains, IK and feed-forward of the tracking (its output must be
    /// torques when a force channel is on).
    pub tracking: TrackingConfig,
    /// Cap on the force channels' sum, force part, N.
    pub max_force: f64,
    /// Cap on the force channels' sum, moment part, N·m.
    pub max_torque: f64,
    /// Where the wrist sensor sits in the tool frame (a `Sensor`-frame reading needs it for
    /// `C_5`; the node sets it from the loop's sensor).
    pub sensor_mount: Option<Pose>,
}

impl Default for FourChannelSlaveConfig {
    /// `c1 = 1`, `c3 = c5 = 0` (the slave-tracking law), default tracking, force channels capped
    /// at 60 N and 5 N·m, no sensor mount.
    fn default() -> Self {
        FourChannelSlaveConfig {
            c1: 1.0,
            c3: 0.0,
            c5: 0.0,
            tracking: TrackingConfig::default(),
            max_force: 60.0,
            max_torque: 5.0,
            sensor_mount: None,
        }
    }
}

impl FourChannelSlaveConfig {
    /// Checks the values.
    ///
    /// # Errors
    /// [`TeleopConfigError`]: a non-finite or negative `c1`, a non-finite `c3`, `c5 <= -1`,
    /// negative caps, a force channel with position-target output, or invalid tracking.
    pub fn validate(&self) -> Result<(), TeleopConfigError> {
        super::check_gain(self.c1, "c1")?;
        if !self.c3.is_finite() {
            return Err(TeleopConfigError::NonFinite { parameter: "c3" });
        }
        if !self.c5.is_finite() {
            return Err(TeleopConfigError::NonFinite { parameter: "c5" });
        }
        if self.c5 <= -1.0 {
            return Err(TeleopConfigError::OutOfRange { parameter: "c5" });
        }
        super::check_cap(self.max_force, "max_force")?;
        super::check_cap(self.max_torque, "max_torque")?;
        if self.has_force_channel() && self.tracking.output == TrackingOutput::BoardServo {
            // A board's own position servo cannot add a wrench.
            return Err(TeleopConfigError::OutOfRange {
                parameter: "output",
            });
        }
        self.tracking.validate()
    }

    /// True when `C_3` or `C_5` is on.
    pub fn has_force_channel(&self) -> bool {
        self.c3 != 0.0 || self.c5 != 0.0
    }

    /// The tracking's settings with its feedback gains times `c1`.
    fn weighted_tracking(&self) -> TrackingConfig {
        let mut t = self.tracking;
        if self.c1 != 1.0 {
            for g in
                t.kp.iter_mut()
                    .chain(t.kd.iter_mut())
                    .chain(t.ki.iter_mut())
            {
                *g *= self.c1;
            }
        }
        t
    }
}

/// The slave half of Lawrence's four-channel architecture. See the [module docs](self).
#[derive(Clone, Copy, Debug)]
pub struct FourChannelSlave {
    config: FourChannelSlaveConfig,
    tracking: SlaveTracking,
    /// Energy into the law through the force channels (the joints push `-F` at the tool twist).
    force_port: PassivityObserver,
    last_wrench: Wrench,
}

impl FourChannelSlave {
    /// A slave with these settings.
    ///
    /// # Errors
    /// As [`FourChannelSlaveConfig::validate`].
    pub fn new(config: FourChannelSlaveConfig) -> Result<Self, TeleopConfigError> {
        config.validate()?;
        Ok(FourChannelSlave {
            config,
            tracking: SlaveTracking::new(config.weighted_tracking())?,
            force_port: PassivityObserver::new(),
            last_wrench: Wrench::zero(Frame::Base),
        })
    }

    /// The settings.
    pub fn config(&self) -> &FourChannelSlaveConfig {
        &self.config
    }

    /// New settings while running (the tracking keeps its reference, filters and integral; the
    /// sensor mount stays, it belongs to the loop's sensor).
    ///
    /// # Errors
    /// As [`FourChannelSlaveConfig::validate`]; the old settings stay.
    pub fn set_config(&mut self, config: FourChannelSlaveConfig) -> Result<(), TeleopConfigError> {
        config.validate()?;
        self.tracking.set_config(config.weighted_tracking())?;
        self.config = FourChannelSlaveConfig {
            sensor_mount: self.config.sensor_mount,
            ..config
        };
        Ok(())
    }

    /// Sets where the wrist sensor sits in the tool frame (`C_5` on a `Sensor`-frame reading).
    pub fn set_sensor_mount(&mut self, mount: Option<Pose>) {
        self.config.sensor_mount = mount;
    }

    /// The force channels' wrench added on the last tick (slave base frame, at the tool), after
    /// the cap.
    pub fn last_wrench(&self) -> &Wrench {
        &self.last_wrench
    }

    /// The position channel.
    pub fn tracking(&self) -> &SlaveTracking {
        &self.tracking
    }

    /// The force channels' wrench for this tick, before the cap.
    fn force_channels(
        &self,
        input: &ControlInput<'_>,
        tool: &Pose,
    ) -> Result<Vector6<f64>, ControllerError> {
        let c = &self.config;
        let mut f = Vector6::zeros();
        if c.c3 != 0.0 {
            let hand = match input.reference {
                Reference::Hybrid(h) => wrench_in_base(&h.wrench, tool),
                // The master sends no operator's wrench: it has no handle sensor.
                _ => None,
            }
            .ok_or(ControllerError::MissingInput)?;
            f += hand * c.c3;
        }
        if c.c5 != 0.0 {
            let contact = input
                .wrench
                .and_then(|w| contact_in_base(w, tool, c.sensor_mount.as_ref()))
                .ok_or(ControllerError::MissingInput)?;
            f += contact * c.c5;
        }
        Ok(f)
    }
}

impl Controller for FourChannelSlave {
    fn kind(&self) -> &'static str {
        "four-channel-slave"
    }

    fn port_energy(&self) -> Option<f64> {
        Some(self.tracking.passivity().energy() + self.force_port.energy())
    }

    fn activate(&mut self, now: Timestamp, measured: &JointState, model: &dyn RobotModel) {
        self.tracking.activate(now, measured, model);
        self.force_port.reset();
        self.last_wrench = Wrench::zero(Frame::Base);
    }

    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        let command = self.tracking.update(input)?;
        if !self.config.has_force_channel() {
            return Ok(command);
        }
        let JointCommand::Effort(mut tau) = command else {
            return Err(ControllerError::UnsupportedReference);
        };
        let model = input.model;
        let q = &input.state.position;
        let tool = model.forward(q);
        let (f, _) = cap_wrench(
            &self.force_channels(input, &tool)?,
            self.config.max_force,
            self.config.max_torque,
        );
        let jac = model.jacobian(q, JacobianFrame::Base);
        let v = jac * input.state.velocity;
        self.force_port
            .observe(input.period.as_secs_f64(), &(-f), &v);
        let applied = Wrench {
            force: top(&f),
            torque: bottom(&f),
            frame: Frame::Base,
        };
        tau += model
            .wrench_to_torques(q, &applied)
            .map_err(|_| ControllerError::NonFinite)?;
        let n = model.joint_count().min(MAX_JOINTS);
        let max = &model.limits().effort_max;
        for j in 0..MAX_JOINTS {
            if j >= n {
                tau[j] = 0.0;
            } else if max[j].is_finite() {
                tau[j] = tau[j].clamp(-max[j], max[j]);
            }
        }
        self.last_wrench = applied;
        effort(tau)
    }
}
