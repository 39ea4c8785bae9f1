//! The position-forward slave: Cartesian reference -> inverse kinematics -> computed torque.

use nalgebra::Vector6;
use penelope_hal::{
    ControlInput, Controller, ControllerError, JointCommand, JointState, JointVector,
    KinematicsError, MAX_JOINTS, Pose, Reference, RobotModel, Timestamp,
};

use super::passivity::PassivityObserver;
use super::{TeleopConfigError, check_gain, check_gains, effort, lowpass_gain, twist_in_base};

/// What [`SlaveTracking`] commands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TrackingOutput {
    /// Joint torques by computed torque (`JointCommand::Effort`).
    #[default]
    Torque,
    /// The inverse-kinematics joint reference as position targets (`JointCommand::Position`):
    /// the board's servo closes the loop.
    BoardServo,
}

/// Settings of a [`SlaveTracking`] controller. Gains are per joint, in acceleration units
/// (computed torque multiplies them by the inertia matrix).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackingConfig {
    /// Position gain, 1/s² (`omega_n²`).
    pub kp: [f64; 6],
    /// Velocity gain, 1/s (`2 zeta omega_n`).
    pub kd: [f64; 6],
    /// Integral gain, 1/s³ (0: no integral action).
    pub ki: [f64; 6],
    /// Bound on each joint's integrated error, rad·s.
    pub integral_limit: f64,
    /// Damping of the damped least-squares Jacobian inverse that turns the reference twist into
    /// joint velocities (m; larger is smoother near singularities, less exact away from them).
    pub dls_lambda: f64,
    /// Corner of the low-pass on the differentiated joint velocity reference that makes the
    /// acceleration feed-forward of a Cartesian reference, Hz (0: no acceleration feed-forward).
    /// A joint reference's own acceleration is used as is.
    pub acceleration_cutoff_hz: f64,
    /// Fraction (`0..=1`) of the model's friction at the reference velocity that is fed forward.
    pub friction_compensation: f64,
    /// Below this reference speed, rad/s, the friction feed-forward fades linearly to zero, so
    /// the Coulomb term does not chatter around rest.
    pub friction_velocity_band: f64,
    /// On an inverse-kinematics failure (unreachable pose, joint limits, branch jump) keep the
    /// last reachable joint reference at rest and count the failure; `false`: return
    /// [`ControllerError::Kinematics`] and let the loop fall back.
    pub hold_on_ik_failure: bool,
    /// A new IK solution further than this from the previous one in any joint, rad, is taken as a
    /// branch jump (near a singularity) and refused.
    pub max_ik_step: f64,
    /// What the controller sends: joint torques (computed torque, the default) or the joint
    /// reference as position targets for the board's own servo loop (for a board whose link is
    /// too slow to close a torque loop over it, such as a Galil DMC on a serial line).
    pub output: TrackingOutput,
}

impl Default for TrackingConfig {
    /// `omega_n` = 80 rad/s critically damped (kp 6400, kd 160), ki 0 (integral limit
    /// 0.01 rad·s), DLS lambda 0.01, 40 Hz acceleration filter, full friction feed-forward faded
    /// below 0.02 rad/s, hold on IK failure, 0.2 rad largest IK step.
    fn default() -> Self {
        TrackingConfig {
            kp: [6400.0; 6],
            kd: [160.0; 6],
            ki: [0.0; 6],
            integral_limit: 0.01,
            dls_lambda: 0.01,
            acceleration_cutoff_hz: 40.0,
            friction_compensation: 1.0,
            friction_velocity_band: 0.02,
            hold_on_ik_failure: true,
            max_ik_step: 0.2,
            output: TrackingOutput::Torque,
        }
    }
}

impl TrackingConfig {
    /// Checks the values.
    ///
    /// # Errors
    /// [`TeleopConfigError`] for negative or non-finite values, or a friction fraction above 1.
    pub fn validate(&self) -> Result<(), TeleopConfigError> {
        check_gains(&self.kp, "kp")?;
        check_gains(&self.kd, "kd")?;
        check_gains(&self.ki, "ki")?;
        check_gain(self.integral_limit, "integral_limit")?;
        check_gain(self.dls_lambda, "dls_lambda")?;
        check_gain(self.acceleration_cutoff_hz, "acceleration_cutoff_hz")?;
        check_gain(self.friction_compensation, "friction_compensation")?;
        if self.friction_compensation > 1.0 {
            return Err(TeleopConfigError::OutOfRange {
                parameter: "friction_compensation",
            });
        }
        check_gain(self.friction_velocity_band, "friction_velocity_band")?;
        check_gain(self.max_ik_step, "max_ik_step")
    }
}

/// The slave half of position-forward teleoperation (a PUMA following the master).
///
/// Each tick:
/// 1. `q_ref = inverse_near(pose_ref, seed)` with the previous `q_ref` as seed (branch
///    continuity; the model picks the `2 pi` equivalent inside the joint limits), skipped when
///    the pose has not changed;
/// 2. `qd_ref = J_dls^+(q_ref) twist_ref` (damped least squares, base frame);
/// 3. `qdd_ref`: the low-passed derivative of `qd_ref`;
/// 4. computed torque `tau = M(q) (qdd_ref + Kp e + Kd ed + Ki int e) + h(q, qd) - f_c(qd_ref)`
///    with `e = q_ref - q`, `ed = qd_ref - qd`, `h` the model's inverse dynamics at zero
///    acceleration (gravity, Coriolis, centrifugal) and `f_c` the fed-forward friction;
/// 5. each torque clipped to the model's `effort_max` (the integrator is held on clipped joints).
///
/// Also follows `Reference::Joint` directly (steps 1-3 skipped) and the motion part of a
/// `Reference::Hybrid`.
///
/// # Real-time
/// `activate` and `update`: no allocation, no blocking; bounded time if the model's
/// `inverse_near` is (closed form, or iterations capped, as hal requires). No panics.
#[derive(Clone, Copy, Debug)]
pub struct SlaveTracking {
    config: TrackingConfig,
    q_ref: JointVector,
    qd_ref_prev: Option<JointVector>,
    qdd_ff: JointVector,
    integral: JointVector,
    last_pose: Option<Pose>,
    ik_failures: u64,
    last_error: JointVector,
    /// Energy into the law through its feedback torque (the joints push `-tau_fb` at `qd`).
    port: PassivityObserver,
}

impl SlaveTracking {
    /// A controller with these settings.
    ///
    /// # Errors
    /// As [`TrackingConfig::validate`].
    pub fn new(config: TrackingConfig) -> Result<Self, TeleopConfigError> {
        config.validate()?;
        Ok(SlaveTracking {
            config,
            q_ref: JointVector::zeros(),
            qd_ref_prev: None,
            qdd_ff: JointVector::zeros(),
            integral: JointVector::zeros(),
            last_pose: None,
            ik_failures: 0,
            last_error: JointVector::zeros(),
            port: PassivityObserver::new(),
        })
    }

    /// The settings.
    pub fn config(&self) -> &TrackingConfig {
        &self.config
    }

    /// New settings while running: the joint reference, its filters and the integral keep
    /// their state, so nothing jumps but the gains.
    ///
    /// # Errors
    /// As [`TrackingConfig::validate`]; the old settings stay.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn set_config(&mut self, config: TrackingConfig) -> Result<(), TeleopConfigError> {
        config.validate()?;
        self.config = config;
        Ok(())
    }

    /// The joint reference of the last tick, rad.
    pub fn joint_reference(&self) -> &JointVector {
        &self.q_ref
    }

    /// The joint tracking error `q_ref - q` of the last tick, rad.
    pub fn joint_error(&self) -> &JointVector {
        &self.last_error
    }

    /// The energy observer of the slave port: energy into the law through its feedback torque
    /// (the joints push `-tau_fb` at `qd`), J. Negative while the law drives the slave with
    /// energy that came from the master: compare with the master's input (the two-port form,
    /// [`TwoPortObserver`](super::TwoPortObserver)) to judge passivity.
    pub fn passivity(&self) -> &PassivityObserver {
        &self.port
    }

    /// How many ticks the inverse kinematics failed and the reference was held, since
    /// activation.
    pub fn ik_failures(&self) -> u64 {
        self.ik_failures
    }

    /// The joint reference (position, velocity, and acceleration when given) for `reference`:
    /// a joint reference as it is, a Cartesian or hybrid motion through IK and the damped
    /// Jacobian inverse.
    fn reference_in_joints(
        &mut self,
        model: &dyn RobotModel,
        reference: &Reference,
    ) -> Result<(JointVector, JointVector, Option<JointVector>), ControllerError> {
        let c = match reference {
            Reference::Joint(j) => return Ok((j.position, j.velocity, Some(j.acceleration))),
            Reference::Cartesian(c) => c,
            Reference::Hybrid(h) => &h.motion,
            Reference::Wrench(_) => return Err(ControllerError::UnsupportedReference),
        };
        let (q_ref, moving) = self.solve(model, &c.pose)?;
        let twist =
            twist_in_base(&c.twist, &c.pose).ok_or(ControllerError::UnsupportedReference)?;
        let qd_ref = if moving {
            model.jacobian_damped_inverse(&q_ref, self.config.dls_lambda) * twist
        } else {
            JointVector::zeros()
        };
        Ok((q_ref, qd_ref, None))
    }

    /// The acceleration feed-forward when the reference gives none: the reference velocity's
    /// change, low-pass filtered (zero without a cutoff).
    #[inline]
    fn filtered_acceleration(&mut self, qd_ref: &JointVector, dt: f64) -> JointVector {
        if self.config.acceleration_cutoff_hz > 0.0 && dt > 0.0 {
            if let Some(prev) = self.qd_ref_prev {
                let raw = (qd_ref - prev) / dt;
                self.qdd_ff +=
                    (raw - self.qdd_ff) * lowpass_gain(self.config.acceleration_cutoff_hz, dt);
            }
        } else {
            self.qdd_ff = JointVector::zeros();
        }
        self.qdd_ff
    }

    /// Feeds the opposite of the model's friction at `qd_ref` forward into `tau`, faded in over
    /// the velocity band.
    #[inline]
    fn add_friction_feed_forward(
        &self,
        model: &dyn RobotModel,
        qd_ref: &JointVector,
        n: usize,
        tau: &mut JointVector,
    ) {
        if self.config.friction_compensation > 0.0 {
            let fr = model.friction(qd_ref);
            for j in 0..n {
                let band = self.config.friction_velocity_band;
                let fade = if band > 0.0 {
                    (qd_ref[j].abs() / band).min(1.0)
                } else {
                    1.0
                };
                // The model's friction opposes motion; feed its opposite forward.
                tau[j] -= self.config.friction_compensation * fade * fr[j];
            }
        }
    }

    /// Clamps `tau` to the effort limits (zero past the `n` joints); the integrator takes the
    /// new `integral` only on joints that are not saturated (anti-windup).
    #[inline]
    fn limit_effort(
        &mut self,
        model: &dyn RobotModel,
        n: usize,
        integral: &JointVector,
        tau: &mut JointVector,
    ) {
        let max = &model.limits().effort_max;
        for j in 0..MAX_JOINTS {
            if j >= n {
                tau[j] = 0.0;
                continue;
            }
            let m = max[j];
            if m.is_finite() && tau[j].abs() > m {
                tau[j] = tau[j].clamp(-m, m);
            } else {
                self.integral[j] = integral[j];
            }
        }
    }

    /// The joint reference for a Cartesian pose: IK from the previous solution.
    fn solve(
        &mut self,
        model: &dyn RobotModel,
        pose: &Pose,
    ) -> Result<(JointVector, bool), ControllerError> {
        if self.last_pose.as_ref() == Some(pose) {
            return Ok((self.q_ref, true));
        }
        let n = model.joint_count().min(MAX_JOINTS);
        let solved = model.inverse_near(pose, &self.q_ref).and_then(|q| {
            let jump = (0..n).any(|j| (q[j] - self.q_ref[j]).abs() > self.config.max_ik_step);
            if jump || !q.iter().all(|x| x.is_finite()) {
                Err(KinematicsError::Singular)
            } else {
                Ok(q)
            }
        });
        match solved {
            Ok(q) => {
                self.last_pose = Some(*pose);
                Ok((q, true))
            }
            Err(_) if self.config.hold_on_ik_failure => {
                self.ik_failures += 1;
                Ok((self.q_ref, false))
            }
            Err(e) => Err(ControllerError::Kinematics(e)),
        }
    }
}

impl Controller for SlaveTracking {
    fn kind(&self) -> &'static str {
        "slave-tracking"
    }

    /// Takes the measured position as the joint reference (and IK seed), clears the integrator,
    /// the acceleration filter and the failure count.
    fn activate(&mut self, _now: Timestamp, measured: &JointState, _model: &dyn RobotModel) {
        self.q_ref = if measured.position.iter().all(|x| x.is_finite()) {
            measured.position
        } else {
            JointVector::zeros()
        };
        self.qd_ref_prev = None;
        self.qdd_ff = JointVector::zeros();
        self.integral = JointVector::zeros();
        self.last_pose = None;
        self.ik_failures = 0;
        self.last_error = JointVector::zeros();
        self.port.reset();
    }

    fn port_energy(&self) -> Option<f64> {
        Some(self.port.energy())
    }

    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        if !input.state.is_finite() {
            return Err(ControllerError::NonFinite);
        }
        let model = input.model;
        let n = model.joint_count().min(MAX_JOINTS);
        let dt = input.period.as_secs_f64();
        let (q_ref, qd_ref, qdd_given) = self.reference_in_joints(model, input.reference)?;
        if self.config.output == TrackingOutput::BoardServo {
            // The board's servo closes the loop: the joint reference is the command. Keep it as
            // the next IK seed, as the torque path does.
            self.q_ref = q_ref;
            return Ok(JointCommand::Position(q_ref));
        }
        let qdd_ref = match qdd_given {
            Some(a) => a,
            None => self.filtered_acceleration(&qd_ref, dt),
        };
        self.qd_ref_prev = Some(qd_ref);
        self.q_ref = q_ref;

        let q = &input.state.position;
        let qd = &input.state.velocity;
        let mut e = q_ref - q;
        let mut ed = qd_ref - qd;
        for j in n..MAX_JOINTS {
            e[j] = 0.0;
            ed[j] = 0.0;
        }
        self.last_error = e;
        let kp = Vector6::from(self.config.kp);
        let kd = Vector6::from(self.config.kd);
        let ki = Vector6::from(self.config.ki);
        let lim = self.config.integral_limit;
        let integral = (self.integral + e * dt).map(|x| x.clamp(-lim, lim));
        let feedback = kp.component_mul(&e) + kd.component_mul(&ed) + ki.component_mul(&integral);
        let inertia = model.inertia(q);
        let mut tau =
            inertia * (qdd_ref + feedback) + model.inverse_dynamics(q, qd, &JointVector::zeros());
        // The port: the feedback torque is the coupling between the (delayed) reference and the
        // slave; the joints push it with -tau_fb. The model terms only cancel the arm's own
        // dynamics and are left out.
        self.port
            .observe_scalar(dt, -(inertia * feedback).dot(qd), 1.0);
        self.add_friction_feed_forward(model, &qd_ref, n, &mut tau);
        self.limit_effort(model, n, &integral, &mut tau);
        effort(tau)
    }
}
