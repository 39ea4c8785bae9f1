//! A test-only robot model: a standard-DH serial chain with recursive Newton-Euler dynamics,
//! reflected motor inertia, viscous + Coulomb friction and a damped-Newton inverse kinematics,
//! plus a plant integrator. The PUMA 560 parameters are those of `reference/kinematics.md`.
//!
//! Compiled on its own (its sanity tests run here) and included by `teleop_controllers.rs`.
#![allow(dead_code)]

use nalgebra::{Matrix3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};
use penelope_hal::{
    Dynamics, IkSolutions, InverseKinematics, Jacobian, JacobianFrame, JointLimits,
    JointSpaceMatrix, JointState, JointVector, Kinematics, KinematicsError, MAX_JOINTS, Pose,
    RobotModel,
};

/// One link: standard DH geometry and its dynamics.
#[derive(Clone, Copy, Debug)]
pub struct Link {
    pub d: f64,
    pub a: f64,
    pub alpha: f64,
    pub offset: f64,
    /// Mass, kg.
    pub m: f64,
    /// Centre of mass in the link frame, m.
    pub r: [f64; 3],
    /// Principal inertia about the centre of mass (Ixx, Iyy, Izz), kg·m².
    pub inertia: [f64; 3],
    /// Motor inertia, kg·m², and gear ratio.
    pub jm: f64,
    pub g: f64,
    /// Viscous friction at the motor, N·m·s/rad; Coulomb friction (+, -) at the motor, N·m.
    pub b: f64,
    pub tc: [f64; 2],
}

impl Link {
    fn transform(&self, q: f64) -> Pose {
        let th = q + self.offset;
        Pose::from_parts(
            Translation3::new(self.a * th.cos(), self.a * th.sin(), self.d),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), th)
                * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), self.alpha),
        )
    }
}

/// A serial arm.
#[derive(Clone, Debug)]
pub struct DhArm {
    pub links: Vec<Link>,
    pub gravity: Vector3<f64>,
    pub limits: JointLimits,
    /// Scales every mass and inertia (a model-mismatch knob for the controller's copy).
    pub mass_scale: f64,
    /// Scales the friction (0: a controller model that knows no friction).
    pub friction_scale: f64,
}

#[allow(clippy::too_many_arguments)]
fn link(
    d: f64,
    a: f64,
    alpha: f64,
    m: f64,
    r: [f64; 3],
    inertia: [f64; 3],
    jm: f64,
    g: f64,
    b: f64,
    tc: [f64; 2],
) -> Link {
    Link {
        d,
        a,
        alpha,
        offset: 0.0,
        m,
        r,
        inertia,
        jm,
        g,
        b,
        tc,
    }
}

impl DhArm {
    /// The PUMA 560 of Corke's toolbox (kinematics.md), with torque limits.
    pub fn puma560() -> Self {
        use std::f64::consts::FRAC_PI_2 as H;
        let links = vec![
            link(
                0.67183,
                0.0,
                H,
                0.0,
                [0.0; 3],
                [0.0, 0.35, 0.0],
                200e-6,
                -62.6111,
                1.48e-3,
                [0.395, -0.435],
            ),
            link(
                0.0,
                0.4318,
                0.0,
                17.4,
                [-0.3638, 0.006, 0.2275],
                [0.13, 0.524, 0.539],
                200e-6,
                107.815,
                0.817e-3,
                [0.126, -0.071],
            ),
            link(
                0.15005,
                0.0203,
                -H,
                4.8,
                [-0.0203, -0.0141, 0.070],
                [0.066, 0.086, 0.0125],
                200e-6,
                -53.7063,
                1.38e-3,
                [0.132, -0.105],
            ),
            link(
                0.4318,
                0.0,
                H,
                0.82,
                [0.0, 0.019, 0.0],
                [1.8e-3, 1.3e-3, 1.8e-3],
                33e-6,
                76.0364,
                71.2e-6,
                [11.2e-3, -16.9e-3],
            ),
            link(
                0.0,
                0.0,
                -H,
                0.34,
                [0.0; 3],
                [0.3e-3, 0.4e-3, 0.3e-3],
                33e-6,
                71.923,
                82.6e-6,
                [9.26e-3, -14.5e-3],
            ),
            link(
                0.0,
                0.0,
                0.0,
                0.09,
                [0.0, 0.0, 0.032],
                [0.15e-3, 0.15e-3, 0.04e-3],
                33e-6,
                76.686,
                36.7e-6,
                [3.96e-3, -10.5e-3],
            ),
        ];
        let mut limits = JointLimits::unbounded();
        limits.effort_max = JointVector::from_column_slice(&[97.6, 186.4, 89.4, 24.2, 20.1, 21.3]);
        DhArm {
            links,
            gravity: Vector3::new(0.0, 0.0, -9.81),
            limits,
            mass_scale: 1.0,
            friction_scale: 1.0,
        }
    }

    /// The FRHC working model of kinematics.md (light links, invented masses), capped at the
    /// torques that hold 10 N / 0.5 N·m.
    pub fn frhc() -> Self {
        use std::f64::consts::FRAC_PI_2 as H;
        let mut links = vec![
            link(
                0.0,
                0.0,
                H,
                0.5,
                [0.0; 3],
                [2e-3, 2e-3, 2e-3],
                0.0,
                1.0,
                0.0,
                [0.0, 0.0],
            ),
            link(
                0.0,
                0.25,
                0.0,
                0.4,
                [-0.125, 0.0, 0.0],
                [1e-3, 3e-3, 3e-3],
                0.0,
                1.0,
                0.0,
                [0.0, 0.0],
            ),
            link(
                0.0,
                0.0,
                -H,
                0.2,
                [0.0; 3],
                [5e-4, 5e-4, 5e-4],
                0.0,
                1.0,
                0.0,
                [0.0, 0.0],
            ),
            link(
                0.25,
                0.0,
                H,
                0.3,
                [0.0, -0.12, 0.0],
                [2e-3, 5e-4, 2e-3],
                0.0,
                1.0,
                0.0,
                [0.0, 0.0],
            ),
            link(
                0.0,
                0.0,
                -H,
                0.05,
                [0.0; 3],
                [5e-5, 5e-5, 5e-5],
                0.0,
                1.0,
                0.0,
                [0.0, 0.0],
            ),
            link(
                0.0,
                0.0,
                0.0,
                0.05,
                [0.0, 0.0, 0.02],
                [5e-5, 5e-5, 5e-5],
                0.0,
                1.0,
                0.0,
                [0.0, 0.0],
            ),
        ];
        links[4].offset = H;
        let mut limits = JointLimits::unbounded();
        limits.effort_max = JointVector::from_column_slice(&[4.0, 4.3, 2.5, 0.5, 0.5, 0.43]);
        DhArm {
            links,
            gravity: Vector3::new(0.0, 0.0, -9.81),
            limits,
            mass_scale: 1.0,
            friction_scale: 0.0,
        }
    }

    /// A nominal, non-singular PUMA 560 pose.
    pub fn puma_nominal() -> JointVector {
        use std::f64::consts::PI;
        JointVector::from_column_slice(&[0.0, PI / 4.0, -PI, 0.0, PI / 4.0, 0.0])
    }

    /// The FRHC home pose.
    pub fn frhc_home() -> JointVector {
        use std::f64::consts::PI;
        JointVector::from_column_slice(&[0.0, PI / 3.0, 5.0 * PI / 6.0, 0.0, 0.0, 0.0])
    }

    fn n(&self) -> usize {
        self.links.len()
    }

    /// Frames 0..=n in the base frame.
    fn frames(&self, q: &JointVector) -> Vec<Pose> {
        let mut out = Vec::with_capacity(self.n() + 1);
        let mut t = Pose::identity();
        out.push(t);
        for (j, l) in self.links.iter().enumerate() {
            t *= l.transform(q[j]);
            out.push(t);
        }
        out
    }

    /// Recursive Newton-Euler (Corke's `rne_dh`), gravity `grav`, motor inertia included.
    fn rne(
        &self,
        q: &JointVector,
        qd: &JointVector,
        qdd: &JointVector,
        grav: &Vector3<f64>,
    ) -> JointVector {
        let n = self.n();
        let z0 = Vector3::z();
        let mut rots = Vec::with_capacity(n);
        let mut ps = Vec::with_capacity(n);
        for (j, l) in self.links.iter().enumerate() {
            let a = l.transform(q[j]);
            rots.push(*a.rotation.to_rotation_matrix().matrix());
            let (sa, ca) = l.alpha.sin_cos();
            ps.push(Vector3::new(l.a, l.d * sa, l.d * ca));
        }
        let mut w = Vector3::zeros();
        let mut wd = Vector3::zeros();
        let mut vd = -grav;
        let mut fm = Vec::with_capacity(n);
        let mut nm = Vec::with_capacity(n);
        for j in 0..n {
            let l = &self.links[j];
            let rt: Matrix3<f64> = rots[j].transpose();
            let p = ps[j];
            let r = Vector3::from(l.r);
            let inertia = Matrix3::from_diagonal(&Vector3::from(l.inertia)) * self.mass_scale;
            let w_new = rt * (w + z0 * qd[j]);
            let wd_new = rt * (wd + z0 * qdd[j] + w.cross(&(z0 * qd[j])));
            let vd_new = wd_new.cross(&p) + w_new.cross(&w_new.cross(&p)) + rt * vd;
            w = w_new;
            wd = wd_new;
            vd = vd_new;
            let vhat = wd.cross(&r) + w.cross(&w.cross(&r)) + vd;
            fm.push(vhat * (l.m * self.mass_scale));
            nm.push(inertia * wd + w.cross(&(inertia * w)));
        }
        let mut tau = JointVector::zeros();
        let mut f = Vector3::zeros();
        let mut nn = Vector3::zeros();
        for j in (0..n).rev() {
            let l = &self.links[j];
            let r = Vector3::from(l.r);
            let p = ps[j];
            let rnext = if j + 1 < n {
                rots[j + 1]
            } else {
                Matrix3::identity()
            };
            nn = rnext * (nn + (rnext.transpose() * p).cross(&f)) + (p + r).cross(&fm[j]) + nm[j];
            f = rnext * f + fm[j];
            tau[j] =
                nn.dot(&(rots[j].transpose() * z0)) + l.g * l.g * l.jm * qdd[j] * self.mass_scale;
        }
        tau
    }

    /// Integrates the plant `M qdd = tau + friction - h` for `dt` in `substeps` steps
    /// (semi-implicit Euler; Coulomb friction applied implicitly so joints stick at rest).
    pub fn step(&self, state: &mut JointState, tau: &JointVector, dt: f64, substeps: usize) {
        let n = self.n();
        let mut tau_c = *tau;
        for j in 0..n {
            let m = self.limits.effort_max[j];
            tau_c[j] = tau_c[j].clamp(-m, m);
        }
        let h = dt / substeps as f64;
        for _ in 0..substeps {
            let q = state.position;
            let qd = state.velocity;
            let m = self.inertia(&q);
            let bias = self.inverse_dynamics(&q, &qd, &JointVector::zeros());
            let mut viscous = JointVector::zeros();
            for j in 0..n {
                let l = &self.links[j];
                viscous[j] = -l.b * l.g * l.g * qd[j] * self.friction_scale;
            }
            let qdd = m.lu().solve(&(tau_c + viscous - bias)).unwrap_or_default();
            let mut v = qd + qdd * h;
            for j in 0..n {
                let l = &self.links[j];
                let tc = if v[j] > 0.0 { l.tc[0] } else { -l.tc[1] };
                let dv = l.g.abs() * tc * self.friction_scale * h / m[(j, j)];
                v[j] = if v[j].abs() <= dv {
                    0.0
                } else {
                    v[j] - v[j].signum() * dv
                };
            }
            state.velocity = v;
            state.position += v * h;
            state.effort = tau_c;
        }
    }

    /// Tool position, m.
    pub fn position(&self, q: &JointVector) -> Vector3<f64> {
        self.forward(q).translation.vector
    }
}

fn pose_err(target: &Pose, actual: &Pose) -> Vector6<f64> {
    let dp = target.translation.vector - actual.translation.vector;
    let dr = (target.rotation * actual.rotation.inverse()).scaled_axis();
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

impl Kinematics for DhArm {
    fn joint_count(&self) -> usize {
        self.n()
    }

    fn forward(&self, q: &JointVector) -> Pose {
        let mut t = Pose::identity();
        for (j, l) in self.links.iter().enumerate() {
            t *= l.transform(q[j]);
        }
        t
    }

    fn jacobian(&self, q: &JointVector, frame: JacobianFrame) -> Jacobian {
        let fr = self.frames(q);
        let pe = fr[self.n()].translation.vector;
        let mut jac = Jacobian::zeros();
        for j in 0..self.n() {
            let z = fr[j].rotation * Vector3::z();
            let o = fr[j].translation.vector;
            let v = z.cross(&(pe - o));
            for k in 0..3 {
                jac[(k, j)] = v[k];
                jac[(k + 3, j)] = z[k];
            }
        }
        if frame == JacobianFrame::Tool {
            let rt = fr[self.n()].rotation.inverse();
            for j in 0..self.n() {
                let v = rt * Vector3::new(jac[(0, j)], jac[(1, j)], jac[(2, j)]);
                let w = rt * Vector3::new(jac[(3, j)], jac[(4, j)], jac[(5, j)]);
                for k in 0..3 {
                    jac[(k, j)] = v[k];
                    jac[(k + 3, j)] = w[k];
                }
            }
        }
        jac
    }
}

impl InverseKinematics for DhArm {
    fn inverse_all(&self, target: &Pose, out: &mut IkSolutions) -> Result<usize, KinematicsError> {
        out.clear();
        let q = self.inverse_near(target, &JointVector::zeros())?;
        let _ = out.push(penelope_hal::IkSolution {
            branch: "numerical",
            q,
            within_limits: true,
        });
        Ok(1)
    }

    /// Damped Newton from the seed, at most 50 iterations.
    fn inverse_near(
        &self,
        target: &Pose,
        seed: &JointVector,
    ) -> Result<JointVector, KinematicsError> {
        if !target.translation.vector.iter().all(|x| x.is_finite())
            || !seed.iter().all(|x| x.is_finite())
        {
            return Err(KinematicsError::NonFinite);
        }
        let mut q = *seed;
        for _ in 0..50 {
            let e = pose_err(target, &self.forward(&q));
            if e.norm() < 1e-11 {
                return Ok(q);
            }
            let j = self.jacobian(&q, JacobianFrame::Base);
            let jjt = j * j.transpose() + Matrix6::identity() * 1e-10;
            let Some(ch) = jjt.cholesky() else {
                return Err(KinematicsError::Singular);
            };
            let mut dq = j.transpose() * ch.solve(&e);
            let big = dq.amax();
            if big > 0.5 {
                dq *= 0.5 / big;
            }
            q += dq;
        }
        Err(KinematicsError::Unreachable)
    }
}

impl Dynamics for DhArm {
    fn gravity(&self, q: &JointVector) -> JointVector {
        self.rne(
            q,
            &JointVector::zeros(),
            &JointVector::zeros(),
            &self.gravity,
        )
    }

    fn inertia(&self, q: &JointVector) -> JointSpaceMatrix {
        let mut m = JointSpaceMatrix::identity();
        let zero = JointVector::zeros();
        for k in 0..self.n() {
            let mut e = zero;
            e[k] = 1.0;
            let col = self.rne(q, &zero, &e, &Vector3::zeros());
            for r in 0..self.n() {
                m[(r, k)] = col[r];
            }
        }
        m
    }

    fn inverse_dynamics(
        &self,
        q: &JointVector,
        qd: &JointVector,
        qdd: &JointVector,
    ) -> JointVector {
        self.rne(q, qd, qdd, &self.gravity)
    }

    fn friction(&self, qd: &JointVector) -> JointVector {
        let mut f = JointVector::zeros();
        for (j, l) in self.links.iter().enumerate() {
            let coulomb = if qd[j] > 0.0 {
                l.tc[0]
            } else if qd[j] < 0.0 {
                l.tc[1]
            } else {
                0.0
            };
            f[j] = -(l.b * l.g * l.g * qd[j] + l.g.abs() * coulomb) * self.friction_scale;
        }
        f
    }
}

impl RobotModel for DhArm {
    fn limits(&self) -> &JointLimits {
        &self.limits
    }
}

const _: () = assert!(MAX_JOINTS == 6);

#[test]
fn puma_gravity_load_matches_the_toolbox() {
    // Corke's toolbox: p560.gravload(qn) = [0, 31.6399, 6.0351, 0, 0.0283, 0].
    let arm = DhArm::puma560();
    let g = arm.gravity(&DhArm::puma_nominal());
    let expected = [0.0, 31.6399, 6.0351, 0.0, 0.0283, 0.0];
    for j in 0..6 {
        assert!(
            (g[j] - expected[j]).abs() < 1e-3,
            "joint {j}: {} vs {}",
            g[j],
            expected[j]
        );
    }
}

#[test]
fn jacobian_is_the_derivative_of_forward_kinematics() {
    for arm in [DhArm::puma560(), DhArm::frhc()] {
        let q = JointVector::from_column_slice(&[0.3, 0.7, -1.2, 0.4, 0.9, -0.5]);
        let jac = arm.jacobian(&q, JacobianFrame::Base);
        let h = 1e-7;
        for j in 0..6 {
            let mut qp = q;
            qp[j] += h;
            let (a, b) = (arm.forward(&q), arm.forward(&qp));
            let v = (b.translation.vector - a.translation.vector) / h;
            let w = (b.rotation * a.rotation.inverse()).scaled_axis() / h;
            for k in 0..3 {
                assert!((jac[(k, j)] - v[k]).abs() < 1e-5);
                assert!((jac[(k + 3, j)] - w[k]).abs() < 1e-5);
            }
        }
    }
}

#[test]
fn dynamics_are_consistent() {
    let arm = DhArm::puma560();
    let q = JointVector::from_column_slice(&[0.3, 0.7, -1.2, 0.4, 0.9, -0.5]);
    let m = arm.inertia(&q);
    assert!((m - m.transpose()).norm() < 1e-9);
    assert!(m.cholesky().is_some());
    let qdd = JointVector::from_column_slice(&[1.0, -2.0, 0.5, 3.0, -1.0, 2.0]);
    let lhs = arm.inverse_dynamics(&q, &JointVector::zeros(), &qdd) - arm.gravity(&q);
    assert!((lhs - m * qdd).norm() < 1e-9);
}

#[test]
fn inverse_kinematics_round_trips() {
    let arm = DhArm::puma560();
    let q = DhArm::puma_nominal();
    let mut target_q = q;
    target_q[0] += 0.05;
    target_q[2] -= 0.04;
    target_q[4] += 0.03;
    let target = arm.forward(&target_q);
    let sol = arm.inverse_near(&target, &q).unwrap();
    assert!(pose_err(&target, &arm.forward(&sol)).norm() < 1e-10);
    assert!((sol - target_q).norm() < 1e-8);
}
