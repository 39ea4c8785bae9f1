//! Rigid-body dynamics of a serial chain (DH rows or axis joints): gravity (holding) torque, the joint-space inertia matrix by
//! the composite-rigid-body algorithm, recursive Newton-Euler inverse dynamics, and friction.
//!
//! Conventions are those of Corke's Robotics Toolbox, so numbers compare directly:
//! - gravity "load" is the torque that *holds* the arm still, `-(torque exerted by gravity)`;
//! - the inertia matrix and inverse dynamics include the reflected motor inertia `Jm G²` on each
//!   joint (on the diagonal of the inertia matrix);
//! - friction parameters are at the motor: viscous `B` and Coulomb `Tc±`, reflected to the
//!   joint as `-|G| (B |G| qd + Tc±)` (zero Coulomb at zero speed).
//!
//! All three algorithms work in the world frame on the stack.

use nalgebra::{Matrix3, Vector3};
use penelope_hal::{JointSpaceMatrix, JointVector, MAX_JOINTS};

use super::chain::SerialChain;
use super::dh::JointKind;

/// The mass properties and drive of one link.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkDynamics {
    /// Link mass, kg.
    pub mass: f64,
    /// Centre of mass in the link's own frame (the DH frame after the joint, or a URDF child
    /// link's frame), m.
    pub com: Vector3<f64>,
    /// Inertia tensor about the centre of mass, in the link frame, kg·m².
    pub inertia: Matrix3<f64>,
    /// Motor rotor inertia, kg·m² (at the motor).
    pub motor_inertia: f64,
    /// Gear ratio, motor turns per joint turn; the sign gives the direction.
    pub gear_ratio: f64,
    /// Viscous friction at the motor, N·m·s/rad.
    pub viscous: f64,
    /// Coulomb friction at the motor for positive and negative speed, N·m (the second is
    /// usually negative).
    pub coulomb: [f64; 2],
}

impl LinkDynamics {
    /// A massless link with no drive: what a kinematics-only model uses.
    pub const fn massless() -> Self {
        LinkDynamics {
            mass: 0.0,
            com: Vector3::new(0.0, 0.0, 0.0),
            inertia: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            motor_inertia: 0.0,
            gear_ratio: 1.0,
            viscous: 0.0,
            coulomb: [0.0, 0.0],
        }
    }

    /// The reflected motor inertia `Jm G²`, kg·m² at the joint.
    pub fn reflected_motor_inertia(&self) -> f64 {
        self.motor_inertia * self.gear_ratio * self.gear_ratio
    }

    /// True when every number is finite.
    pub fn is_finite(&self) -> bool {
        self.mass.is_finite()
            && self.com.iter().all(|x| x.is_finite())
            && self.inertia.iter().all(|x| x.is_finite())
            && self.motor_inertia.is_finite()
            && self.gear_ratio.is_finite()
            && self.viscous.is_finite()
            && self.coulomb.iter().all(|x| x.is_finite())
    }

    /// Friction torque at the joint (N·m) at joint speed `qd` (rad/s), opposing motion.
    pub fn friction(&self, qd: f64) -> f64 {
        let g = self.gear_ratio.abs();
        let mut tau = self.viscous * g * qd;
        if qd > 0.0 {
            tau += self.coulomb[0];
        } else if qd < 0.0 {
            tau += self.coulomb[1];
        }
        -g * tau
    }
}

/// Holding torque against gravity (`gravity` is the gravitational acceleration in the world
/// frame, m/s²): for each joint, the moment of the composite mass outboard of it.
pub(crate) fn gravity(
    chain: &SerialChain,
    links: &[LinkDynamics; MAX_JOINTS],
    gravity: &Vector3<f64>,
    q: &JointVector,
) -> JointVector {
    let f = chain.frames(q);
    let n = chain.joint_count();
    let a0 = -gravity; // the base accelerates upwards instead of gravity pulling down
    let mut tau = JointVector::zeros();
    let mut mass = 0.0;
    let mut first_moment = Vector3::zeros(); // sum of m_k c_k over the outboard links
    for j in (0..n).rev() {
        let l = &links[j];
        let c = f.p[j + 1] + f.r[j + 1] * l.com;
        mass += l.mass;
        first_moment += c * l.mass;
        let (z, o) = chain.joint_axis(&f, j);
        tau[j] = match chain.geometry(j).kind() {
            JointKind::Revolute => z.dot(&(first_moment - o * mass).cross(&a0)),
            JointKind::Prismatic => z.dot(&a0) * mass,
        };
    }
    tau
}

/// Joint-space inertia matrix by the composite-rigid-body algorithm (spatial quantities about the
/// world origin), plus `Jm G²` on the diagonal; identity on unused joints.
pub(crate) fn inertia(
    chain: &SerialChain,
    links: &[LinkDynamics; MAX_JOINTS],
    q: &JointVector,
) -> JointSpaceMatrix {
    let f = chain.frames(q);
    let n = chain.joint_count();
    let mut m = JointSpaceMatrix::identity();
    // Motion subspace of each joint: angular part and linear velocity of the point at the origin.
    let mut s_w = [Vector3::zeros(); MAX_JOINTS];
    let mut s_v = [Vector3::zeros(); MAX_JOINTS];
    for j in 0..n {
        let (z, o) = chain.joint_axis(&f, j);
        match chain.geometry(j).kind() {
            JointKind::Revolute => {
                s_w[j] = z;
                s_v[j] = o.cross(&z);
            }
            JointKind::Prismatic => s_v[j] = z,
        }
    }
    // Composite body j..n: mass, first moment h = sum m c, rotational inertia about the origin.
    let mut mass = 0.0;
    let mut h = Vector3::zeros();
    let mut jo = Matrix3::zeros();
    for j in (0..n).rev() {
        let l = &links[j];
        let r = &f.r[j + 1];
        let c = f.p[j + 1] + r * l.com;
        let ic = r * l.inertia * r.transpose();
        let cc = c.dot(&c);
        mass += l.mass;
        h += c * l.mass;
        jo += ic + (Matrix3::identity() * cc - c * c.transpose()) * l.mass;
        // Spatial force to accelerate the composite body with unit speed of joint j:
        // momentum p = m v_O - h x w, angular momentum about O: L = J_O w + h x v_O.
        let p = s_v[j] * mass - h.cross(&s_w[j]);
        let ang = jo * s_w[j] + h.cross(&s_v[j]);
        for i in 0..=j {
            let mij = s_w[i].dot(&ang) + s_v[i].dot(&p);
            m[(i, j)] = mij;
            m[(j, i)] = mij;
        }
        m[(j, j)] += l.reflected_motor_inertia();
    }
    m
}

/// Recursive Newton-Euler inverse dynamics in the world frame: torques for `qdd` at `q`, `qd`
/// with `gravity` (m/s², world frame), plus `Jm G² qdd`; friction excluded.
pub(crate) fn rne(
    chain: &SerialChain,
    links: &[LinkDynamics; MAX_JOINTS],
    gravity: &Vector3<f64>,
    q: &JointVector,
    qd: &JointVector,
    qdd: &JointVector,
) -> JointVector {
    let f = chain.frames(q);
    let n = chain.joint_count();
    // Forward pass: velocities and accelerations of each link, its origin and its centre of mass.
    let mut w = Vector3::zeros();
    let mut wd = Vector3::zeros();
    let mut a = -gravity; // linear acceleration of the current frame origin
    let mut force = [Vector3::zeros(); MAX_JOINTS];
    let mut moment = [Vector3::zeros(); MAX_JOINTS];
    let mut com = [Vector3::zeros(); MAX_JOINTS];
    for j in 0..n {
        let (z, o) = chain.joint_axis(&f, j);
        let r = f.p[j + 1] - f.p[j];
        let geometry = chain.geometry(j);
        match geometry.kind() {
            JointKind::Revolute => {
                // The point on the axis moves with the previous link (a DH frame's origin is
                // that point already; a URDF joint's is at the joint origin).
                if !geometry.axis_through_origin() {
                    let to_axis = o - f.p[j];
                    a += wd.cross(&to_axis) + w.cross(&w.cross(&to_axis));
                }
                let w_prev = w;
                w += z * qd[j];
                wd += z * qdd[j] + w_prev.cross(&z) * qd[j];
                let r = f.p[j + 1] - o;
                a += wd.cross(&r) + w.cross(&w.cross(&r));
            }
            JointKind::Prismatic => {
                a +=
                    wd.cross(&r) + w.cross(&w.cross(&r)) + w.cross(&z) * (2.0 * qd[j]) + z * qdd[j];
            }
        }
        let l = &links[j];
        let rot = &f.r[j + 1];
        let rc = rot * l.com;
        let ac = a + wd.cross(&rc) + w.cross(&w.cross(&rc));
        let ic = rot * l.inertia * rot.transpose();
        com[j] = f.p[j + 1] + rc;
        force[j] = ac * l.mass;
        moment[j] = ic * wd + w.cross(&(ic * w));
    }
    // Backward pass: force and moment (about the joint's axis point) transmitted to each link.
    let mut tau = JointVector::zeros();
    let mut f_out = Vector3::zeros(); // force link j+1 receives from link j
    let mut n_out = Vector3::zeros(); // its moment about `n_point`, the axis point of joint j+1
    let mut n_point = f.p[n];
    for j in (0..n).rev() {
        let (z, o) = chain.joint_axis(&f, j);
        let n_j = n_out + (n_point - o).cross(&f_out) + (com[j] - o).cross(&force[j]) + moment[j];
        let f_j = f_out + force[j];
        let l = &links[j];
        tau[j] = match chain.geometry(j).kind() {
            JointKind::Revolute => z.dot(&n_j),
            JointKind::Prismatic => z.dot(&f_j),
        } + l.reflected_motor_inertia() * qdd[j];
        f_out = f_j;
        n_out = n_j;
        n_point = o;
    }
    tau
}

/// Friction torque per joint at speed `qd` (see [`LinkDynamics::friction`]).
pub(crate) fn friction(
    n: usize,
    links: &[LinkDynamics; MAX_JOINTS],
    qd: &JointVector,
) -> JointVector {
    let mut tau = JointVector::zeros();
    for j in 0..n {
        tau[j] = links[j].friction(qd[j]);
    }
    tau
}
