//! The fast path of the commonest chain: six revolute standard-DH rows (both PUMAs, the FRHC).
//!
//! The arithmetic is the general sweep's ([`LinkGeometry::compose`]), operation for operation and
//! in the same order, so every result is equal bit for bit (the chain's tests compare the two
//! over many random configurations). What changes is what surrounds it:
//!
//! - the six `sin_cos` come first: a call clobbers every vector register, so interleaving them
//!   with the frames (as the general loop does) spills and reloads the running frame six times;
//! - the rows are plain arrays of fixed length: the loop unrolls, with no per-joint match on the
//!   joint's type and no reading of 2 KiB of mostly unused enum variants;
//! - the caller writes the Jacobian once, every column, straight into its result.

use nalgebra::{Matrix3, Vector3};
use penelope_hal::JointVector;

use super::dh::{JointKind, LinkGeometry, Rt};

/// Six revolute DH rows, as arrays: `theta_j = q_j + offset_j`, then `Rz Tz(d) Tx(a) Rx(alpha)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Dh6 {
    offset: [f64; 6],
    d: [f64; 6],
    a: [f64; 6],
    /// `cos(alpha)`, `sin(alpha)` as [`LinkGeometry`] computed them.
    ca: [f64; 6],
    sa: [f64; 6],
}

/// One configuration's sweep: the flange frame, and each joint's axis and a point on it (the
/// origin of the frame before the joint), in the world frame.
pub(crate) struct Sweep6 {
    pub flange: Rt,
    pub axis: [Vector3<f64>; 6],
    pub origin: [Vector3<f64>; 6],
}

impl Dh6 {
    /// The fast form of `links` when they are exactly six revolute DH rows, else `None`.
    pub fn new(links: &[Option<&LinkGeometry>]) -> Option<Self> {
        let rows: [&LinkGeometry; 6] = match links {
            [Some(a), Some(b), Some(c), Some(d), Some(e), Some(f)] => [a, b, c, d, e, f],
            _ => return None,
        };
        if rows.iter().any(|g| g.link.kind != JointKind::Revolute) {
            return None;
        }
        Some(Dh6 {
            offset: rows.map(|g| g.link.offset),
            d: rows.map(|g| g.link.d),
            a: rows.map(|g| g.link.a),
            ca: rows.map(|g| g.ca),
            sa: rows.map(|g| g.sa),
        })
    }

    /// `(sin theta_j, cos theta_j)` of every joint, as [`LinkGeometry::joint`] computes them.
    #[inline(always)]
    fn angles(&self, q: &JointVector) -> [(f64, f64); 6] {
        core::array::from_fn(|j| libm::sincos(q[j] + self.offset[j]))
    }

    /// Link `j`'s frame from the frame `(r, p)` before it: [`LinkGeometry::compose`] exactly.
    #[inline(always)]
    fn link(
        &self,
        j: usize,
        (st, ct): (f64, f64),
        r: &Matrix3<f64>,
        p: &Vector3<f64>,
    ) -> (Matrix3<f64>, Vector3<f64>) {
        let x = r.column(0);
        let y = r.column(1);
        let z = r.column(2);
        let xn = x * ct + y * st;
        let u = y * ct - x * st;
        let yn = u * self.ca[j] + z * self.sa[j];
        let zn = z * self.ca[j] - u * self.sa[j];
        let pn = p + z * self.d[j] + xn * self.a[j];
        (Matrix3::from_columns(&[xn, yn, zn]), pn)
    }

    /// The flange frame (after the sixth link) in the world frame.
    #[inline(always)]
    pub fn flange(&self, base: &Rt, q: &JointVector) -> Rt {
        let angles = self.angles(q);
        let (mut r, mut p) = (base.r, base.p);
        for (j, sc) in angles.into_iter().enumerate() {
            (r, p) = self.link(j, sc, &r, &p);
        }
        Rt { r, p }
    }

    /// The flange frame and every joint's axis (the z axis of the frame before it) and origin.
    #[inline(always)]
    pub fn sweep(&self, base: &Rt, q: &JointVector) -> Sweep6 {
        let angles = self.angles(q);
        let mut axis = [Vector3::zeros(); 6];
        let mut origin = [Vector3::zeros(); 6];
        let (mut r, mut p) = (base.r, base.p);
        for (j, sc) in angles.into_iter().enumerate() {
            axis[j] = r.column(2).into();
            origin[j] = p;
            (r, p) = self.link(j, sc, &r, &p);
        }
        Sweep6 {
            flange: Rt { r, p },
            axis,
            origin,
        }
    }
}
