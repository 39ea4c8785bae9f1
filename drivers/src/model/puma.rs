//! Closed-form inverse kinematics of the PUMA structure: a first link with `a1 = 0`, two
//! parallel shoulder/elbow axes with a lateral offset `d2 + d3`, a forearm `(a3, d4)` and a
//! spherical wrist (`a4 = a5 = a6 = 0`, `d5 = 0`), twists `(+pi/2, 0, -pi/2, +pi/2, -pi/2, 0)`.
//!
//! After Paul and Zhang (IJRR 5(2), 1986), as in the Robotics Toolbox's `Puma560.ikine_a`, with
//! the same branch conventions, generalised to joint offsets, `d2 != 0`, a flange offset `d6` and
//! any base and tool transform. Both PUMAs fit, and so does the FRHC working model.
//!
//! Branches are named `shoulder-elbow-wrist`: `left`/`right`, `up`/`down`, `noflip`/`flip`
//! (the toolbox's configuration letters `l r u d n f`).

use core::f64::consts::PI;

use nalgebra::{Matrix3, Vector3};
use penelope_hal::{JointVector, KinematicsError, MAX_JOINTS};

use super::chain::SerialChain;
use super::dh::{JointKind, Rt};

/// The eight branch names, indexed by `4 * right + 2 * down + flip`.
pub const BRANCHES: [&str; 8] = [
    "left-up-noflip",
    "left-up-flip",
    "left-down-noflip",
    "left-down-flip",
    "right-up-noflip",
    "right-up-flip",
    "right-down-noflip",
    "right-down-flip",
];

/// Tolerance on the structural checks (twists in rad, lengths in m).
const STRUCTURE_TOL: f64 = 1e-9;
/// Below this distance from the wrist-singular configuration (`sin q5 = 0`) the wrist angles
/// `q4` and `q6` are coupled and `q4` is taken from the hint.
const WRIST_SINGULAR: f64 = 1e-12;
/// Slack on the reach checks, m: targets this far outside the workspace are clamped onto it.
const REACH_SLACK: f64 = 1e-9;

/// The lengths the closed form needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PumaIk {
    d1: f64,
    a2: f64,
    a3: f64,
    /// Lateral shoulder offset `d2 + d3`.
    lateral: f64,
    d4: f64,
    d6: f64,
    /// Joint offsets `theta = q + offset`.
    offset: [f64; 6],
}

/// Joint angles `theta` (offsets included) of one branch.
type Theta = [f64; 6];

impl PumaIk {
    /// The closed form when `chain` has the PUMA structure, else `None`.
    pub fn detect(chain: &SerialChain) -> Option<PumaIk> {
        if chain.joint_count() != 6 {
            return None;
        }
        let alphas = [PI / 2.0, 0.0, -PI / 2.0, PI / 2.0, -PI / 2.0, 0.0];
        let mut l = [chain.dh_geometry(0)?.link; 6];
        for (j, lj) in l.iter_mut().enumerate() {
            *lj = chain.dh_geometry(j)?.link;
            if lj.kind != JointKind::Revolute || (lj.alpha - alphas[j]).abs() > STRUCTURE_TOL {
                return None;
            }
        }
        let zero = |x: f64| x.abs() <= STRUCTURE_TOL;
        if !(zero(l[0].a) && zero(l[3].a) && zero(l[4].a) && zero(l[5].a) && zero(l[4].d)) {
            return None;
        }
        if zero(l[1].a) || zero(l[2].a.hypot(l[3].d)) {
            return None;
        }
        Some(PumaIk {
            d1: l[0].d,
            a2: l[1].a,
            a3: l[2].a,
            lateral: l[1].d + l[2].d,
            d4: l[3].d,
            d6: l[5].d,
            offset: l.map(|lj| lj.offset),
        })
    }

    /// Every branch for the flange frame `flange` (in frame 0, i.e. base and tool removed),
    /// written into `out` in [`BRANCHES`] order as joint values `q` (offsets removed, principal
    /// angles). `wrist_hint` is the `q4` to use at a wrist singularity.
    ///
    /// # Errors
    /// [`KinematicsError::Unreachable`] when the wrist centre is out of reach.
    pub fn solve(
        &self,
        chain: &SerialChain,
        flange: &Rt,
        wrist_hint: f64,
        out: &mut [JointVector; 8],
    ) -> Result<(), KinematicsError> {
        let r = &flange.r;
        // Wrist centre: the flange origin moved back along the approach vector by d6.
        let pw = flange.p - r.column(2) * self.d6;
        let (px, py, pz) = (pw.x, pw.y, pw.z - self.d1);
        let radius = px.hypot(py);
        let d = self.lateral;
        if radius < d.abs() - REACH_SLACK {
            return Err(KinematicsError::Unreachable);
        }
        let phi = py.atan2(px);
        let asin = if radius > 0.0 {
            (d / radius).clamp(-1.0, 1.0).asin()
        } else {
            // On the waist axis with no lateral offset: every q1 works; take 0 for "right".
            -phi
        };
        let (a2, a3, d4) = (self.a2, self.a3, self.d4);
        for right in [false, true] {
            let t1 = if right { phi + asin } else { phi + PI - asin };
            let (s1, c1) = t1.sin_cos();
            let v114 = px * c1 + py * s1;
            let reach = v114.hypot(pz);
            if reach <= 0.0 {
                return Err(KinematicsError::Unreachable);
            }
            let cos_psi =
                (a2 * a2 - d4 * d4 - a3 * a3 + v114 * v114 + pz * pz) / (2.0 * a2 * reach);
            // Relative slack: cos_psi changes by about REACH_SLACK / a2 per metre of overshoot.
            if cos_psi.abs() > 1.0 + REACH_SLACK / a2.abs() {
                return Err(KinematicsError::Unreachable);
            }
            let psi = cos_psi.clamp(-1.0, 1.0).acos();
            let base_angle = pz.atan2(v114);
            for down in [false, true] {
                let mut n2 = if down { -1.0 } else { 1.0 };
                if !right {
                    n2 = -n2;
                }
                let t2 = base_angle + n2 * psi;
                let (s2, c2) = t2.sin_cos();
                let num = c2 * v114 + s2 * pz - a2;
                let den = c2 * pz - s2 * v114;
                let t3 = a3.atan2(d4) - num.atan2(den);
                let arm = [t1, t2, t3];
                let r36 = self.wrist_rotation(chain, &arm, r);
                for flip in [false, true] {
                    let (t4, t5, t6) = wrist(&r36, flip, wrist_hint + self.offset[3]);
                    let theta: Theta = [t1, t2, t3, t4, t5, t6];
                    let k = 4 * usize::from(right) + 2 * usize::from(down) + usize::from(flip);
                    let mut q = JointVector::zeros();
                    for j in 0..6 {
                        q[j] = principal(theta[j] - self.offset[j]);
                    }
                    out[k] = q;
                }
            }
        }
        Ok(())
    }

    /// `R36 = R03^T R06` for arm angles `theta` (offsets included).
    fn wrist_rotation(
        &self,
        chain: &SerialChain,
        theta: &[f64; 3],
        r06: &Matrix3<f64>,
    ) -> Matrix3<f64> {
        let mut r = Matrix3::identity();
        let mut p = Vector3::zeros();
        for (j, t) in theta.iter().enumerate() {
            (r, p) = chain.geometry(j).compose(&r, &p, t - self.offset[j]);
        }
        r.tr_mul(r06)
    }
}

/// Wrist angles `(theta4, theta5, theta6)` from `R36 = Rz(t4) Ry(-t5) Rz(t6)` (ZYZ Euler angles
/// with the middle angle negated, as the toolbox does for `alpha4 > 0`). `noflip` has
/// `theta5 <= 0`. At a singularity `theta4 = hint` (`hint + pi` when flipped).
fn wrist(r: &Matrix3<f64>, flip: bool, hint: f64) -> (f64, f64, f64) {
    let (r02, r12) = (r[(0, 2)], r[(1, 2)]);
    let t4 = if r02.hypot(r12) < WRIST_SINGULAR {
        if flip { hint + PI } else { hint }
    } else if flip {
        (-r12).atan2(-r02)
    } else {
        r12.atan2(r02)
    };
    let (s4, c4) = t4.sin_cos();
    let beta = (c4 * r02 + s4 * r12).atan2(r[(2, 2)]);
    let t6 = (-s4 * r[(0, 0)] + c4 * r[(1, 0)]).atan2(-s4 * r[(0, 1)] + c4 * r[(1, 1)]);
    (t4, -beta, t6)
}

/// The angle in `(-pi, pi]` (arithmetic only, no trigonometry).
#[inline]
pub(crate) fn principal(x: f64) -> f64 {
    const TAU: f64 = 2.0 * PI;
    let y = x - TAU * (x / TAU).round();
    if y <= -PI {
        y + TAU
    } else if y > PI {
        y - TAU
    } else {
        y
    }
}

/// The 2π-equivalent of `x` inside `[lo, hi]` closest to `target`, or `None`.
#[inline]
pub(crate) fn equivalent_within(x: f64, lo: f64, hi: f64, target: f64) -> Option<f64> {
    // The equivalent nearest the target, then step outwards by whole turns.
    let near = target + principal(x - target);
    let mut best: Option<f64> = None;
    for k in [0.0, -1.0, 1.0, -2.0, 2.0] {
        let c = near + k * 2.0 * PI;
        if c >= lo && c <= hi {
            match best {
                Some(b) if (b - target).abs() <= (c - target).abs() => {}
                _ => best = Some(c),
            }
        }
    }
    best
}

/// Maps every revolute joint of `q` to its 2π-equivalent inside the limits closest to `target`
/// (the principal value when `target` is zero). Returns whether every joint is within limits;
/// joints with no equivalent inside keep their value.
pub(crate) fn fit_limits(
    q: &mut JointVector,
    n: usize,
    kinds: impl Fn(usize) -> JointKind,
    lo: &JointVector,
    hi: &JointVector,
    target: &JointVector,
) -> bool {
    let mut ok = true;
    for j in 0..n.min(MAX_JOINTS) {
        match kinds(j) {
            JointKind::Revolute => match equivalent_within(q[j], lo[j], hi[j], target[j]) {
                Some(v) => q[j] = v,
                None => {
                    q[j] = target[j] + principal(q[j] - target[j]);
                    ok = false;
                }
            },
            JointKind::Prismatic => ok &= q[j] >= lo[j] && q[j] <= hi[j],
        }
    }
    ok
}
