//! Denavit-Hartenberg links (standard, distal convention) and the link transform.
//!
//! One link's transform is `A_j = Rz(theta_j) Tz(d_j) Tx(a_j) Rx(alpha_j)` with
//! `theta_j = q_j + offset_j` for a revolute joint and `d_j + q_j` for a prismatic one. The
//! modified (Craig) convention is not supported: do not mix the two.

use nalgebra::{Matrix3, Vector3};

/// How a joint moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum JointKind {
    /// Rotation about the previous frame's z axis; the joint variable is an angle, rad.
    #[default]
    Revolute,
    /// Translation along the previous frame's z axis; the joint variable is a length, m.
    Prismatic,
}

/// One row of a standard DH table.
///
/// For a revolute joint `theta = q + offset` and `d` is fixed; for a prismatic joint
/// `d = q + offset` and `theta` is fixed. The unused one of `theta` (revolute) or `d` (prismatic)
/// is ignored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DhLink {
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Fixed joint angle of a prismatic joint, rad (ignored for a revolute joint).
    pub theta: f64,
    /// Offset along the previous z axis of a revolute joint, m (ignored for a prismatic joint).
    pub d: f64,
    /// Length along the new x axis, m.
    pub a: f64,
    /// Twist about the new x axis, rad.
    pub alpha: f64,
    /// Added to the joint variable: rad for a revolute joint, m for a prismatic one.
    pub offset: f64,
}

impl DhLink {
    /// A revolute link: `d`, `a` in m, `alpha`, `offset` in rad.
    pub const fn revolute(d: f64, a: f64, alpha: f64, offset: f64) -> Self {
        DhLink {
            kind: JointKind::Revolute,
            theta: 0.0,
            d,
            a,
            alpha,
            offset,
        }
    }

    /// A prismatic link: fixed angle `theta` (rad), `a` (m), `alpha` (rad), `offset` (m).
    pub const fn prismatic(theta: f64, a: f64, alpha: f64, offset: f64) -> Self {
        DhLink {
            kind: JointKind::Prismatic,
            theta,
            d: 0.0,
            a,
            alpha,
            offset,
        }
    }

    /// True when every number is finite.
    pub fn is_finite(&self) -> bool {
        [self.theta, self.d, self.a, self.alpha, self.offset]
            .iter()
            .all(|x| x.is_finite())
    }
}

/// A DH row prepared for fast evaluation: `cos(alpha)` and `sin(alpha)` computed once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LinkGeometry {
    pub link: DhLink,
    pub ca: f64,
    pub sa: f64,
    /// `cos(theta)`, `sin(theta)` of a prismatic joint's fixed angle.
    ct0: f64,
    st0: f64,
}

impl LinkGeometry {
    pub fn new(link: DhLink) -> Self {
        let (sa, ca) = link.alpha.sin_cos();
        let (st0, ct0) = link.theta.sin_cos();
        LinkGeometry {
            link,
            ca,
            sa,
            ct0,
            st0,
        }
    }

    /// `(cos theta, sin theta, d)` for joint value `q`.
    #[inline(always)]
    pub fn joint(&self, q: f64) -> (f64, f64, f64) {
        match self.link.kind {
            JointKind::Revolute => {
                let (s, c) = libm::sincos(q + self.link.offset);
                (c, s, self.link.d)
            }
            JointKind::Prismatic => (self.ct0, self.st0, q + self.link.offset),
        }
    }

    /// Composes the frame `(r, p)` with this link's transform at joint value `q`, returning the
    /// new frame. Exploits the structure of `Rz Tz Tx Rx`: 12 multiplications for the rotation.
    #[inline(always)]
    pub fn compose(
        &self,
        r: &Matrix3<f64>,
        p: &Vector3<f64>,
        q: f64,
    ) -> (Matrix3<f64>, Vector3<f64>) {
        let (ct, st, d) = self.joint(q);
        let x = r.column(0);
        let y = r.column(1);
        let z = r.column(2);
        let xn = x * ct + y * st;
        let u = y * ct - x * st;
        let yn = u * self.ca + z * self.sa;
        let zn = z * self.ca - u * self.sa;
        let pn = p + z * d + xn * self.link.a;
        (Matrix3::from_columns(&[xn, yn, zn]), pn)
    }
}

/// A rigid transform as a rotation matrix and a translation (faster to compose than a
/// quaternion pose in the inner loops).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Rt {
    pub r: Matrix3<f64>,
    pub p: Vector3<f64>,
}

impl Rt {
    pub fn from_pose(pose: &penelope_hal::Pose) -> Self {
        Rt {
            r: *pose.rotation.to_rotation_matrix().matrix(),
            p: pose.translation.vector,
        }
    }

    pub fn is_identity(&self) -> bool {
        self.r == Matrix3::identity() && self.p == Vector3::zeros()
    }

    pub fn inverse(&self) -> Rt {
        let rt = self.r.transpose();
        Rt {
            r: rt,
            p: -(rt * self.p),
        }
    }

    pub fn mul(&self, other: &Rt) -> Rt {
        Rt {
            r: self.r * other.r,
            p: self.p + self.r * other.p,
        }
    }

    pub fn to_pose(self) -> penelope_hal::Pose {
        let rot = nalgebra::Rotation3::from_matrix_unchecked(self.r);
        penelope_hal::Pose::from_parts(
            nalgebra::Translation3::from(self.p),
            nalgebra::UnitQuaternion::from_rotation_matrix(&rot),
        )
    }
}
