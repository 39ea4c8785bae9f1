//! A joint as URDF describes one: a fixed origin transform in the parent link's frame, then a
//! rotation about (or a translation along) a unit axis of that joint frame.
//!
//! The child link's frame is `T_child = T_parent · origin · Rot(axis, q)` for a revolute joint
//! and `T_parent · origin · Trans(axis · q)` for a prismatic one; the axis is given in the joint
//! frame (equal to the child frame at `q = 0`). The joint variable has no offset.

use nalgebra::{Matrix3, Vector3};
use penelope_hal::Pose;

use super::dh::JointKind;

/// One joint of an axis-based (URDF-style) chain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisJoint {
    /// Revolute (rotation about `axis`) or prismatic (translation along it).
    pub kind: JointKind,
    /// Pose of the joint frame in the parent link's frame (URDF `<origin xyz rpy>`).
    pub origin: Pose,
    /// The joint axis in the joint frame; normalised when the chain is built (URDF `<axis>`).
    pub axis: Vector3<f64>,
}

impl AxisJoint {
    /// A revolute joint about `axis` after `origin`.
    pub fn revolute(origin: Pose, axis: Vector3<f64>) -> Self {
        AxisJoint {
            kind: JointKind::Revolute,
            origin,
            axis,
        }
    }

    /// A prismatic joint along `axis` after `origin`.
    pub fn prismatic(origin: Pose, axis: Vector3<f64>) -> Self {
        AxisJoint {
            kind: JointKind::Prismatic,
            origin,
            axis,
        }
    }

    /// True when every number is finite and the axis has a usable length.
    pub fn is_valid(&self) -> bool {
        self.origin
            .translation
            .vector
            .iter()
            .chain(self.origin.rotation.coords.iter())
            .chain(self.axis.iter())
            .all(|x| x.is_finite())
            && self.axis.norm() > 1e-9
    }
}

/// An [`AxisJoint`] prepared for fast evaluation: the origin as a matrix, and the three matrices
/// whose combination `c·M1 + s·M2 + (1 − c)·M3` is `R_origin · Rot(axis, q)` (Rodrigues).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct AxisGeometry {
    pub joint: AxisJoint,
    /// `R_origin`.
    r0: Matrix3<f64>,
    /// `p_origin`.
    p0: Vector3<f64>,
    /// `R_origin · [a]×`.
    r0_skew: Matrix3<f64>,
    /// `(R_origin · a) aᵀ`.
    r0_outer: Matrix3<f64>,
    /// `R_origin · a`: the axis in the parent link's frame.
    axis_parent: Vector3<f64>,
}

impl AxisGeometry {
    /// Prepares `joint`; its axis must be non-zero (checked by the chain).
    pub fn new(joint: AxisJoint) -> Self {
        let a = joint.axis.normalize();
        let joint = AxisJoint { axis: a, ..joint };
        let r0 = *joint.origin.rotation.to_rotation_matrix().matrix();
        let p0 = joint.origin.translation.vector;
        let axis_parent = r0 * a;
        AxisGeometry {
            joint,
            r0,
            p0,
            r0_skew: r0 * a.cross_matrix(),
            r0_outer: axis_parent * a.transpose(),
            axis_parent,
        }
    }

    /// Composes the parent frame `(r, p)` with this joint at value `q`: the child link's frame.
    #[inline(always)]
    pub fn compose(
        &self,
        r: &Matrix3<f64>,
        p: &Vector3<f64>,
        q: f64,
    ) -> (Matrix3<f64>, Vector3<f64>) {
        let pj = p + r * self.p0;
        match self.joint.kind {
            JointKind::Revolute => {
                let (s, c) = libm::sincos(q);
                let local = self.r0 * c + self.r0_skew * s + self.r0_outer * (1.0 - c);
                (r * local, pj)
            }
            JointKind::Prismatic => (r * self.r0, pj + r * (self.axis_parent * q)),
        }
    }

    /// The joint's axis (unit) and a point on it, in the frame `(r, p)` of the parent link is
    /// expressed in.
    #[inline(always)]
    pub fn axis_in(&self, r: &Matrix3<f64>, p: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        (r * self.axis_parent, p + r * self.p0)
    }
}
