//! Joint space: vectors, state and limits.

use nalgebra::SVector;

/// The largest number of joints a robot may have. Robots with fewer joints use the first
/// `joint_count()` entries of every joint vector and leave the rest at zero.
pub const MAX_JOINTS: usize = 6;

/// One value per joint: radians (positions), rad/s (velocities), rad/s² (accelerations) or N·m
/// (torques) depending on use. Lives on the stack; never allocates.
pub type JointVector = SVector<f64, MAX_JOINTS>;

/// A set of joint indices (`0..MAX_JOINTS`): which joints one controller of a robot drives when
/// several controllers share the robot. A bit mask: `Copy`, no allocation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct JointSet(u8);

impl JointSet {
    /// No joint.
    pub const EMPTY: JointSet = JointSet(0);

    /// Joints `0..n` (`n` clamped to [`MAX_JOINTS`]).
    pub fn first(n: usize) -> JointSet {
        let n = n.min(MAX_JOINTS);
        JointSet(((1u16 << n) - 1) as u8)
    }

    /// The set of these indices, or `None` if one is `MAX_JOINTS` or more.
    pub fn from_indices(indices: &[usize]) -> Option<JointSet> {
        let mut s = JointSet::EMPTY;
        for &j in indices {
            if j >= MAX_JOINTS {
                return None;
            }
            s.0 |= 1 << j;
        }
        Some(s)
    }

    /// True when joint `j` is in the set.
    pub fn contains(self, j: usize) -> bool {
        j < MAX_JOINTS && self.0 & (1 << j) != 0
    }

    /// The set with joint `j` added (`j` past [`MAX_JOINTS`] is ignored).
    #[must_use]
    pub fn with(self, j: usize) -> JointSet {
        if j < MAX_JOINTS {
            JointSet(self.0 | 1 << j)
        } else {
            self
        }
    }

    /// Joints in either set.
    #[must_use]
    pub fn union(self, other: JointSet) -> JointSet {
        JointSet(self.0 | other.0)
    }

    /// Joints in both sets.
    #[must_use]
    pub fn intersection(self, other: JointSet) -> JointSet {
        JointSet(self.0 & other.0)
    }

    /// True when the set has no joint.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// How many joints the set holds.
    pub fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    /// The joints in the set, in increasing order.
    pub fn iter(self) -> impl Iterator<Item = usize> {
        (0..MAX_JOINTS).filter(move |&j| self.contains(j))
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joint_sets_hold_exactly_their_indices() {
        let arm = JointSet::first(3);
        let wrist = JointSet::from_indices(&[3, 4, 5]).unwrap();
        assert_eq!(arm.iter().collect::<heapless::Vec<_, 6>>(), [0, 1, 2]);
        assert_eq!(arm.len(), 3);
        assert!(arm.contains(2) && !arm.contains(3) && !arm.contains(99));
        assert!(arm.intersection(wrist).is_empty());
        assert_eq!(arm.union(wrist), JointSet::first(MAX_JOINTS));
        assert_eq!(JointSet::first(100), JointSet::first(MAX_JOINTS));
        assert_eq!(
            JointSet::EMPTY.with(4).with(MAX_JOINTS),
            JointSet::from_indices(&[4]).unwrap()
        );
        assert_eq!(JointSet::from_indices(&[1, MAX_JOINTS]), None);
    }
}
