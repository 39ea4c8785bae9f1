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
/// whose combination `c·M1 + s·M2 + (1 − c)·M3` is `R_origin · Rot(axis, q)` (Rodrigues). An axis
/// along a coordinate axis of the joint frame (most URDFs) takes a shorter path: the joint
/// frame `R · R_origin`, then two of its columns turned (like a DH row's `Rz`).
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
    /// `Some((k, ±1))` when the axis is `±e_k`.
    coordinate: Option<(usize, f64)>,
    /// The origin has no rotation.
    origin_unrotated: bool,
}

impl AxisGeometry {
    /// Prepares `joint`; its axis must be non-zero (checked by the chain).
    pub fn new(joint: AxisJoint) -> Self {
        let a = joint.axis.normalize();
        let joint = AxisJoint { axis: a, ..joint };
        let r0 = *joint.origin.rotation.to_rotation_matrix().matrix();
        let p0 = joint.origin.translation.vector;
        let axis_parent = r0 * a;
        let coordinate = (0..3).find_map(|k| {
            let others_zero = (0..3).all(|i| i == k || a[i] == 0.0);
            (others_zero && a[k].abs() == 1.0).then(|| (k, a[k]))
        });
        AxisGeometry {
            joint,
            r0,
            p0,
            r0_skew: r0 * a.cross_matrix(),
            r0_outer: axis_parent * a.transpose(),
            axis_parent,
            coordinate,
            origin_unrotated: r0 == Matrix3::identity(),
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
        let (frame, _) = self.step(r, p, q);
        frame
    }

    /// [`compose`](Self::compose) and [`axis_in`](Self::axis_in) in one: the child link's frame,
    /// and the joint's unit axis and a point on it, sharing the joint frame's computation (for a
    /// coordinate axis the axis is a column of it, for free).
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    pub fn step(
        &self,
        r: &Matrix3<f64>,
        p: &Vector3<f64>,
        q: f64,
    ) -> ((Matrix3<f64>, Vector3<f64>), (Vector3<f64>, Vector3<f64>)) {
        let pj = p + r * self.p0;
        match (self.joint.kind, self.coordinate) {
            (kind, Some((k, sign))) => {
                let mut f = if self.origin_unrotated {
                    *r
                } else {
                    r * self.r0
                };
                let z = f.column(k) * sign;
                if kind == JointKind::Prismatic {
                    return ((f, pj + z * q), (z, pj));
                }
                // Rotation about e_k turns columns i = k+1 and j = k+2 (cyclic).
                let (s, c) = libm::sincos(sign * q);
                let (i, j) = ((k + 1) % 3, (k + 2) % 3);
                let (ci, cj) = (f.column(i).into_owned(), f.column(j).into_owned());
                f.set_column(i, &(ci * c + cj * s));
                f.set_column(j, &(cj * c - ci * s));
                ((f, pj), (z, pj))
            }
            (JointKind::Revolute, None) => {
                let (s, c) = libm::sincos(q);
                let local = self.r0 * c + self.r0_skew * s + self.r0_outer * (1.0 - c);
                ((r * local, pj), (r * self.axis_parent, pj))
            }
            (JointKind::Prismatic, None) => {
                let z = r * self.axis_parent;
                ((r * self.r0, pj + z * q), (z, pj))
            }
        }
    }

    /// The joint's axis (unit) and a point on it, in the frame `(r, p)` of the parent link is
    /// expressed in.
    #[inline(always)]
    pub fn axis_in(&self, r: &Matrix3<f64>, p: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        (r * self.axis_parent, p + r * self.p0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Translation3, Unit, UnitQuaternion};

    /// The child frame by the definition: `R · R_origin · Rot(axis, q)`.
    fn reference(j: &AxisJoint, r: &Matrix3<f64>, q: f64) -> Matrix3<f64> {
        let r0 = j.origin.rotation.to_rotation_matrix();
        let turn = Rotation3::from_axis_angle(&Unit::new_normalize(j.axis), q);
        r * r0.matrix() * turn.matrix()
    }

    #[test]
    fn both_rotation_paths_are_the_definition() {
        let parent = *Rotation3::from_euler_angles(0.3, -1.1, 2.0).matrix();
        let p = Vector3::new(0.1, -0.2, 0.3);
        let origins = [
            Pose::identity(),
            Pose::from_parts(
                Translation3::new(0.2, 0.0, -0.1),
                UnitQuaternion::from_euler_angles(0.4, 0.5, -0.6),
            ),
        ];
        let axes = [
            Vector3::z(),
            -Vector3::z(),
            Vector3::x() * 3.0,
            -Vector3::y(),
            Vector3::new(1.0, 1.0, 0.0),
            Vector3::new(0.2, -0.7, 0.4),
        ];
        for origin in origins {
            for axis in axes {
                let j = AxisJoint::revolute(origin, axis);
                let g = AxisGeometry::new(j);
                let coordinate = axis.iter().filter(|x| **x != 0.0).count() == 1;
                assert_eq!(g.coordinate.is_some(), coordinate, "{axis:?}");
                for q in [-2.5, -0.3, 0.0, 0.7, 3.0] {
                    let (r, pn) = g.compose(&parent, &p, q);
                    let e = (r - reference(&j, &parent, q)).abs().max();
                    assert!(e < 1e-14, "axis {axis:?} q {q}: off by {e:e}");
                    let want_p = p + parent * origin.translation.vector;
                    assert!((pn - want_p).norm() < 1e-15);
                    let (_, (zs, os)) = g.step(&parent, &p, q);
                    let (z, o) = g.axis_in(&parent, &p);
                    assert!((zs - z).norm() < 1e-14 && (os - o).norm() < 1e-15);
                    assert!((z - parent * (origin.rotation * axis.normalize())).norm() < 1e-14);
                    assert!((o - want_p).norm() < 1e-15);
                }
            }
        }
    }

    #[test]
    fn a_prismatic_joint_slides_along_its_axis() {
        // Oblique axis (the general path) under a rotated parent.
        let parent = *Rotation3::from_euler_angles(0.3, -1.1, 2.0).matrix();
        let a = Vector3::new(0.2, -0.7, 0.4);
        let g = AxisGeometry::new(AxisJoint::prismatic(Pose::identity(), a));
        let (r, p) = g.compose(&parent, &Vector3::zeros(), 0.5);
        assert!((p - parent * a.normalize() * 0.5).norm() < 1e-15);
        assert_eq!(r, parent);
        let origin = Pose::from_parts(
            Translation3::new(0.3, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5),
        );
        let g = AxisGeometry::new(AxisJoint::prismatic(origin, Vector3::new(0.0, 0.0, -2.0)));
        let (r, p) = g.compose(&Matrix3::identity(), &Vector3::zeros(), 0.25);
        assert!((p - Vector3::new(0.3, 0.0, -0.25)).norm() < 1e-15);
        assert!(
            (r - origin.rotation.to_rotation_matrix().matrix())
                .abs()
                .max()
                < 1e-15
        );
    }
}
