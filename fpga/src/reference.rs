//! The floating-point (f64) model of the same DH chain: the accuracy oracle for the tests and
//! the float baseline of `penelope bench fpga`.
//!
//! It composes frames exactly as the fixed-point pipeline does (`R <- R Rz(theta) Rx(alpha)`,
//! `p <- p + a R[:,0]' + d R[:,2]`), with one sine/cosine per joint and fixed-size arrays, and
//! accepts any twist `alpha`. The sine/cosine function is a parameter so that `std` users can pass
//! `f64::sin_cos` and `no_std` users `libm::sincos`.
//!
//! # Real-time
//! No allocation, no panic, constant time.

use crate::dh::{DhParams, JOINTS};

/// A DH chain in f64 with the twists' sines and cosines precomputed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatChain {
    rows: [FloatRow; JOINTS],
    joints: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct FloatRow {
    a: f64,
    d: f64,
    offset: f64,
    ca: f64,
    sa: f64,
}

/// A float forward-kinematics result with the intermediate frames.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct FloatFk {
    /// Tool rotation, `r[row][col]`.
    pub r: [[f64; 3]; 3],
    /// Tool position, m.
    pub p: [f64; 3],
    /// Joint `j`'s axis in the base frame (frame `j`'s z).
    pub z: [[f64; 3]; JOINTS],
    /// Frame `j`'s origin, m.
    pub o: [[f64; 3]; JOINTS],
}

impl FloatChain {
    /// The chain of `params` (at most [`JOINTS`] rows; missing rows are identity). Exact twists
    /// of 0, +-90 and 180 degrees get exact sines and cosines.
    pub fn new(params: &[DhParams]) -> FloatChain {
        let mut rows = [FloatRow {
            ca: 1.0,
            ..FloatRow::default()
        }; JOINTS];
        for (row, p) in rows.iter_mut().zip(params) {
            let (sa, ca) = match crate::dh::Alpha::from_radians(p.alpha) {
                Some(a) => match a {
                    crate::dh::Alpha::Zero => (0.0, 1.0),
                    crate::dh::Alpha::Plus90 => (1.0, 0.0),
                    crate::dh::Alpha::Pi => (0.0, -1.0),
                    crate::dh::Alpha::Minus90 => (-1.0, 0.0),
                },
                None => libm::sincos(p.alpha),
            };
            *row = FloatRow {
                a: p.a,
                d: p.d,
                offset: p.offset,
                ca,
                sa,
            };
        }
        FloatChain {
            rows,
            joints: params.len().min(JOINTS),
        }
    }

    /// Rows used.
    pub fn joints(&self) -> usize {
        self.joints
    }

    /// Tool rotation and position at `q` (rad), one `sin_cos` call per joint.
    #[inline]
    pub fn forward(
        &self,
        q: &[f64; JOINTS],
        sin_cos: impl Fn(f64) -> (f64, f64),
    ) -> ([[f64; 3]; 3], [f64; 3]) {
        let mut r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let mut p = [0.0; 3];
        for (row, &qj) in self.rows.iter().zip(q).take(self.joints) {
            step(&mut r, &mut p, row, sin_cos(qj + row.offset));
        }
        (r, p)
    }

    /// Forward kinematics with every intermediate frame (for the Jacobian and `J^T F`).
    pub fn forward_frames(
        &self,
        q: &[f64; JOINTS],
        sin_cos: impl Fn(f64) -> (f64, f64),
    ) -> FloatFk {
        let mut r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let mut p = [0.0; 3];
        let mut out = FloatFk::default();
        for (j, (row, &qj)) in self.rows.iter().zip(q).enumerate() {
            out.z[j] = [r[0][2], r[1][2], r[2][2]];
            out.o[j] = p;
            if j < self.joints {
                step(&mut r, &mut p, row, sin_cos(qj + row.offset));
            }
        }
        out.r = r;
        out.p = p;
        out
    }
}

#[inline(always)]
fn step(r: &mut [[f64; 3]; 3], p: &mut [f64; 3], row: &FloatRow, (s, c): (f64, f64)) {
    for i in 0..3 {
        let (r0, r1, r2) = (r[i][0], r[i][1], r[i][2]);
        let n0 = c * r0 + s * r1;
        let n1 = c * r1 - s * r0;
        p[i] += row.a * n0 + row.d * r2;
        r[i] = [n0, row.ca * n1 + row.sa * r2, row.ca * r2 - row.sa * n1];
    }
}

impl FloatFk {
    /// Joint torques `tau = J^T [f; m]` for a wrench in the base frame about the tool origin
    /// (N, N m), for the first `joints` joints (the rest zero).
    pub fn joint_torques(&self, wrench: &[f64; 6], joints: usize) -> [f64; JOINTS] {
        let f = [wrench[0], wrench[1], wrench[2]];
        let mut tau = [0.0; JOINTS];
        for (j, t) in tau.iter_mut().enumerate().take(joints) {
            let r = [
                self.p[0] - self.o[j][0],
                self.p[1] - self.o[j][1],
                self.p[2] - self.o[j][2],
            ];
            let m = [
                wrench[3] + r[1] * f[2] - r[2] * f[1],
                wrench[4] + r[2] * f[0] - r[0] * f[2],
                wrench[5] + r[0] * f[1] - r[1] * f[0],
            ];
            let z = self.z[j];
            *t = z[0] * m[0] + z[1] * m[1] + z[2] * m[2];
        }
        tau
    }

    /// A wrench given in the tool frame, rotated into the base frame (same origin).
    pub fn rotate_to_base(&self, wrench: &[f64; 6]) -> [f64; 6] {
        let mut out = [0.0; 6];
        for i in 0..3 {
            for k in 0..3 {
                out[i] += self.r[i][k] * wrench[k];
                out[3 + i] += self.r[i][k] * wrench[3 + k];
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dh::DhTable;

    #[test]
    fn frhc_home_is_a_quarter_metre_in_front() {
        let chain = FloatChain::new(&DhTable::frhc_params());
        let pi = core::f64::consts::PI;
        let (_, p) = chain.forward(
            &[0.0, pi / 3.0, 5.0 * pi / 6.0, 0.0, 0.0, 0.0],
            libm::sincos,
        );
        // Shoulder at the origin; the grip 0.25 m away from it.
        let reach = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        assert!((reach - 0.25).abs() < 1e-12, "{p:?}");
    }
}
