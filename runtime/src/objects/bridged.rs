//! Bridged channels: `trajectory/teleop` channels whose master end is fed from outside the
//! node, by a bridge (the Zenoh bridge today), instead of by a data-plane link. The runtime owns
//! what such a channel takes, so that a bridge sits above the creator and is never stored in
//! it: the key rule ([`check_key`]), the operator pose record ([`OperatorPose`]: a fixed
//! 58-byte little-endian record, cheap to produce from any language and easy to refuse before
//! anything is parsed), and the table of the node's bridged channels ([`BridgedChannels`]),
//! registered by the creator when it configures a channel with `zenoh_reference` and read by
//! the bridge's threads.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError};

use nalgebra::{Quaternion, Translation3, UnitQuaternion, Vector3};
use penelope_hal::{CartesianReference, Pose, Reference, Timestamp, Twist};
use penelope_rt_core::teleop::TeleopSample;

use super::teleop_end::BridgedEnd;

/// Checks a key expression a channel takes poses from: chunks separated by `/`, none empty,
/// no wildcard or reserved character (`*`, `$`, `?`, `#`): a plain key.
///
/// # Errors
/// Why it is no plain key.
pub fn check_key(key: &str) -> Result<(), &'static str> {
    if key.is_empty() || key.len() > 256 {
        return Err("a key is 1 to 256 characters");
    }
    if key.split('/').any(str::is_empty) {
        return Err("a key's chunks are not empty (no leading, trailing or double `/`)");
    }
    if key.contains(['*', '$', '?', '#']) || key.chars().any(char::is_whitespace) {
        return Err("a key has no wildcard (`*`), `$`, `?`, `#` or white space");
    }
    Ok(())
}

/// The length of an encoded [`OperatorPose`], bytes.
pub const OPERATOR_POSE_LEN: usize = 58;
/// The tag (first byte) of an [`OperatorPose`], version 1.
pub const OPERATOR_POSE_TAG: u8 = 0x01;
/// How far from 1 the norm of an operator pose's quaternion may be (it is normalized after).
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;
/// The largest distance of an operator pose's position from its frame's origin, m: anything
/// farther is no hand-held master's pose.
pub const MAX_POSITION_M: f64 = 100.0;

/// An operator station's master tool pose, as a `trajectory/teleop` channel's bridged end
/// takes it: the master side's sample (its base frame), mapped to the slave by the channel as
/// any master's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OperatorPose {
    /// The clutch (indexing) button: held = `true` (the slave holds; motion re-anchors on
    /// release).
    pub clutch: bool,
    /// The tool position, m.
    pub position: [f64; 3],
    /// The tool orientation, a unit quaternion `[w, x, y, z]`.
    pub orientation: [f64; 4],
}

/// Why an operator pose payload was refused (counted per channel; never reaches a loop).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum PoseError {
    /// Not [`OPERATOR_POSE_LEN`] bytes.
    #[error("{0} bytes, not {OPERATOR_POSE_LEN}")]
    Length(usize),
    /// The first byte is not [`OPERATOR_POSE_TAG`].
    #[error("tag {0:#04x}, not {OPERATOR_POSE_TAG:#04x}")]
    Tag(u8),
    /// The clutch byte is neither 0 nor 1.
    #[error("clutch byte {0:#04x}, neither 0 nor 1")]
    Clutch(u8),
    /// A number is NaN or infinite.
    #[error("a number is not finite")]
    NotFinite,
    /// The position is farther than [`MAX_POSITION_M`] from the origin.
    #[error("the position is farther than {MAX_POSITION_M} m from the origin")]
    OutOfReach,
    /// The quaternion's norm is off 1 by more than [`QUATERNION_NORM_TOLERANCE`].
    #[error("the orientation is not a unit quaternion")]
    NotUnit,
}

impl OperatorPose {
    /// The 58 bytes: tag `0x01`, clutch (0 or 1), position x, y, z and orientation w, x, y, z
    /// as IEEE 754 doubles, little-endian.
    pub fn encode(&self) -> [u8; OPERATOR_POSE_LEN] {
        let mut out = [0u8; OPERATOR_POSE_LEN];
        out[0] = OPERATOR_POSE_TAG;
        out[1] = u8::from(self.clutch);
        let numbers = self.position.iter().chain(self.orientation.iter());
        for (i, v) in numbers.enumerate() {
            out[2 + 8 * i..10 + 8 * i].copy_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Reads and checks a payload.
    ///
    /// # Errors
    /// [`PoseError`]: the wrong length or tag, a clutch byte other than 0 or 1, a number not
    /// finite, a position out of reach, a quaternion not of unit norm.
    pub fn decode(bytes: &[u8]) -> Result<OperatorPose, PoseError> {
        if bytes.len() != OPERATOR_POSE_LEN {
            return Err(PoseError::Length(bytes.len()));
        }
        if bytes[0] != OPERATOR_POSE_TAG {
            return Err(PoseError::Tag(bytes[0]));
        }
        let clutch = match bytes[1] {
            0 => false,
            1 => true,
            other => return Err(PoseError::Clutch(other)),
        };
        let mut n = [0f64; 7];
        for (i, v) in n.iter_mut().enumerate() {
            let mut b = [0u8; 8];
            b.copy_from_slice(&bytes[2 + 8 * i..10 + 8 * i]);
            *v = f64::from_le_bytes(b);
        }
        OperatorPose {
            clutch,
            position: [n[0], n[1], n[2]],
            orientation: [n[3], n[4], n[5], n[6]],
        }
        .checked()
    }

    /// The pose if it is one an operator's hand can give: every number finite, the position
    /// within [`MAX_POSITION_M`] of the origin, the quaternion of unit norm (within
    /// [`QUATERNION_NORM_TOLERANCE`]).
    ///
    /// # Errors
    /// [`PoseError::NotFinite`], [`PoseError::OutOfReach`] or [`PoseError::NotUnit`].
    pub fn checked(self) -> Result<OperatorPose, PoseError> {
        if self
            .position
            .iter()
            .chain(&self.orientation)
            .any(|v| !v.is_finite())
        {
            return Err(PoseError::NotFinite);
        }
        if Vector3::from(self.position).norm() > MAX_POSITION_M {
            return Err(PoseError::OutOfReach);
        }
        let norm = self.orientation.iter().map(|v| v * v).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
            return Err(PoseError::NotUnit);
        }
        Ok(self)
    }

    /// The pose (orientation normalized).
    pub fn pose(&self) -> Pose {
        let [w, x, y, z] = self.orientation;
        Pose::from_parts(
            Translation3::from(Vector3::from(self.position)),
            UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)),
        )
    }

    /// The channel sample it makes: sequence `sequence` (the bridge numbers what it took), a
    /// master's Cartesian reference with the clutch. Its send time is the tick's that takes it.
    pub fn sample(&self, sequence: u64) -> TeleopSample {
        TeleopSample {
            clutch: self.clutch,
            ..TeleopSample::new(
                sequence,
                Timestamp::ZERO,
                Reference::Cartesian(CartesianReference {
                    pose: self.pose(),
                    twist: Twist::default(),
                }),
            )
        }
    }
}

/// One bridged channel: where its reference comes from, its cells, and what was taken and
/// refused.
pub struct BridgedChannel {
    /// The Zenoh key expression its operator poses come from.
    pub key: String,
    /// The robot the channel drives (its slave, on this node).
    pub slave: String,
    end: BridgedEnd,
    /// Poses taken (handed to the loop).
    pub taken: u64,
    /// Payloads refused (malformed: never handed to the loop).
    pub refused: u64,
    /// Why the last refused payload was refused.
    pub last_refusal: Option<PoseError>,
}

/// What a bridged channel counted, for `describe` and for tests.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BridgedCounts {
    /// Its key expression.
    pub key: String,
    /// Poses taken.
    pub taken: u64,
    /// Payloads refused.
    pub refused: u64,
    /// Why the last refused payload was refused.
    pub last_refusal: Option<PoseError>,
}

/// Every bridged channel of a node, by channel name (shared by the creator and the bridge;
/// non-real-time: it locks).
#[derive(Clone, Default)]
pub struct BridgedChannels(Arc<Mutex<BTreeMap<String, BridgedChannel>>>);

impl std::fmt::Debug for BridgedChannels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.keys()).finish()
    }
}

impl BridgedChannels {
    fn with<R>(&self, f: impl FnOnce(&mut BTreeMap<String, BridgedChannel>) -> R) -> R {
        f(&mut self.0.lock().unwrap_or_else(PoisonError::into_inner))
    }

    /// Registers (or replaces: a channel configured anew has new cells) channel `channel`,
    /// whose operator poses come from `key` and drive robot `slave`.
    pub fn insert(&self, channel: &str, key: &str, slave: &str, end: BridgedEnd) {
        self.with(|m| {
            m.insert(
                channel.to_string(),
                BridgedChannel {
                    key: key.to_string(),
                    slave: slave.to_string(),
                    end,
                    taken: 0,
                    refused: 0,
                    last_refusal: None,
                },
            )
        });
    }

    /// Forgets channel `channel` (destroyed).
    pub fn remove(&self, channel: &str) {
        self.with(|m| m.remove(channel));
    }

    /// `(channel, key)` of every bridged channel.
    pub fn keys(&self) -> Vec<(String, String)> {
        self.with(|m| m.iter().map(|(c, b)| (c.clone(), b.key.clone())).collect())
    }

    /// The robot bridged channel `channel` drives.
    pub fn slave_of(&self, channel: &str) -> Option<String> {
        self.with(|m| m.get(channel).map(|b| b.slave.clone()))
    }

    /// The key of the bridged channel that drives robot `robot`, if one does.
    pub fn key_driving(&self, robot: &str) -> Option<String> {
        self.with(|m| m.values().find(|b| b.slave == robot).map(|b| b.key.clone()))
    }

    /// What channel `channel` counted.
    pub fn counts(&self, channel: &str) -> Option<BridgedCounts> {
        self.with(|m| {
            m.get(channel).map(|b| BridgedCounts {
                key: b.key.clone(),
                taken: b.taken,
                refused: b.refused,
                last_refusal: b.last_refusal,
            })
        })
    }

    /// Takes `payload`, which arrived on `key`, for every channel fed from that key: decoded
    /// and checked, it goes to the loop's cell as the channel's next sample; malformed, it is
    /// refused and counted. Returns whether it was taken.
    pub fn offer(&self, key: &str, payload: &[u8]) -> Result<(), PoseError> {
        self.take(key, OperatorPose::decode(payload))
    }

    /// As [`offer`](Self::offer), a pose already decoded (from another encoding: a ROS 2
    /// message), [`checked`](OperatorPose::checked) here.
    pub fn offer_pose(&self, key: &str, pose: OperatorPose) -> Result<(), PoseError> {
        self.take(key, pose.checked())
    }

    fn take(&self, key: &str, decoded: Result<OperatorPose, PoseError>) -> Result<(), PoseError> {
        self.with(|m| {
            for b in m.values_mut().filter(|b| b.key == key) {
                match decoded {
                    Ok(pose) => {
                        b.taken += 1;
                        b.end.to_loop.write(pose.sample(b.taken));
                    }
                    Err(e) => {
                        b.refused += 1;
                        b.last_refusal = Some(e);
                    }
                }
            }
        });
        decoded.map(|_| ())
    }

    /// The newest sample each channel's end sent since the last call (channel, sample).
    pub fn feedback(&self) -> Vec<(String, TeleopSample)> {
        self.with(|m| {
            m.iter_mut()
                .filter_map(|(c, b)| match b.end.from_loop.read() {
                    penelope_rt_core::cell::Fresh::New(s) => Some((c.clone(), s)),
                    _ => None,
                })
                .collect()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::check_key;

    #[test]
    fn plain_keys_pass_and_wildcards_do_not() {
        assert!(check_key("station/hand/pose").is_ok());
        for bad in ["", "/a", "a/", "a//b", "a/*", "a/**", "a/$b", "a b"] {
            assert!(check_key(bad).is_err(), "{bad}");
        }
    }
}
