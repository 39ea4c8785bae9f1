//! Time-domain passivity on a running channel: the two-port observer and passivity controllers
//! of the force-position law, in each side's communication thread.
//!
//! The two-port is the channel with its delays (and everything of the law between the two
//! devices). Its master port has impedance causality (the master's velocity goes in, the force
//! to display comes out), its slave port admittance causality (the contact force goes in, the
//! motion the slave must follow comes out). So each end observes and corrects what the channel
//! hands its loop:
//!
//! ```text
//!  master comm: F_ref (channel) -> F_ref - alpha v_m / s  -> Reference (wrench) -> ForceDisplay
//!               power into the two-port: -s F_ref·v_m,   v_m = J qd (newest sample)
//!  slave comm:  x_ref (channel) -> x_ref + int(beta F)    -> Reference (pose)   -> SlaveTracking
//!               power into the two-port: F·x'_ref,       F = the contact (world on the robot)
//! ```
//!
//! Each side counts the energy that has entered the two-port at its port and sends that counter
//! with its samples ([`PortEnergy`], on the data plane or the delay line); each side may give out
//! only what the *other* side has put in (Ryu, Artigas & Preusche). The master's power is scaled
//! by `s = sigma / force_gain`, the power gain of the mapping, so that both ports count in the
//! same units (with a force gain of 0.5 the master feels half the force the slave meets: half
//! the power at the same speed). The laws allow each port an initial energy of 10 mJ before
//! its controller acts (the `E0` of the passivity inequality), so that sensor noise at zero
//! delay does not set it off.
//!
//! *NOTE*: the observers run at the communication period on what the channel hands the loops:
//! the display's dead band, damping and caps only take energy away, but its 30 Hz filter shifts
//! the displayed force by a few milliseconds against what is counted. The slave's correction
//! is a position offset that stays (the known drift of the admittance form): the slave presses
//! less deep than the master asks, never deeper.

use nalgebra::{Translation3, UnitQuaternion, Vector6};
use penelope_hal::{Dynamics, JacobianFrame, Pose, Reference, Timestamp, Wrench};
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_rt_core::teleop::{
    MappingConfig, PassivityForm, PortEnergy, TwoPortConfig, TwoPortController, pose_error,
};

use super::teleop_end::Side;
use crate::objects::error::ObjectError;

/// What a law's half runs in its channel end, besides the channel's mapping.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PortLaw {
    /// Nothing more.
    Plain,
    /// Force-position: the two-port observer, with its controller when the form is not off.
    TwoPort(TwoPortConfig),
    /// A master half whose force its own control law makes (position-error, four-channel):
    /// the two-port observer alone, with the master port's power read from what the motors
    /// do beyond gravity (`(tau - g(q))·qd`), since the channel hands the loop no force of its
    /// own. Its counters let the slave's half observe, and control in admittance form.
    Observer,
    /// The wave-variable transform.
    Wave(penelope_rt_core::teleop::WaveConfig),
}

/// The two-port observer and passivity controller of one channel end.
#[derive(Clone, Copy, Debug)]
pub struct TwoPortEnd {
    side: Side,
    controller: TwoPortController,
    /// The master's port power times this is in the slave's units (`sigma / force_gain`).
    scale: f64,
    last_tick: Option<Timestamp>,
    /// The slave's accumulated admittance correction `[dp; dr]` (m, rad; base frame).
    offset: Vector6<f64>,
    /// The slave's reference pose handed to the loop last tick.
    previous: Option<Pose>,
    /// Whether the other side's counters have been heard: until then the other half runs
    /// no observer, so this side only passes the reference on.
    heard: bool,
    /// A master port's power from the loop's joint efforts rather than the displayed wrench.
    power_from_effort: bool,
}

impl TwoPortEnd {
    /// The `side` end with `config`, for a channel mapped by `mapping`.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] for values the controller refuses, or a form that does not fit
    /// the side's causality (impedance at the master, admittance at the slave).
    pub fn new(
        side: Side,
        config: TwoPortConfig,
        mapping: &MappingConfig,
    ) -> Result<Self, ObjectError> {
        let bad = |message: String| ObjectError::BadConfig {
            kind: "trajectory/teleop".into(),
            message,
        };
        match (side, config.form) {
            (_, PassivityForm::Off)
            | (Side::Master, PassivityForm::Impedance)
            | (Side::Slave, PassivityForm::Admittance) => {}
            (Side::Master, _) => {
                return Err(bad(
                    "the master port has impedance causality: `passivity` = \"impedance\"".into(),
                ));
            }
            (Side::Slave, _) => {
                return Err(bad(
                    "the slave port has admittance causality: `passivity` = \"admittance\"".into(),
                ));
            }
        }
        let controller = TwoPortController::new(config).map_err(|e| bad(format!("{e:?}")))?;
        // Without force feedback nothing is displayed: any scale counts the same zero.
        let scale = if mapping.force_gain > 1e-6 {
            mapping.scale / mapping.force_gain
        } else {
            1.0
        };
        Ok(TwoPortEnd {
            side,
            controller,
            scale,
            last_tick: None,
            offset: Vector6::zeros(),
            previous: None,
            heard: false,
            power_from_effort: false,
        })
    }

    /// The observer alone, for a master whose own law makes its force ([`PortLaw::Observer`]):
    /// its port's power comes from the loop's joint efforts.
    ///
    /// # Errors
    /// As [`TwoPortEnd::new`].
    pub fn observer(side: Side, mapping: &MappingConfig) -> Result<Self, ObjectError> {
        let config = TwoPortConfig {
            form: PassivityForm::Off,
            ..TwoPortConfig::default()
        };
        let mut end = TwoPortEnd::new(side, config, mapping)?;
        end.power_from_effort = side == Side::Master;
        Ok(end)
    }

    /// Takes the other side's counters, if its sample carried them.
    pub fn receive(&mut self, remote: Option<&PortEnergy>) {
        if let Some(e) = remote {
            self.controller.receive(e);
            self.heard = true;
        }
    }

    /// The counters to send with this side's samples.
    pub fn counters(&self) -> PortEnergy {
        self.controller.observer().counters()
    }

    /// The two-port's energy at this port, J (what the other side put in, minus what this side
    /// gave out); `None` until the other side's counters have been heard.
    pub fn energy(&self) -> Option<f64> {
        self.heard.then(|| self.controller.observer().energy())
    }

    /// The lowest energy seen, J.
    pub fn min_energy(&self) -> f64 {
        self.controller.observer().min_energy()
    }

    /// The energy the controller has dissipated at this port, J.
    pub fn dissipated(&self) -> f64 {
        self.controller.observer().dissipated()
    }

    /// The slave's accumulated position correction, m (zero on a master).
    pub fn drift(&self) -> f64 {
        self.offset.fixed_rows::<3>(0).norm()
    }

    /// Forgets the motion history (the channel re-anchored, after the clutch or a link loss):
    /// the next tick starts the slave's accounting afresh, so nothing jumps; the counters and
    /// the offset stay.
    pub fn restart_motion(&mut self) {
        self.previous = None;
        self.last_tick = None;
    }

    /// One tick at `now` on the channel's `reference` for this side's loop: observes the port
    /// and, when the controller is on, corrects the reference. The master reads its tool twist
    /// from the loop's newest `sample`; the slave its `contact` (the world's wrench on it, base
    /// frame).
    ///
    /// # Real-time
    /// No allocation: a Jacobian and constant-time arithmetic.
    pub fn tick(
        &mut self,
        now: Timestamp,
        reference: Reference,
        model: &impl Dynamics,
        sample: &TelemetrySample,
        contact: &Wrench,
    ) -> Reference {
        let dt = super::teleop_wave::seconds_since(&mut self.last_tick, now);
        if !self.heard {
            return reference;
        }
        match self.side {
            Side::Master if self.power_from_effort => {
                // What the motors do beyond holding the arm up goes to the operator; the
                // operator puts its opposite into the two-port.
                let out = (sample.effort - model.gravity(&sample.q)).dot(&sample.qd);
                if dt > 0.0 && out.is_finite() {
                    self.controller.commit(dt, -out * self.scale, 0.0, 0.0);
                }
                reference
            }
            Side::Master => {
                let v = model.jacobian(&sample.q, JacobianFrame::Base) * sample.qd;
                self.master(dt, reference, &v)
            }
            Side::Slave => self.slave(dt, reference, &contact.to_vector()),
        }
    }

    /// The master port: the displayed wrench `F` against the tool twist `v`.
    fn master(&mut self, dt: f64, mut reference: Reference, v: &Vector6<f64>) -> Reference {
        let wrench = match &mut reference {
            Reference::Wrench(w) => w,
            Reference::Hybrid(h) => &mut h.wrench,
            _ => return reference,
        };
        if dt <= 0.0 || !v.iter().all(|x| x.is_finite()) {
            return reference;
        }
        // The operator pushes about -F into the two-port; in the slave's units.
        let into = -wrench.to_vector() * self.scale;
        let (corrected, alpha) = self.controller.correct_force(dt, &into, v);
        if alpha > 0.0 {
            // (Untouched otherwise: the observer alone changes nothing, to the last bit.)
            let shown = -corrected / self.scale;
            wrench.force = shown.fixed_rows::<3>(0).into();
            wrench.torque = shown.fixed_rows::<3>(3).into();
        }
        self.controller
            .commit(dt, corrected.dot(v), alpha, alpha * v.norm_squared());
        reference
    }

    /// The slave port: the reference motion `x'_ref` under the contact `force`.
    fn slave(&mut self, dt: f64, mut reference: Reference, force: &Vector6<f64>) -> Reference {
        let motion = match &mut reference {
            Reference::Cartesian(c) => c,
            Reference::Hybrid(h) => &mut h.motion,
            _ => return reference,
        };
        let wanted = shifted(&motion.pose, &self.offset);
        let Some(previous) = self.previous.filter(|_| dt > 0.0) else {
            motion.pose = wanted;
            self.previous = Some(wanted);
            return reference;
        };
        let velocity = pose_error(&wanted, &previous) / dt;
        if !(velocity.iter().all(|x| x.is_finite()) && force.iter().all(|x| x.is_finite())) {
            motion.pose = wanted;
            self.previous = Some(wanted);
            return reference;
        }
        let (corrected, beta) = self.controller.correct_velocity(dt, force, &velocity);
        self.offset += (corrected - velocity) * dt;
        motion.pose = shifted(&motion.pose, &self.offset);
        self.previous = Some(motion.pose);
        self.controller
            .commit(dt, force.dot(&corrected), beta, beta * force.norm_squared());
        reference
    }
}

/// `pose` moved by `offset` `[dp; dr]` in the base frame.
fn shifted(pose: &Pose, offset: &Vector6<f64>) -> Pose {
    if offset.iter().all(|x| *x == 0.0) {
        return *pose;
    }
    let dp = offset.fixed_rows::<3>(0).into_owned();
    let dr = UnitQuaternion::from_scaled_axis(offset.fixed_rows::<3>(3).into_owned());
    Pose::from_parts(
        Translation3::from(pose.translation.vector + dp),
        dr * pose.rotation,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use penelope_hal::{CartesianReference, Frame, Kinematics, Twist};

    fn at(ms: u64) -> Timestamp {
        Timestamp::from_nanos(ms * 1_000_000)
    }

    fn slave_end(form: PassivityForm) -> TwoPortEnd {
        let config = TwoPortConfig {
            form,
            ..TwoPortConfig::default()
        };
        TwoPortEnd::new(Side::Slave, config, &MappingConfig::default()).unwrap()
    }

    fn pose_at(x: f64) -> Reference {
        Reference::Cartesian(CartesianReference {
            pose: Pose::from_parts(Translation3::new(x, 0.0, 0.0), UnitQuaternion::identity()),
            twist: Twist::default(),
        })
    }

    fn x_of(r: &Reference) -> f64 {
        match r {
            Reference::Cartesian(c) => c.pose.translation.vector.x,
            _ => f64::NAN,
        }
    }

    /// The slave's reference moves into a wall that pushes back, with no energy from the
    /// master: observed, the port goes active; controlled, the correction holds the slave back
    /// so that it never gives out energy it was not given, and the reference stops short.
    #[test]
    fn the_slave_admittance_form_holds_back_what_the_master_did_not_pay_for() {
        let wall = Wrench {
            force: Vector3::new(-20.0, 0.0, 0.0),
            torque: Vector3::zeros(),
            frame: Frame::Base,
        };
        let (model, sample) = (
            penelope_drivers::model::puma560(),
            TelemetrySample::default(),
        );
        let run = |form| {
            let mut end = slave_end(form);
            end.receive(Some(&PortEnergy::default()));
            let mut last = 0.0;
            for k in 0..500u64 {
                let r = end.tick(at(2 * k), pose_at(1e-4 * k as f64), &model, &sample, &wall);
                last = x_of(&r);
            }
            (
                end.controller.observer().energy(),
                end.min_energy(),
                last,
                end.drift(),
            )
        };
        let (e_off, _, x_off, drift_off) = run(PassivityForm::Off);
        assert!(e_off < -0.9, "uncorrected: {e_off} J given out");
        assert!((x_off - 0.0499).abs() < 1e-9 && drift_off == 0.0);
        let (e_on, min_on, x_on, drift_on) = run(PassivityForm::Admittance);
        assert!(
            min_on > -1e-9 && e_on > -1e-9,
            "corrected: {e_on} J, min {min_on}"
        );
        assert!(x_on < 0.01 && drift_on > 0.04, "x {x_on}, drift {drift_on}");
    }

    /// The master displays a force while the hand moves with it (the channel gives energy out)
    /// and nothing came from the slave: the impedance form adds damping, the displayed force
    /// drops, and the port stays passive; energy received from the slave lets it through.
    #[test]
    fn the_master_impedance_form_damps_only_energy_not_received() {
        let model = penelope_drivers::model::frhc();
        let q = penelope_hal::JointVector::from([0.1, 0.4, -0.3, 0.2, 0.3, 0.1]);
        let mut sample = TelemetrySample {
            q,
            ..TelemetrySample::default()
        };
        // A joint velocity whose tool twist has an x component.
        sample.qd[0] = 0.5;
        let v = model.jacobian(&q, JacobianFrame::Base) * sample.qd;
        let push = Reference::Wrench(Wrench {
            force: Vector3::new(v[0].signum() * 2.0, 0.0, 0.0),
            torque: Vector3::zeros(),
            frame: Frame::Base,
        });
        let config = TwoPortConfig {
            form: PassivityForm::Impedance,
            ..TwoPortConfig::default()
        };
        let mapping = MappingConfig::default();
        let mut end = TwoPortEnd::new(Side::Master, config, &mapping).unwrap();
        end.receive(Some(&PortEnergy::default()));
        let mut shown = 0.0;
        for k in 0..100u64 {
            let r = end.tick(at(2 * k), push, &model, &sample, &Wrench::default());
            if let Reference::Wrench(w) = r {
                shown = w.force.x.abs();
            }
        }
        let e = end.controller.observer().energy();
        assert!(e > -1e-9, "{e}");
        assert!(shown < 2.0 && end.dissipated() > 0.0, "shown {shown}");
        // Energy from the slave lets the same force through.
        let mut paid = TwoPortEnd::new(Side::Master, config, &mapping).unwrap();
        paid.receive(Some(&PortEnergy { input: 1e3 }));
        let mut shown = 0.0;
        for k in 0..100u64 {
            if let Reference::Wrench(w) =
                paid.tick(at(2 * k), push, &model, &sample, &Wrench::default())
            {
                shown = w.force.x.abs();
            }
        }
        assert!((shown - 2.0).abs() < 1e-12 && paid.dissipated() == 0.0);
    }

    #[test]
    fn a_form_against_the_port_causality_is_refused() {
        let mapping = MappingConfig::default();
        for (side, form) in [
            (Side::Master, PassivityForm::Admittance),
            (Side::Slave, PassivityForm::Impedance),
        ] {
            let config = TwoPortConfig {
                form,
                ..TwoPortConfig::default()
            };
            assert!(matches!(
                TwoPortEnd::new(side, config, &mapping),
                Err(ObjectError::BadConfig { .. })
            ));
        }
    }
}
