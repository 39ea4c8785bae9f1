//! The wave-variable law as objects: `controller/wave-master` and `controller/wave-slave`.
//!
//! The wave transforms ([`WaveMaster`], [`WaveSlave`], rt-core) run in each side's
//! communication thread, where the samples cross: the waves are what travels
//! ([`PortPayload::wave`](penelope_rt_core::teleop::PortPayload)), so the line between the two
//! transforms is passive whatever delay, loss, duplication or reordering it suffers (rt-core's
//! `teleop::wave` docs give the argument). Each side's control thread runs an existing law on
//! what its transform makes:
//!
//! ```text
//!  master comm: x'_m = J qd  -> WaveMaster -> F = -F_m -> Reference::Wrench -> ForceDisplay
//!              (no dead band, no filter: both would break the port's power balance)
//!  slave comm:  F_s = -contact -> WaveSlave -> x_sd, x'_sd -> Reference::Cartesian -> SlaveTracking
//! ```
//!
//! The line is expressed in the master's base frame. The slave maps it with the channel's
//! rotation `R_ms` and scale `sigma` as a power-preserving transformer: velocity `sigma R x'`,
//! force `sigma R^T F_s` (so the channel's `force_gain` does not apply: a force gain other than
//! the scale would make the mapping itself active).
//!
//! *NOTE*: translational only: the slave holds the orientation it started with, and the
//! master's wrist gets no wave force (its rotational damping only). While the master's clutch
//! is held the line sees a master at rest and the operator feels no force.
//!
//! *NOTE*: the transforms run at the communication period, and the master's control loop holds
//! the displayed force between communication ticks: the port's power balance holds per
//! communication tick, not per control tick (a small, bounded difference at 2 ms).

use nalgebra::{UnitQuaternion, Vector3};
use penelope_hal::{
    CartesianReference, Frame, JacobianFrame, Kinematics, Pose, Reference, Timestamp, Twist, Wrench,
};
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_rt_core::teleop::{
    ForceDisplay, ForceDisplayConfig, MappingConfig, MissingWave, SlaveTracking, TrackingConfig,
    TrackingOutput, WaveConfig, WaveMaster, WaveSample, WaveSlave,
};

use super::kinematics::RobotKinematics;
use super::teleop_end::Side;
use crate::objects::error::ObjectError;

/// Seconds from `*last` to `now` (0 when there is no `last`), and `now` becomes `last`: the
/// period of a communication-thread transform's tick, as the clock measured it.
pub(crate) fn seconds_since(last: &mut Option<Timestamp>, now: Timestamp) -> f64 {
    let dt = last.map_or(0.0, |t| now.saturating_since(t).as_secs_f64());
    *last = Some(now);
    dt
}

/// The wave transform of one side, in its communication thread.
#[derive(Clone, Copy, Debug)]
pub struct WaveEnd {
    law: WaveLaw,
    rotation: UnitQuaternion<f64>,
    scale: f64,
    /// The slave's tool pose when the law started: its displacement is added to it.
    origin: Option<Pose>,
    /// The first master position heard, and the newest one's displacement from it (master
    /// frame): what the slave's drift correction follows.
    master_origin: Option<Vector3<f64>>,
    master_displacement: Option<Vector3<f64>>,
    /// The master's position when its clutch was pressed, while it is held.
    clutched_at: Option<Vector3<f64>>,
    /// The master's motion while its clutch was held, summed: taken off the position it sends,
    /// as the wave (zero velocity while clutched) takes it off the slave's motion.
    clutch_offset: Vector3<f64>,
    last_tick: Option<Timestamp>,
}

#[derive(Clone, Copy, Debug)]
enum WaveLaw {
    Master(WaveMaster),
    Slave(WaveSlave),
}

impl WaveEnd {
    /// The `side` transform with `config`, mapped by the channel's `mapping`.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] for a configuration the transform refuses.
    pub fn new(
        side: Side,
        config: WaveConfig,
        mapping: &MappingConfig,
    ) -> Result<Self, ObjectError> {
        let bad = |e| ObjectError::BadConfig {
            kind: "controller/wave".into(),
            message: format!("{e:?}"),
        };
        let law = match side {
            Side::Master => WaveLaw::Master(WaveMaster::new(config).map_err(bad)?),
            Side::Slave => WaveLaw::Slave(WaveSlave::new(config).map_err(bad)?),
        };
        Ok(WaveEnd {
            law,
            rotation: mapping.rotation,
            scale: mapping.scale,
            origin: None,
            master_origin: None,
            master_displacement: None,
            clutched_at: None,
            clutch_offset: Vector3::zeros(),
            last_tick: None,
        })
    }

    /// The master's tool `position` as it sends it beside its wave (the master's end): less the
    /// motion made while the `clutch` was held, so that it matches what the waves carried and
    /// the slave's drift correction does not undo the re-indexing.
    pub fn indexed_master_position(
        &mut self,
        position: &Vector3<f64>,
        clutch: bool,
    ) -> Vector3<f64> {
        match (clutch, self.clutched_at) {
            (true, None) => {
                self.clutched_at = Some(*position);
                position - self.clutch_offset
            }
            (true, Some(at)) => at - self.clutch_offset,
            (false, Some(at)) => {
                self.clutch_offset += position - at;
                self.clutched_at = None;
                position - self.clutch_offset
            }
            (false, None) => position - self.clutch_offset,
        }
    }

    /// Starts the line afresh (after a link loss): the transform's waves, reserves and
    /// observers, the slave's origin and the master's position origin are forgotten, so the
    /// next tick starts from where each robot is, as at the law's start.
    pub fn restart(&mut self) {
        match &mut self.law {
            WaveLaw::Master(m) => m.reset(),
            WaveLaw::Slave(s) => s.reset(),
        }
        self.origin = None;
        self.master_origin = None;
        self.master_displacement = None;
        self.clutched_at = None;
        self.clutch_offset = Vector3::zeros();
        self.last_tick = None;
    }

    /// Takes the master's tool position that came with its newest wave (the slave's end).
    pub fn hear_master(&mut self, position: &Vector3<f64>) {
        if position.iter().all(|x| x.is_finite()) {
            let origin = *self.master_origin.get_or_insert(*position);
            self.master_displacement = Some(position - origin);
        }
    }

    /// Takes the other side's wave with its sender's `sequence`.
    pub fn receive(&mut self, sequence: u64, sample: &WaveSample) {
        match &mut self.law {
            WaveLaw::Master(m) => m.receive(sequence, sample),
            WaveLaw::Slave(s) => s.receive(sequence, sample),
        }
    }

    /// Seconds since the previous tick (0 on the first).
    fn dt(&mut self, now: Timestamp) -> f64 {
        seconds_since(&mut self.last_tick, now)
    }

    /// One master tick at `now`: the loop's newest `sample` (joint velocities) gives the tool
    /// velocity; returns the wrench to display and the wave to send.
    ///
    /// # Real-time
    /// No allocation: a Jacobian and the transform's constant-time step.
    pub fn master_tick(
        &mut self,
        now: Timestamp,
        model: &RobotKinematics,
        sample: &TelemetrySample,
        clutch: bool,
    ) -> (Reference, WaveSample) {
        let dt = self.dt(now);
        let twist = model.jacobian(&sample.q, JacobianFrame::Base) * sample.qd;
        let velocity = if clutch {
            Vector3::zeros()
        } else {
            Vector3::new(twist[0], twist[1], twist[2])
        };
        let WaveLaw::Master(m) = &mut self.law else {
            return (
                Reference::Wrench(Wrench::zero(Frame::Base)),
                WaveSample::default(),
            );
        };
        let out = m.step(dt, &velocity);
        let force = if clutch {
            Vector3::zeros()
        } else {
            out.display
        };
        (
            Reference::Wrench(Wrench {
                force,
                torque: Vector3::zeros(),
                frame: Frame::Base,
            }),
            out.sample,
        )
    }

    /// One slave tick at `now` with the tool `pose` and the world's `contact` wrench on the
    /// robot (base frame): returns the pose to follow and the wave to send.
    ///
    /// # Real-time
    /// No allocation, constant time.
    pub fn slave_tick(
        &mut self,
        now: Timestamp,
        pose: &Pose,
        contact: &Wrench,
    ) -> (Reference, WaveSample) {
        let dt = self.dt(now);
        let origin = *self.origin.get_or_insert(*pose);
        // The force the slave puts on its environment, onto the line (master frame).
        let force = self.rotation.inverse() * (-contact.force) * self.scale;
        let WaveLaw::Slave(s) = &mut self.law else {
            return (cartesian(origin, Vector3::zeros()), WaveSample::default());
        };
        let out = s.step(dt, &force, self.master_displacement.as_ref());
        let mut target = origin;
        target.translation.vector += self.rotation * out.displacement * self.scale;
        (
            cartesian(target, self.rotation * out.velocity * self.scale),
            out.sample,
        )
    }

    /// The line's energy at this side, J: the wave energy the other side has sent that this
    /// side has not yet released (its receiver's reserve, summed over the axes). Never below
    /// zero: the reserve is how the wave law stays passive; the two-port observers' counterpart
    /// for `channel_energy`.
    pub fn channel_energy(&self) -> f64 {
        let receiver = match &self.law {
            WaveLaw::Master(m) => m.receiver(),
            WaveLaw::Slave(s) => s.receiver(),
        };
        (receiver.heard_energy() - receiver.used_energy()).sum()
    }

    /// The energy the side's environment (operator or contact) has put into the line, J: the
    /// master's port, or the slave's port (energy into the slave's environment counts
    /// negative).
    pub fn port_energy(&self) -> f64 {
        match &self.law {
            WaveLaw::Master(m) => m.port().energy(),
            WaveLaw::Slave(s) => -s.port().energy(),
        }
    }
}

fn cartesian(pose: Pose, velocity: Vector3<f64>) -> Reference {
    Reference::Cartesian(CartesianReference {
        pose,
        twist: Twist {
            linear: velocity,
            angular: Vector3::zeros(),
            frame: Frame::Base,
        },
    })
}

fn missing(kind: &str, word: &str) -> Result<MissingWave, ObjectError> {
    match word {
        "hold" => Ok(MissingWave::HoldWithinReserve),
        "zero" => Ok(MissingWave::Zero),
        other => Err(ObjectError::BadConfig {
            kind: kind.into(),
            message: format!(
                "`missing` = {other:?}: \"hold\" (within the energy reserve) or \"zero\""
            ),
        }),
    }
}

fn bad(kind: &str, e: impl std::fmt::Debug) -> ObjectError {
    ObjectError::BadConfig {
        kind: kind.into(),
        message: format!("{e:?}"),
    }
}

crate::objects::config::loop_keys!(WaveMasterToml {
    impedance: f64 = WaveConfig::default().impedance, #[doc = "Wave impedance b, N·s/m: the damping felt in free motion (same on both halves for transparency; any b keeps the line passive)."]
    missing: String = "hold".into(), #[doc = "A late or lost wave: `hold` (within the energy reserve) or `zero`."]
    max_force: f64 = ForceDisplayConfig::default().max_force, #[doc = "Largest displayed force, N."]
    angular_damping: [f64; 3] = [0.02; 3], #[doc = "Damping of the master's wrist (it has no wave force), N·m·s/rad."]
    gravity_compensation: bool = true, #[doc = "Add g(q)."]
});

crate::objects::config::loop_keys!(WaveSlaveToml {
    impedance: f64 = WaveConfig::default().impedance, #[doc = "Wave impedance b, N·s/m."]
    missing: String = "hold".into(), #[doc = "On a missing wave: `hold` (within the reserve) or `zero`."]
    drift_gain: f64 = WaveConfig::default().drift_gain, #[doc = "The slave closes the gap to the master's position (which travels with its wave) at this rate, 1/s; a correction that pushes on the contact is paid from the energy the matching damper dissipated, so the port stays passive (0: none)."]
    max_drift_speed: f64 = WaveConfig::default().max_drift_speed, #[doc = "The drift correction's largest speed, m/s."]
    matching: bool = true, #[doc = "Terminate the line with b: no wave reflected in free motion."]
    kp: [f64; 6] = TrackingConfig::default().kp, #[doc = "Computed-torque position gain to the wave pose, per joint, 1/s²."]
    kd: [f64; 6] = TrackingConfig::default().kd, #[doc = "Velocity gain per joint, 1/s."]
    ki: [f64; 6] = TrackingConfig::default().ki, #[doc = "Integral gain per joint, 1/s³."]
});

impl crate::objects::config::KindConfig for WaveMasterToml {}

impl crate::objects::config::KindConfig for WaveSlaveToml {}

impl WaveMasterToml {
    /// The wave transform's settings, checked.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn wave(&self, kind: &str) -> Result<WaveConfig, ObjectError> {
        let c = WaveConfig {
            impedance: self.impedance,
            missing: missing(kind, &self.missing)?,
            matching: true,
            ..WaveConfig::default()
        };
        c.validate().map_err(|e| bad(kind, e))?;
        Ok(c)
    }

    /// The display the control thread runs: no dead band, no filter, no translational damping
    /// (the wave's `b` is the damping).
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn law(&self, kind: &str) -> Result<ForceDisplay, ObjectError> {
        let [a, b, c] = self.angular_damping;
        ForceDisplay::new(ForceDisplayConfig {
            force_deadband: 0.0,
            torque_deadband: 0.0,
            damping: [0.0, 0.0, 0.0, a, b, c],
            max_force: self.max_force,
            filter_cutoff_hz: 0.0,
            gravity_compensation: self.gravity_compensation,
            ..ForceDisplayConfig::default()
        })
        .map_err(|e| bad(kind, e))
    }
}

impl WaveSlaveToml {
    /// The wave transform's settings, checked.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn wave(&self, kind: &str) -> Result<WaveConfig, ObjectError> {
        let c = WaveConfig {
            impedance: self.impedance,
            drift_gain: self.drift_gain,
            max_drift_speed: self.max_drift_speed,
            missing: missing(kind, &self.missing)?,
            matching: self.matching,
        };
        c.validate().map_err(|e| bad(kind, e))?;
        Ok(c)
    }

    /// The tracking law the control thread runs.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn law(&self, kind: &str) -> Result<SlaveTracking, ObjectError> {
        SlaveTracking::new(TrackingConfig {
            kp: self.kp,
            kd: self.kd,
            ki: self.ki,
            output: TrackingOutput::Torque,
            ..TrackingConfig::default()
        })
        .map_err(|e| bad(kind, e))
    }
}
