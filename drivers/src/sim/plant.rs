//! A rigid-body plant: the robot's own dynamics, integrated.

use core::time::Duration;

use penelope_hal::{
    Frame, JacobianFrame, JointState, JointVector, MAX_JOINTS, RobotModel, Timestamp, Twist, Wrench,
};

use super::Interaction;

/// Below this joint speed (rad/s), friction fades linearly to zero so that Coulomb friction does
/// not chatter around rest in a fixed-step integrator (a regularised Coulomb model).
const FRICTION_REGULARISATION_SPEED: f64 = 0.02;

/// Settings of a [`RigidBodyPlant`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantConfig {
    /// Integration sub-step. The plant advances in steps no longer than this.
    pub substep: Duration,
    /// Largest torque each motor can produce, N·m at the joint; commands beyond are clipped.
    pub motor_torque_limit: JointVector,
    /// Include the model's friction (viscous + Coulomb).
    pub friction: bool,
}

impl Default for PlantConfig {
    fn default() -> Self {
        PlantConfig {
            substep: Duration::from_micros(200),
            motor_torque_limit: JointVector::repeat(f64::INFINITY),
            friction: true,
        }
    }
}

/// The robot's physical state and what last acted on it.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PlantSnapshot {
    /// Time the state refers to.
    pub time: Timestamp,
    /// True joint positions (rad) and velocities (rad/s); effort is the applied motor torque (N·m).
    pub joints: JointState,
    /// The interaction wrench on the tool (base frame, about the tool origin), N and N·m.
    pub interaction: Wrench,
    /// The tool's twist in the base frame.
    pub tool_twist: Twist,
    /// Kinetic energy `½ qdᵀ M qd`, J.
    pub kinetic_energy: f64,
    /// Energy delivered to the robot by the interaction since the start, J: `∫ Fᵀ v dt`.
    pub interaction_work: f64,
}

/// A robot's rigid-body dynamics integrated in fixed sub-steps (semi-implicit Euler):
/// `M(q) qdd = tau_motor + Jᵀ F_interaction + tau_friction(qd) - (C(q, qd) qd + g(q))`.
///
/// The motor torque is held constant between calls (zero-order hold), as a DAC holds its output.
#[derive(Clone, Debug)]
pub struct RigidBodyPlant<M> {
    model: M,
    config: PlantConfig,
    snapshot: PlantSnapshot,
}

impl<M: RobotModel> RigidBodyPlant<M> {
    /// A plant at rest at `q0` at time `start`.
    pub fn new(model: M, config: PlantConfig, q0: JointVector, start: Timestamp) -> Self {
        let snapshot = PlantSnapshot {
            time: start,
            joints: JointState::at_rest(q0),
            interaction: Wrench::zero(Frame::Base),
            tool_twist: Twist::default(),
            kinetic_energy: 0.0,
            interaction_work: 0.0,
        };
        RigidBodyPlant {
            model,
            config,
            snapshot,
        }
    }

    /// The robot model the plant integrates.
    pub fn model(&self) -> &M {
        &self.model
    }

    /// The current physical state.
    pub fn snapshot(&self) -> &PlantSnapshot {
        &self.snapshot
    }

    /// Puts joint `j` at `position`, at rest (a brake holding it; a reset). Does nothing past
    /// the joint count.
    pub fn hold_joint(&mut self, j: usize, position: f64) {
        if j < self.model.joint_count().min(MAX_JOINTS) && position.is_finite() {
            self.snapshot.joints.position[j] = position;
            self.snapshot.joints.velocity[j] = 0.0;
        }
    }

    /// Sets the joint positions and velocities, the interaction wrench and the energies to
    /// `state` (a recorded hand moving the handle): the motor torques and the time stay.
    ///
    /// # Real-time
    /// No allocation.
    pub fn impose(&mut self, state: &super::recorded_hand::ImposedState) {
        self.snapshot.joints.position = state.position;
        self.snapshot.joints.velocity = state.velocity;
        self.snapshot.interaction = state.wrench;
        self.snapshot.kinetic_energy = state.kinetic_energy;
        self.snapshot.interaction_work = state.interaction_work;
    }

    /// Advances the plant to `now` with motor torques `tau` (N·m, clipped at the motor limits)
    /// held constant, the interaction evaluated at every sub-step. Does nothing if `now` is not
    /// later than the plant's time.
    ///
    /// # Real-time
    /// No allocation; time bounded by `(now - time) / substep` sub-steps.
    pub fn advance_to(
        &mut self,
        now: Timestamp,
        tau: &JointVector,
        interaction: &mut dyn Interaction,
    ) {
        let n = self.model.joint_count();
        let mut applied = JointVector::zeros();
        for j in 0..n {
            let limit = self.config.motor_torque_limit[j];
            applied[j] = if tau[j].is_finite() {
                tau[j].clamp(-limit, limit)
            } else {
                0.0
            };
        }
        self.snapshot.joints.effort = applied;
        while self.snapshot.time < now {
            let dt = (now - self.snapshot.time).min(self.config.substep);
            self.step(dt, &applied, interaction);
            self.snapshot.time = self.snapshot.time + dt;
        }
    }

    fn step(&mut self, dt: Duration, applied: &JointVector, interaction: &mut dyn Interaction) {
        let dt_s = dt.as_secs_f64();
        let n = self.model.joint_count();
        let q = self.snapshot.joints.position;
        let qd = self.snapshot.joints.velocity;
        let pose = self.model.forward(&q);
        let jac = self.model.jacobian(&q, JacobianFrame::Base);
        let v = jac * qd;
        let twist = Twist {
            linear: v.fixed_rows::<3>(0).into(),
            angular: v.fixed_rows::<3>(3).into(),
            frame: Frame::Base,
        };
        let wrench = interaction.wrench_on_tool(self.snapshot.time, &pose, &twist);
        let wrench = if wrench.is_finite() {
            wrench
        } else {
            Wrench::zero(Frame::Base)
        };
        let external = jac.transpose() * wrench.to_vector();
        let bias = self.model.inverse_dynamics(&q, &qd, &JointVector::zeros());
        let mut friction = JointVector::zeros();
        if self.config.friction {
            friction = self.model.friction(&qd);
            for j in 0..n {
                friction[j] *= (qd[j].abs() / FRICTION_REGULARISATION_SPEED).min(1.0);
            }
        }
        let inertia = self.model.inertia(&q);
        let net = applied + external + friction - bias;
        let qdd = match inertia.cholesky() {
            Some(ch) => ch.solve(&net),
            None => JointVector::zeros(),
        };
        let mut qd_next = qd;
        let mut q_next = q;
        for j in 0..n.min(MAX_JOINTS) {
            qd_next[j] += qdd[j] * dt_s;
            q_next[j] += qd_next[j] * dt_s;
        }
        self.snapshot.interaction_work += wrench.to_vector().dot(&v) * dt_s;
        self.snapshot.joints.position = q_next;
        self.snapshot.joints.velocity = qd_next;
        self.snapshot.interaction = wrench;
        self.snapshot.tool_twist = twist;
        self.snapshot.kinetic_energy = 0.5 * qd_next.dot(&(inertia * qd_next));
    }
}
