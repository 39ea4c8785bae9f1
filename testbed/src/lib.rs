//! A small but real simulated robot for Penelope's tests, examples and benchmarks: a decoupled
//! six-joint chain ([`DecoupledChain`], a [`RobotModel`]), a memory-like board that integrates its
//! dynamics ([`ChainBoard`]), and a sinusoidal joint trajectory ([`SineTrajectory`]).
//!
//! Each joint is a pendulum: a point mass `m` on a massless link of length `l`, turning about a
//! horizontal axis, plus rotor inertia `jm` and viscous friction `b`. Joint `i` swings in a
//! vertical plane turned `i · 60°` about the base's z axis; the tool position is the sum of the six
//! link tips. The joints do not couple:
//!
//! `(m l² + jm) q̈ + b q̇ + m g l cos q = τ`.
//!
//! The real robot models (PUMA 560/200, FRHC) live in `penelope-drivers`. This crate is a test
//! fixture in its own crate so that the real-time core's production build does not carry it;
//! `no_std`, like the core it exercises.

#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]

use core::f64::consts::PI;
use core::fmt;
use core::time::Duration;

use nalgebra::{Matrix3, Translation3, UnitQuaternion, Vector3};
use penelope_hal::robot::{IkSolution, IkSolutions, JacobianFrame, KinematicsError, check_finite};
use penelope_hal::{
    AxisCommand, AxisState, Board, Dynamics, Error, ErrorKind, InverseKinematics, Jacobian,
    JointLimits, JointReference, JointSpaceMatrix, JointVector, Kinematics, MAX_JOINTS, Pose,
    Reference, RobotModel, Timestamp, Trajectory, TrajectoryError,
};

/// Gravity, m/s².
pub const GRAVITY: f64 = 9.81;

/// The decoupled pendulum chain. See the [module docs](self).
#[derive(Clone, Debug, PartialEq)]
pub struct DecoupledChain {
    /// Tip mass per joint, kg.
    pub mass: JointVector,
    /// Link length per joint, m.
    pub length: JointVector,
    /// Rotor inertia per joint (at the joint), kg·m².
    pub rotor_inertia: JointVector,
    /// Viscous friction per joint, N·m·s/rad.
    pub damping: JointVector,
    /// The joint envelope.
    pub limits: JointLimits,
}

impl DecoupledChain {
    /// A six-joint chain with arm-like proportions: heavy, long proximal joints and light wrist
    /// joints; ±170° range, 3 rad/s, torque limits well above gravity.
    pub fn six_joint() -> Self {
        let deg = PI / 180.0;
        DecoupledChain {
            mass: JointVector::from([4.0, 3.0, 2.0, 0.5, 0.4, 0.2]),
            length: JointVector::from([0.4, 0.35, 0.3, 0.1, 0.08, 0.05]),
            rotor_inertia: JointVector::from([0.2, 0.15, 0.1, 0.01, 0.01, 0.005]),
            damping: JointVector::from([1.0, 0.8, 0.5, 0.05, 0.05, 0.02]),
            limits: JointLimits {
                position_min: JointVector::repeat(-170.0 * deg),
                position_max: JointVector::repeat(170.0 * deg),
                velocity_max: JointVector::repeat(3.0),
                effort_max: JointVector::from([60.0, 45.0, 30.0, 5.0, 4.0, 2.0]),
            },
        }
    }

    fn plane(i: usize) -> (f64, f64) {
        let phi = i as f64 * PI / 3.0;
        (libm::cos(phi), libm::sin(phi))
    }

    fn position_jacobian(&self, q: &JointVector) -> nalgebra::SMatrix<f64, 3, MAX_JOINTS> {
        let mut j = nalgebra::SMatrix::<f64, 3, MAX_JOINTS>::zeros();
        for i in 0..MAX_JOINTS {
            let (c, s) = Self::plane(i);
            let l = self.length[i];
            let (sq, cq) = (libm::sin(q[i]), libm::cos(q[i]));
            j[(0, i)] = -l * sq * c;
            j[(1, i)] = -l * sq * s;
            j[(2, i)] = l * cq;
        }
        j
    }

    fn tool_position(&self, q: &JointVector) -> Vector3<f64> {
        let mut p = Vector3::zeros();
        for i in 0..MAX_JOINTS {
            let (c, s) = Self::plane(i);
            let l = self.length[i];
            let cq = libm::cos(q[i]);
            p += Vector3::new(l * cq * c, l * cq * s, l * libm::sin(q[i]));
        }
        p
    }
}

impl Kinematics for DecoupledChain {
    fn joint_count(&self) -> usize {
        MAX_JOINTS
    }

    /// The tool's orientation is the identity (the model has no wrist geometry).
    fn forward(&self, q: &JointVector) -> Pose {
        Pose::from_parts(
            Translation3::from(self.tool_position(q)),
            UnitQuaternion::identity(),
        )
    }

    /// Linear rows only; the angular rows are zero (see [`forward`](Kinematics::forward)).
    fn jacobian(&self, q: &JointVector, _frame: JacobianFrame) -> Jacobian {
        let mut j = Jacobian::zeros();
        j.fixed_rows_mut::<3>(0)
            .copy_from(&self.position_jacobian(q));
        j
    }
}

impl InverseKinematics for DecoupledChain {
    fn inverse_all(&self, target: &Pose, out: &mut IkSolutions) -> Result<usize, KinematicsError> {
        out.clear();
        let q = self.inverse_near(target, &JointVector::zeros())?;
        let within_limits = self.limits.contains_position(&q, MAX_JOINTS);
        let _ = out.push(IkSolution {
            branch: "numerical",
            q,
            within_limits,
        });
        Ok(out.len())
    }

    /// Damped least squares on the tool position (orientation is ignored), at most 50 iterations.
    fn inverse_near(
        &self,
        target: &Pose,
        seed: &JointVector,
    ) -> Result<JointVector, KinematicsError> {
        check_finite(seed)?;
        let goal = target.translation.vector;
        if !goal.iter().all(|x| x.is_finite()) {
            return Err(KinematicsError::NonFinite);
        }
        let mut q = *seed;
        for _ in 0..50 {
            let e = goal - self.tool_position(&q);
            if e.norm() < 1e-9 {
                return Ok(q);
            }
            let j = self.position_jacobian(&q);
            let jjt = j * j.transpose() + Matrix3::identity() * 1e-4;
            let Some(inv) = jjt.try_inverse() else {
                return Err(KinematicsError::Singular);
            };
            q += j.transpose() * (inv * e);
        }
        if (goal - self.tool_position(&q)).norm() < 1e-6 {
            Ok(q)
        } else {
            Err(KinematicsError::Unreachable)
        }
    }
}

impl Dynamics for DecoupledChain {
    fn gravity(&self, q: &JointVector) -> JointVector {
        JointVector::from_fn(|i, _| self.mass[i] * GRAVITY * self.length[i] * libm::cos(q[i]))
    }

    fn inertia(&self, _q: &JointVector) -> JointSpaceMatrix {
        let d = JointVector::from_fn(|i, _| {
            self.mass[i] * self.length[i] * self.length[i] + self.rotor_inertia[i]
        });
        JointSpaceMatrix::from_diagonal(&d)
    }

    fn inverse_dynamics(
        &self,
        q: &JointVector,
        _qd: &JointVector,
        qdd: &JointVector,
    ) -> JointVector {
        self.inertia(q) * qdd + self.gravity(q)
    }

    fn friction(&self, qd: &JointVector) -> JointVector {
        -self.damping.component_mul(qd)
    }
}

impl RobotModel for DecoupledChain {
    fn limits(&self) -> &JointLimits {
        &self.limits
    }
}

/// Errors of [`ChainBoard`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChainBoardError {
    /// A command slice was shorter than the axis count, or an output slice too short.
    WrongLength,
    /// An effort command was NaN or infinite.
    NonFinite,
    /// A read failure injected with [`ChainBoard::fail_next_reads`].
    Injected,
}

impl fmt::Display for ChainBoardError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ChainBoardError::WrongLength => "slice shorter than the axis count",
            ChainBoardError::NonFinite => "effort command is NaN or infinite",
            ChainBoardError::Injected => "injected read failure",
        })
    }
}

impl Error for ChainBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            ChainBoardError::WrongLength => ErrorKind::InvalidInput,
            ChainBoardError::NonFinite => ErrorKind::NonFinite,
            ChainBoardError::Injected => ErrorKind::Communication,
        }
    }
}

/// A memory-like board driving a simulated [`DecoupledChain`]: six axes, encoder counts, a torque
/// mode and an ideal position servo. The plant integrates (semi-implicit Euler, 0.25 ms sub-steps)
/// from the previous read to `now`, holding the last command (zero-order hold). Optional seeded
/// encoder noise makes runs differ by seed while staying repeatable.
#[derive(Clone, Debug)]
pub struct ChainBoard {
    model: DecoupledChain,
    counts_per_radian: f64,
    q: JointVector,
    qd: JointVector,
    applied: JointVector,
    commands: [AxisCommand; MAX_JOINTS],
    enabled: bool,
    last: Option<Timestamp>,
    servo_kp: f64,
    servo_kd: f64,
    noise_counts: u32,
    rng: u64,
    fail_reads: u32,
}

impl ChainBoard {
    /// The longest integration sub-step.
    pub const SUBSTEP: Duration = Duration::from_micros(250);
    /// At most this many sub-steps per read (a longer gap is integrated with longer steps).
    pub const MAX_SUBSTEPS: u64 = 400;

    /// A board at rest at q = 0 with `counts_per_radian` encoder scaling on every axis.
    pub fn new(model: DecoupledChain, counts_per_radian: f64) -> Self {
        ChainBoard {
            model,
            counts_per_radian,
            q: JointVector::zeros(),
            qd: JointVector::zeros(),
            applied: JointVector::zeros(),
            commands: [AxisCommand::Off; MAX_JOINTS],
            enabled: false,
            last: None,
            servo_kp: 200.0,
            servo_kd: 20.0,
            noise_counts: 0,
            rng: 0x9E37_79B9_7F4A_7C15,
            fail_reads: 0,
        }
    }

    /// Starts the plant at rest at `q`, rad.
    pub fn with_position(mut self, q: JointVector) -> Self {
        self.q = q;
        self
    }

    /// Adds uniform encoder noise of up to `counts` counts, from a generator seeded with `seed`.
    pub fn with_noise(mut self, counts: u32, seed: u64) -> Self {
        self.noise_counts = counts;
        self.rng = seed | 1;
        self
    }

    /// The true joint positions, rad.
    pub fn true_position(&self) -> JointVector {
        self.q
    }

    /// The true joint velocities, rad/s.
    pub fn true_velocity(&self) -> JointVector {
        self.qd
    }

    /// Makes the next `n` reads fail (fault injection).
    pub fn fail_next_reads(&mut self, n: u32) {
        self.fail_reads = n;
    }

    fn next_noise(&mut self) -> i64 {
        if self.noise_counts == 0 {
            return 0;
        }
        // xorshift64*
        self.rng ^= self.rng >> 12;
        self.rng ^= self.rng << 25;
        self.rng ^= self.rng >> 27;
        let r = self.rng.wrapping_mul(0x2545_F491_4F6C_DD1D);
        let span = u64::from(self.noise_counts) * 2 + 1;
        (r % span) as i64 - i64::from(self.noise_counts)
    }

    fn advance(&mut self, now: Timestamp) {
        let Some(last) = self.last else {
            self.last = Some(now);
            return;
        };
        self.last = Some(now.max(last));
        let total = now.saturating_since(last).as_nanos() as f64 * 1e-9;
        if total <= 0.0 {
            return;
        }
        let sub = Self::SUBSTEP.as_nanos() as f64 * 1e-9;
        let steps = libm::ceil(total / sub).clamp(1.0, Self::MAX_SUBSTEPS as f64);
        let dt = total / steps;
        let inertia = self.model.inertia(&self.q).diagonal();
        for _ in 0..steps as u64 {
            let g = self.model.gravity(&self.q);
            for i in 0..MAX_JOINTS {
                let tau = if !self.enabled {
                    0.0
                } else {
                    match self.commands[i] {
                        AxisCommand::Off => 0.0,
                        AxisCommand::Effort(t) => t,
                        AxisCommand::Position(c) => {
                            let target = c as f64 / self.counts_per_radian;
                            self.servo_kp * (target - self.q[i]) - self.servo_kd * self.qd[i] + g[i]
                        }
                    }
                }
                .clamp(
                    -self.model.limits.effort_max[i],
                    self.model.limits.effort_max[i],
                );
                self.applied[i] = tau;
                let qdd = (tau - g[i] - self.model.damping[i] * self.qd[i]) / inertia[i];
                self.qd[i] += qdd * dt;
                self.q[i] += self.qd[i] * dt;
            }
        }
    }
}

impl Board for ChainBoard {
    type Error = ChainBoardError;

    fn axis_count(&self) -> usize {
        MAX_JOINTS
    }

    fn read_axes(&mut self, now: Timestamp, out: &mut [AxisState]) -> Result<(), ChainBoardError> {
        if self.fail_reads > 0 {
            self.fail_reads -= 1;
            return Err(ChainBoardError::Injected);
        }
        if out.len() < MAX_JOINTS {
            return Err(ChainBoardError::WrongLength);
        }
        self.advance(now);
        for (i, axis) in out.iter_mut().take(MAX_JOINTS).enumerate() {
            let noise = self.next_noise();
            *axis = AxisState {
                position: (libm::round(self.q[i] * self.counts_per_radian) as i64)
                    .wrapping_add(noise),
                velocity: self.qd[i] * self.counts_per_radian,
                effort: self.applied[i],
                following_error: 0,
                enabled: self.enabled,
            };
        }
        Ok(())
    }

    fn write_axes(
        &mut self,
        _now: Timestamp,
        commands: &[AxisCommand],
    ) -> Result<(), ChainBoardError> {
        if commands.len() < MAX_JOINTS {
            return Err(ChainBoardError::WrongLength);
        }
        if commands
            .iter()
            .any(|c| matches!(c, AxisCommand::Effort(t) if !t.is_finite()))
        {
            return Err(ChainBoardError::NonFinite);
        }
        self.commands.copy_from_slice(&commands[..MAX_JOINTS]);
        Ok(())
    }

    fn set_enabled(&mut self, enabled: bool) -> Result<(), ChainBoardError> {
        self.enabled = enabled;
        Ok(())
    }
}

/// A joint trajectory that starts at rest where the robot is and swings every joint:
/// `q_j(t) = q0_j + s_j a (1 - cos(2π f t))`, with `s_j = +1` for even and `-1` for odd joints.
/// Velocity and acceleration feed-forward included.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SineTrajectory {
    amplitude: f64,
    frequency: f64,
    origin: JointVector,
    start: Option<Timestamp>,
}

impl SineTrajectory {
    /// Half-swing `amplitude` rad at `frequency` Hz.
    pub fn new(amplitude: f64, frequency: f64) -> Self {
        SineTrajectory {
            amplitude,
            frequency,
            origin: JointVector::zeros(),
            start: None,
        }
    }

    /// Changes the amplitude, rad (takes effect at once; continuous only at the start of a
    /// cycle).
    pub fn set_amplitude(&mut self, amplitude: f64) {
        self.amplitude = amplitude;
    }
}

impl Trajectory for SineTrajectory {
    fn kind(&self) -> &'static str {
        "sine"
    }

    fn start(&mut self, now: Timestamp, from: &Reference) {
        self.origin = match from {
            Reference::Joint(j) => j.position,
            _ => JointVector::zeros(),
        };
        self.start = Some(now);
    }

    fn reference(&mut self, now: Timestamp) -> Result<Reference, TrajectoryError> {
        let start = self.start.ok_or(TrajectoryError::NotStarted)?;
        let t = now.saturating_since(start).as_nanos() as f64 * 1e-9;
        let w = 2.0 * PI * self.frequency;
        let (s, c) = (libm::sin(w * t), libm::cos(w * t));
        let mut r = JointReference::default();
        for j in 0..MAX_JOINTS {
            let a = if j % 2 == 0 {
                self.amplitude
            } else {
                -self.amplitude
            };
            r.position[j] = self.origin[j] + a * (1.0 - c);
            r.velocity[j] = a * w * s;
            r.acceleration[j] = a * w * w * c;
        }
        Ok(Reference::Joint(r))
    }

    fn is_finished(&self, _now: Timestamp) -> bool {
        false
    }
}

/// Joint PID gains for `model` that place every joint's closed-loop poles at `omega` rad/s with
/// damping ratio 1 (`kp = I ω²`, `kd = 2 I ω`), with gravity compensation.
pub fn critically_damped_gains(
    model: &DecoupledChain,
    omega: f64,
) -> penelope_rt_core::controller::JointPidGains {
    let inertia = model.inertia(&JointVector::zeros()).diagonal();
    penelope_rt_core::controller::JointPidGains::pd(
        inertia * (omega * omega),
        inertia * (2.0 * omega),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobian_matches_finite_differences() {
        let m = DecoupledChain::six_joint();
        let q = JointVector::from([0.3, -0.7, 1.1, 0.2, -1.5, 2.0]);
        let j = m.jacobian(&q, JacobianFrame::Base);
        for i in 0..MAX_JOINTS {
            let mut dq = JointVector::zeros();
            dq[i] = 1e-7;
            let fd = (m.tool_position(&(q + dq)) - m.tool_position(&(q - dq))) / 2e-7;
            for r in 0..3 {
                assert!((fd[r] - j[(r, i)]).abs() < 1e-6, "joint {i} row {r}");
            }
        }
    }

    #[test]
    fn gravity_is_the_gradient_of_potential_energy() {
        let m = DecoupledChain::six_joint();
        let q = JointVector::from([0.3, -0.7, 1.1, 0.2, -1.5, 2.0]);
        let potential = |q: &JointVector| {
            (0..MAX_JOINTS)
                .map(|i| m.mass[i] * GRAVITY * m.length[i] * libm::sin(q[i]))
                .sum::<f64>()
        };
        let g = m.gravity(&q);
        for i in 0..MAX_JOINTS {
            let mut dq = JointVector::zeros();
            dq[i] = 1e-6;
            let fd = (potential(&(q + dq)) - potential(&(q - dq))) / 2e-6;
            assert!((fd - g[i]).abs() < 1e-6);
        }
    }

    #[test]
    fn inverse_kinematics_reaches_forward_kinematics() {
        let m = DecoupledChain::six_joint();
        let q = JointVector::from([0.3, -0.2, 0.5, 0.1, -0.3, 0.4]);
        let target = m.forward(&q);
        let sol = m.inverse_near(&target, &(q * 0.8)).unwrap();
        assert!((m.forward(&sol).translation.vector - target.translation.vector).norm() < 1e-6);
    }

    #[test]
    fn unpowered_plant_falls_and_gravity_compensation_holds_it() {
        let m = DecoupledChain::six_joint();
        let mut b = ChainBoard::new(m.clone(), 1000.0);
        let mut axes = [AxisState::default(); MAX_JOINTS];
        b.read_axes(Timestamp::ZERO, &mut axes).unwrap();
        b.read_axes(Timestamp::from_nanos(200_000_000), &mut axes)
            .unwrap();
        assert!(
            b.true_position()[0] < -0.05,
            "should fall: {}",
            b.true_position()[0]
        );
        // Gravity torque commanded: stays put.
        let mut b = ChainBoard::new(m.clone(), 1000.0).with_position(JointVector::repeat(0.2));
        b.set_enabled(true).unwrap();
        let g = m.gravity(&JointVector::repeat(0.2));
        let cmds: [AxisCommand; 6] = core::array::from_fn(|i| AxisCommand::Effort(g[i]));
        b.read_axes(Timestamp::ZERO, &mut axes).unwrap();
        b.write_axes(Timestamp::ZERO, &cmds).unwrap();
        b.read_axes(Timestamp::from_nanos(200_000_000), &mut axes)
            .unwrap();
        assert!((b.true_position() - JointVector::repeat(0.2)).norm() < 1e-3);
        assert_eq!(
            b.write_axes(Timestamp::ZERO, &[AxisCommand::Effort(f64::NAN); 6]),
            Err(ChainBoardError::NonFinite)
        );
    }
}
