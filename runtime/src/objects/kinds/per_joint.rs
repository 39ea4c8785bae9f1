//! [`PerJoint`]: one value for every joint, or one per joint, as the configurations write gains
//! and limits.

use crate::objects::config::{bad, check_range};
use crate::objects::error::ObjectError;
use penelope_hal::{JointVector, MAX_AXES, MAX_JOINTS};
use serde::{Deserialize, Serialize};

/// One value for every joint, or one per joint.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum PerJoint {
    /// The same value on every joint.
    One(f64),
    /// One value per joint.
    Each(Vec<f64>),
}

impl PerJoint {
    /// The values for `n` joints, each checked in `lo..=hi`.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] for a wrong count or a value out of range.
    pub fn resolve(
        &self,
        kind: &str,
        key: &str,
        n: usize,
        lo: f64,
        hi: f64,
    ) -> Result<JointVector, ObjectError> {
        let mut v = JointVector::zeros();
        match self {
            PerJoint::One(x) => {
                check_range(kind, key, *x, lo, hi)?;
                for j in 0..n.min(MAX_JOINTS) {
                    v[j] = *x;
                }
            }
            PerJoint::Each(xs) => {
                if xs.len() != n {
                    return Err(bad(
                        kind,
                        format!("`{key}` has {} values, the robot has {n} joints", xs.len()),
                    ));
                }
                for (j, x) in xs.iter().enumerate() {
                    check_range(kind, key, *x, lo, hi)?;
                    v[j] = *x;
                }
            }
        }
        Ok(v)
    }

    /// Checks what can be checked without knowing the joint count.
    pub(super) fn check(&self, kind: &str, key: &str, lo: f64, hi: f64) -> Result<(), ObjectError> {
        let values: &[f64] = match self {
            PerJoint::One(x) => std::slice::from_ref(x),
            PerJoint::Each(xs) => xs,
        };
        if values.is_empty() || values.len() > MAX_JOINTS.max(MAX_AXES) {
            return Err(bad(kind, format!("`{key}` needs 1 to {MAX_AXES} values")));
        }
        for x in values {
            check_range(kind, key, *x, lo, hi)?;
        }
        Ok(())
    }
}
