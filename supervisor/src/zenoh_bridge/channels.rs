//! The channels whose other end is an operator station behind the Zenoh bridge: registered by
//! the creator when it configures a `trajectory/teleop` channel with `zenoh_reference`, read by
//! the bridge's threads. Always compiled (a node built without the `zenoh` feature refuses to
//! start a bridge, not to configure the channel).

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError};

use penelope_rt_core::teleop::TeleopSample;

use super::encoding::{OperatorPose, PoseError};
use crate::objects::teleop_end::BridgedEnd;

/// One bridged channel: where its reference comes from, its cells, and what was taken and
/// refused.
pub struct BridgedChannel {
    /// The Zenoh key expression its operator poses come from.
    pub key: String,
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
    /// whose operator poses come from `key`.
    pub fn insert(&self, channel: &str, key: &str, end: BridgedEnd) {
        self.with(|m| {
            m.insert(
                channel.to_string(),
                BridgedChannel {
                    key: key.to_string(),
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
        let decoded = OperatorPose::decode(payload);
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
