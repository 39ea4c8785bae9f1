//! References: what a trajectory hands a controller each tick.

use crate::joint::{JointVector, all_finite};
use crate::spatial::{Pose, Twist, Wrench};

/// A joint-space set-point.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct JointReference {
    /// Desired positions, rad.
    pub position: JointVector,
    /// Desired velocities, rad/s (feed-forward).
    pub velocity: JointVector,
    /// Desired accelerations, rad/s² (feed-forward).
    pub acceleration: JointVector,
}

/// An operational-space set-point for the tool frame, in the robot's base frame.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CartesianReference {
    /// Desired tool pose.
    pub pose: Pose,
    /// Desired tool twist (feed-forward).
    pub twist: Twist,
}

/// Position control along some axes and force control along the others.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct HybridReference {
    /// The motion part.
    pub motion: CartesianReference,
    /// The force part.
    pub wrench: Wrench,
    /// Per axis `[x, y, z, rx, ry, rz]` of the wrench's frame: `true` = force-controlled.
    pub force_axes: [bool; 6],
}

/// What a controller is asked to follow.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Reference {
    /// Follow joint positions.
    Joint(JointReference),
    /// Follow a tool pose.
    Cartesian(CartesianReference),
    /// Apply (or display, on a master) a wrench.
    Wrench(Wrench),
    /// Position along some axes, force along the others.
    Hybrid(HybridReference),
}

impl Reference {
    /// The tool pose it asks for, if it asks for one (Cartesian and hybrid references).
    pub fn pose(&self) -> Option<Pose> {
        match self {
            Reference::Cartesian(c) => Some(c.pose),
            Reference::Hybrid(h) => Some(h.motion.pose),
            Reference::Joint(_) | Reference::Wrench(_) => None,
        }
    }

    /// The wrench it carries, if it carries one (wrench and hybrid references).
    pub fn wrench(&self) -> Option<Wrench> {
        match self {
            Reference::Wrench(w) => Some(*w),
            Reference::Hybrid(h) => Some(h.wrench),
            Reference::Joint(_) | Reference::Cartesian(_) => None,
        }
    }

    /// True when no component is NaN or infinite. The control loop rejects references that fail
    /// this check before any controller sees them.
    pub fn is_finite(&self) -> bool {
        fn pose_ok(p: &Pose) -> bool {
            p.translation.vector.iter().all(|x| x.is_finite())
                && p.rotation.coords.iter().all(|x| x.is_finite())
        }
        fn twist_ok(t: &Twist) -> bool {
            t.to_vector().iter().all(|x| x.is_finite())
        }
        match self {
            Reference::Joint(j) => {
                all_finite(&j.position) && all_finite(&j.velocity) && all_finite(&j.acceleration)
            }
            Reference::Cartesian(c) => pose_ok(&c.pose) && twist_ok(&c.twist),
            Reference::Wrench(w) => w.is_finite(),
            Reference::Hybrid(h) => {
                pose_ok(&h.motion.pose) && twist_ok(&h.motion.twist) && h.wrench.is_finite()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_anywhere_is_caught() {
        let mut j = JointReference::default();
        assert!(Reference::Joint(j).is_finite());
        j.velocity[3] = f64::NAN;
        assert!(!Reference::Joint(j).is_finite());
        let mut w = Wrench::default();
        w.torque.z = f64::INFINITY;
        assert!(!Reference::Wrench(w).is_finite());
    }
}
