//! Coordinates a trajectory interpolates in: joint positions, or `[p; phi]` for a tool pose
//! (position and rotation vector relative to the start orientation).

use nalgebra::{Matrix3, Translation3, UnitQuaternion, Vector3, Vector6};
use penelope_hal::{CartesianReference, Frame, JointReference, Pose, Reference, Twist};

use super::Goal;

/// Joint space or operational space.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Space {
    Joint,
    Cartesian,
}

impl Space {
    pub(crate) fn of(goal: &Goal) -> Space {
        match goal {
            Goal::Joint(_) => Space::Joint,
            Goal::Cartesian(_) => Space::Cartesian,
        }
    }
}

/// The chart a started trajectory works in: for operational space, the start orientation `R0`
/// the rotation vectors are relative to.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Chart {
    space: Space,
    rotation0: UnitQuaternion<f64>,
}

/// Where a trajectory starts, in chart coordinates.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StartPoint {
    pub chart: Chart,
    pub coords: Vector6<f64>,
    pub velocity: Vector6<f64>,
}

impl Chart {
    /// The chart and coordinates of `from`, or `None` when `from` is of the wrong kind for `space`
    /// or not finite.
    pub(crate) fn start(space: Space, from: &Reference) -> Option<StartPoint> {
        if !from.is_finite() {
            return None;
        }
        match (space, from) {
            (Space::Joint, Reference::Joint(j)) => Some(StartPoint {
                chart: Chart {
                    space,
                    rotation0: UnitQuaternion::identity(),
                },
                coords: j.position,
                velocity: j.velocity,
            }),
            (Space::Cartesian, Reference::Cartesian(c)) => Some(cartesian_start(c)),
            (Space::Cartesian, Reference::Hybrid(h)) => Some(cartesian_start(&h.motion)),
            _ => None,
        }
    }

    /// The coordinates of `goal` in this chart (`None` for a goal of the other space). Rotation
    /// vectors lie within `pi` of the start orientation.
    pub(crate) fn coords(&self, goal: &Goal) -> Option<Vector6<f64>> {
        match (self.space, goal) {
            (Space::Joint, Goal::Joint(q)) => Some(*q),
            (Space::Cartesian, Goal::Cartesian(p)) => {
                let phi = (p.rotation * self.rotation0.inverse()).scaled_axis();
                let t = p.translation.vector;
                Some(Vector6::new(t.x, t.y, t.z, phi.x, phi.y, phi.z))
            }
            _ => None,
        }
    }

    /// The reference at coordinates `c`, rate `cd` and second derivative `cdd`.
    pub(crate) fn reference(
        &self,
        c: &Vector6<f64>,
        cd: &Vector6<f64>,
        cdd: &Vector6<f64>,
    ) -> Reference {
        match self.space {
            Space::Joint => Reference::Joint(JointReference {
                position: *c,
                velocity: *cd,
                acceleration: *cdd,
            }),
            Space::Cartesian => {
                let phi: Vector3<f64> = c.fixed_rows::<3>(3).into();
                let phid: Vector3<f64> = cd.fixed_rows::<3>(3).into();
                let rotation = UnitQuaternion::from_scaled_axis(phi) * self.rotation0;
                let pose = Pose::from_parts(Translation3::new(c[0], c[1], c[2]), rotation);
                Reference::Cartesian(CartesianReference {
                    pose,
                    twist: Twist {
                        linear: cd.fixed_rows::<3>(0).into(),
                        angular: so3_left_jacobian(&phi) * phid,
                        frame: Frame::Base,
                    },
                })
            }
        }
    }

    /// The goal held after the end: exactly the configured goal, at rest.
    pub(crate) fn hold(goal: &Goal) -> Reference {
        match goal {
            Goal::Joint(q) => Reference::Joint(JointReference {
                position: *q,
                velocity: Vector6::zeros(),
                acceleration: Vector6::zeros(),
            }),
            Goal::Cartesian(p) => Reference::Cartesian(CartesianReference {
                pose: *p,
                twist: Twist::default(),
            }),
        }
    }
}

fn cartesian_start(c: &CartesianReference) -> StartPoint {
    let t = c.pose.translation.vector;
    // The twist in the base frame; Tool/Flange/Sensor twists are rotated by the tool orientation.
    let (v, w) = match c.twist.frame {
        Frame::Base | Frame::Master => (c.twist.linear, c.twist.angular),
        _ => (
            c.pose.rotation * c.twist.linear,
            c.pose.rotation * c.twist.angular,
        ),
    };
    StartPoint {
        chart: Chart {
            space: Space::Cartesian,
            rotation0: c.pose.rotation,
        },
        coords: Vector6::new(t.x, t.y, t.z, 0.0, 0.0, 0.0),
        // At phi = 0 the left Jacobian is the identity, so phi' = omega.
        velocity: Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z),
    }
}

/// Chooses, among the rotation vectors equivalent to `phi` (`phi + 2 pi k phi/|phi|`), the one
/// closest to `previous`, so a spline through several orientations does not wrap around.
pub(crate) fn unwrap_rotation_vector(phi: Vector3<f64>, previous: &Vector3<f64>) -> Vector3<f64> {
    let angle = phi.norm();
    if angle < 1e-12 {
        return phi;
    }
    let axis = phi / angle;
    // Candidates phi + 2 pi k axis for k in -2..=2: enough for consecutive waypoints less than
    // half a turn apart.
    let mut best = phi;
    let mut best_d = (phi - previous).norm();
    for k in [-2.0_f64, -1.0, 1.0, 2.0] {
        let cand = axis * (angle + k * 2.0 * core::f64::consts::PI);
        let d = (cand - previous).norm();
        if d < best_d {
            best = cand;
            best_d = d;
        }
    }
    best
}

/// The left Jacobian of SO(3): the base-frame angular velocity of `exp(phi)` is
/// `J_l(phi) phi'`.
pub(crate) fn so3_left_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = phi.norm_squared();
    let (a, b) = if theta2 < 1e-8 {
        // Taylor series of (1 - cos t)/t² and (t - sin t)/t³.
        (0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0)
    } else {
        let theta = libm::sqrt(theta2);
        (
            (1.0 - libm::cos(theta)) / theta2,
            (theta - libm::sin(theta)) / (theta2 * theta),
        )
    };
    let k = phi.cross_matrix();
    Matrix3::identity() + k * a + k * k * b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn left_jacobian_matches_numerical_angular_velocity() {
        let phi = Vector3::new(0.4, -1.1, 0.7);
        let phid = Vector3::new(0.3, 0.2, -0.5);
        let h = 1e-6;
        let r0 = UnitQuaternion::from_scaled_axis(phi);
        let r1 = UnitQuaternion::from_scaled_axis(phi + phid * h);
        let omega_num = (r1 * r0.inverse()).scaled_axis() / h;
        let omega = so3_left_jacobian(&phi) * phid;
        assert!((omega - omega_num).norm() < 1e-5, "{omega} vs {omega_num}");
    }

    #[test]
    fn unwrap_picks_the_nearby_equivalent() {
        let prev = Vector3::new(0.0, 0.0, 3.0);
        // -3.0 about z is the same rotation as 2 pi - 3.0 = 3.283 about z.
        let phi = Vector3::new(0.0, 0.0, -3.0);
        let u = unwrap_rotation_vector(phi, &prev);
        assert!((u.z - (2.0 * core::f64::consts::PI - 3.0)).abs() < 1e-12);
    }
}
