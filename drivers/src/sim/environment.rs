//! What the slave touches: rigid shapes rendered as one-sided spring-dampers at the tool point.

use heapless::Vec as FixedVec;
use nalgebra::{Unit, Vector3};
use penelope_hal::{Frame, Pose, Timestamp, Twist, Wrench};

use super::Interaction;

/// The largest number of shapes in one [`Environment`].
pub const MAX_SHAPES: usize = 8;

/// A rigid shape, in the robot's base frame (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// An infinite plane (a wall or a table): free space is on the side `normal` points to.
    Plane {
        /// A point on the plane, m.
        point: Vector3<f64>,
        /// Unit normal pointing into free space.
        normal: Unit<Vector3<f64>>,
    },
    /// A solid sphere.
    Sphere {
        /// Centre, m.
        center: Vector3<f64>,
        /// Radius, m.
        radius: f64,
    },
}

impl Shape {
    /// Penetration depth (m, positive inside) and the outward surface normal at `p`.
    pub fn penetration(&self, p: &Vector3<f64>) -> (f64, Unit<Vector3<f64>>) {
        match *self {
            Shape::Plane { point, normal } => (-(p - point).dot(&normal), normal),
            Shape::Sphere { center, radius } => {
                let d = p - center;
                let dist = d.norm();
                let normal = if dist > 1e-12 {
                    Unit::new_unchecked(d / dist)
                } else {
                    Vector3::z_axis()
                };
                (radius - dist, normal)
            }
        }
    }
}

/// A shape with its contact mechanics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactModel {
    /// The shape.
    pub shape: Shape,
    /// Contact stiffness, N/m.
    pub stiffness: f64,
    /// Contact damping, N·s/m (acts only while in contact, and never pulls).
    pub damping: f64,
}

impl ContactModel {
    /// The force the shape exerts on a point at `p` moving at `v` (base frame, N): along the
    /// outward normal, `k d - b v_n`, never negative (a surface pushes, it does not pull).
    pub fn force(&self, p: &Vector3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
        let (depth, normal) = self.shape.penetration(p);
        if depth <= 0.0 {
            return Vector3::zeros();
        }
        let normal_speed = v.dot(&normal);
        let magnitude = (self.stiffness * depth - self.damping * normal_speed).max(0.0);
        normal.into_inner() * magnitude
    }

    /// Elastic energy stored in the contact at `p`, J (`½ k d²`).
    pub fn stored_energy(&self, p: &Vector3<f64>) -> f64 {
        let (depth, _) = self.shape.penetration(p);
        if depth > 0.0 {
            0.5 * self.stiffness * depth * depth
        } else {
            0.0
        }
    }
}

/// The slave's surroundings: a fixed set of shapes touched by the tool point.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Environment {
    shapes: FixedVec<ContactModel, MAX_SHAPES>,
}

/// More shapes than [`MAX_SHAPES`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TooManyShapes;

impl Environment {
    /// Empty space.
    pub fn new() -> Self {
        Environment::default()
    }

    /// Adds a shape.
    ///
    /// # Errors
    /// [`TooManyShapes`] beyond [`MAX_SHAPES`].
    pub fn with(mut self, contact: ContactModel) -> Result<Self, TooManyShapes> {
        self.shapes.push(contact).map_err(|_| TooManyShapes)?;
        Ok(self)
    }

    /// The shapes.
    pub fn shapes(&self) -> &[ContactModel] {
        &self.shapes
    }

    /// Elastic energy stored in all contacts at tool point `p`, J.
    pub fn stored_energy(&self, p: &Vector3<f64>) -> f64 {
        self.shapes.iter().map(|s| s.stored_energy(p)).sum()
    }
}

impl Interaction for Environment {
    fn wrench_on_tool(&mut self, _now: Timestamp, tool: &Pose, twist: &Twist) -> Wrench {
        let p = tool.translation.vector;
        let force = self.shapes.iter().map(|s| s.force(&p, &twist.linear)).sum();
        // Point contact at the tool origin: no moment about it.
        Wrench {
            force,
            torque: Vector3::zeros(),
            frame: Frame::Base,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wall() -> ContactModel {
        ContactModel {
            shape: Shape::Plane {
                point: Vector3::new(0.5, 0.0, 0.0),
                normal: -Vector3::x_axis(),
            },
            stiffness: 10_000.0,
            damping: 50.0,
        }
    }

    #[test]
    fn a_wall_pushes_back_in_proportion_to_depth_and_never_pulls() {
        let w = wall();
        assert_eq!(
            w.force(&Vector3::new(0.49, 0.0, 0.0), &Vector3::zeros()),
            Vector3::zeros()
        );
        let f = w.force(&Vector3::new(0.502, 0.1, 0.0), &Vector3::zeros());
        assert!((f - Vector3::new(-20.0, 0.0, 0.0)).norm() < 1e-9);
        // Leaving fast: damping would pull, but the surface only pushes.
        let leaving = w.force(
            &Vector3::new(0.5001, 0.0, 0.0),
            &Vector3::new(-5.0, 0.0, 0.0),
        );
        assert_eq!(leaving, Vector3::zeros());
        assert!((w.stored_energy(&Vector3::new(0.502, 0.0, 0.0)) - 0.02).abs() < 1e-12);
    }

    #[test]
    fn a_sphere_pushes_radially() {
        let s = ContactModel {
            shape: Shape::Sphere {
                center: Vector3::zeros(),
                radius: 0.1,
            },
            stiffness: 1000.0,
            damping: 0.0,
        };
        let f = s.force(&Vector3::new(0.0, 0.09, 0.0), &Vector3::zeros());
        assert!((f - Vector3::new(0.0, 10.0, 0.0)).norm() < 1e-9);
    }
}
