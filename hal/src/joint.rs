//! Joint space: vectors, state and limits.

use nalgebra::SVector;

/// The largest number of joints a robot may have. Robots with fewer joints use the first
/// `joint_count()` entries of every joint vector and leave the rest at zero.
pub const MAX_JOINTS: usize = 6;

/// One value per joint: radians (positions), rad/s (velocities), rad/s² (accelerations) or N·m
/// (torques) depending on use. Lives on the stack; never allocates.
pub type JointVector = SVector<f64, MAX_JOINTS>;

/// The measured state of a robot's joints.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct JointState {
    /// Joint positions, rad.
    pub position: JointVector,
    /// Joint velocities, rad/s.
    pub velocity: JointVector,
    /// Joint torques (applied or measured), N·m.
    pub effort: JointVector,
}

impl JointState {
    /// A state at rest at `position`.
    pub fn at_rest(position: JointVector) -> Self {
        JointState {
            position,
            velocity: JointVector::zeros(),
            effort: JointVector::zeros(),
        }
    }

    /// True when every value is finite.
    pub fn is_finite(&self) -> bool {
        all_finite(&self.position) && all_finite(&self.velocity) && all_finite(&self.effort)
    }
}

/// True when every entry of `v` is finite (neither NaN nor infinite).
pub fn all_finite(v: &JointVector) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// The safe operating envelope of a robot's joints.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct JointLimits {
    /// Lowest allowed position per joint, rad.
    pub position_min: JointVector,
    /// Highest allowed position per joint, rad.
    pub position_max: JointVector,
    /// Largest allowed speed per joint, rad/s (absolute value).
    pub velocity_max: JointVector,
    /// Largest allowed torque per joint, N·m (absolute value).
    pub effort_max: JointVector,
}

impl JointLimits {
    /// True when `q[j]` lies within `[position_min[j], position_max[j]]` for the first `n` joints.
    pub fn contains_position(&self, q: &JointVector, n: usize) -> bool {
        (0..n.min(MAX_JOINTS)).all(|j| q[j] >= self.position_min[j] && q[j] <= self.position_max[j])
    }

    /// Limits that allow everything: for models whose envelope is not known.
    pub fn unbounded() -> Self {
        JointLimits {
            position_min: JointVector::repeat(f64::NEG_INFINITY),
            position_max: JointVector::repeat(f64::INFINITY),
            velocity_max: JointVector::repeat(f64::INFINITY),
            effort_max: JointVector::repeat(f64::INFINITY),
        }
    }
}
