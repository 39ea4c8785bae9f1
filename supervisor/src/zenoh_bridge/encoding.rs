//! What crosses the Zenoh bridge, byte for byte (`docs/zenoh.md` is its description, checked
//! against this module by `supervisor/tests/zenoh_doc.rs`): the key expressions, the JSON
//! messages a node publishes and the binary operator pose it takes.
//!
//! Outward, a node publishes the same JSON messages its MCAP recordings hold (`runs::mcap_log`):
//! one encoding of a tick, a safety event and a link's statistics for files and for the wire,
//! readable by any Zenoh tool without generated code. Inward, the operator pose is a fixed
//! 58-byte little-endian record: cheap to produce from any language (`struct.pack`), and a
//! length and a tag that make a malformed payload easy to refuse before anything is parsed.
//!
//! Nothing here needs the `zenoh` crate: the encoding is tested in every build.

use penelope_rt_core::safety::{FaultCause, SafetyState};
use penelope_rt_core::teleop::TeleopSample;
use serde_json::json;

use penelope_runtime::objects::tick::TickRecord;

/// The first chunk of every key expression the bridge uses.
pub const KEY_ROOT: &str = "penelope";
/// The stream of a controller's ticks: `penelope/<node>/<controller>/telemetry`.
pub const TELEMETRY: &str = "telemetry";
/// The stream of a controller's safety events: `penelope/<node>/<controller>/events`.
pub const EVENTS: &str = "events";
/// The stream of a channel's link statistics: `penelope/<node>/<channel>/link`.
pub const LINK: &str = "link";
/// The stream of what a bridged channel's end on this node sends back to the operator station
/// (its robot's pose and sensed wrench): `penelope/<node>/<channel>/feedback`.
pub const FEEDBACK: &str = "feedback";
/// The queryable of a node's object tree: `penelope/<node>/objects` (every object) and
/// `penelope/<node>/objects/<name>` (one).
pub const OBJECTS: &str = "objects";

/// The key expression `penelope/<node>/<object>/<stream>`.
pub fn stream_key(node: &str, object: &str, stream: &str) -> String {
    format!("{KEY_ROOT}/{node}/{object}/{stream}")
}

/// The key expression of a node's object tree, `penelope/<node>/objects`.
pub fn objects_key(node: &str) -> String {
    format!("{KEY_ROOT}/{node}/{OBJECTS}")
}

/// The operator pose a bridged channel takes is the runtime's (one format for every bridge).
pub use penelope_runtime::objects::bridged::{
    MAX_POSITION_M, OPERATOR_POSE_LEN, OPERATOR_POSE_TAG, OperatorPose, PoseError,
    QUATERNION_NORM_TOLERANCE,
};

/// A tick's JSON message on `…/telemetry`: the serde form of [`TickRecord`] (what a
/// recording's `/controllers/<name>` channel holds).
///
/// # Errors
/// A JSON error (none for finite and non-finite numbers alike: serde_json writes `null`).
pub fn tick_message(record: &TickRecord) -> Result<Vec<u8>, serde_json::Error> {
    serde_json::to_vec(record)
}

/// A safety event's JSON message on `…/events` (a recording's `/safety` message): tick
/// `record` of `controller`, after a tick whose state and fault were `previous` (`None`: the
/// first tick seen). `None` when nothing changed and no event was raised.
pub fn event_message(
    controller: &str,
    record: &TickRecord,
    previous: Option<(SafetyState, Option<FaultCause>)>,
) -> Option<Vec<u8>> {
    let s = &record.sample;
    let changed = previous != Some((s.state, s.fault));
    if !changed && s.events.is_empty() {
        return None;
    }
    let events: Vec<&str> = s.events.iter().map(|e| e.as_str()).collect();
    serde_json::to_vec(&json!({
        "time_ns": s.time.as_nanos(),
        "controller": controller,
        "seq": s.seq,
        "state": s.state.as_str(),
        "previous_state": previous.map(|(p, _)| p.as_str()),
        "fault": s.fault.map(|f| f.to_string()),
        "events": events,
    }))
    .ok()
}

/// What a bridged channel's end sent, as its JSON message on `…/feedback`: the sample's
/// sequence, time (ns, the node's clock), its robot's tool pose (position m, orientation
/// `[w, x, y, z]`) and sensed wrench (N, N·m, the robot's base frame) where the sample has them.
pub fn feedback_message(sample: &TeleopSample) -> Vec<u8> {
    let (pose, wrench) = (sample.reference.pose(), sample.reference.wrench());
    let position = pose.map(|p| [p.translation.x, p.translation.y, p.translation.z]);
    let orientation = pose.map(|p| {
        let q = p.rotation.quaternion();
        [q.w, q.i, q.j, q.k]
    });
    serde_json::to_vec(&json!({
        "sequence": sample.sequence,
        "time_ns": sample.sent.as_nanos(),
        "position": position,
        "orientation": orientation,
        "force": wrench.map(|w| [w.force.x, w.force.y, w.force.z]),
        "torque": wrench.map(|w| [w.torque.x, w.torque.y, w.torque.z]),
    }))
    .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> OperatorPose {
        OperatorPose {
            clutch: false,
            position: [0.5, -0.25, 1.0],
            orientation: [1.0, 0.0, 0.0, 0.0],
        }
    }

    #[test]
    fn a_pose_reads_back_as_written() {
        let p = pose();
        assert_eq!(OperatorPose::decode(&p.encode()), Ok(p));
        let held = OperatorPose { clutch: true, ..p };
        assert_eq!(OperatorPose::decode(&held.encode()), Ok(held));
    }

    #[test]
    fn malformed_poses_are_refused_with_their_reason() {
        let good = pose().encode();
        assert_eq!(
            OperatorPose::decode(&good[..57]),
            Err(PoseError::Length(57))
        );
        assert_eq!(OperatorPose::decode(&[]), Err(PoseError::Length(0)));
        let mut b = good;
        b[0] = 2;
        assert_eq!(OperatorPose::decode(&b), Err(PoseError::Tag(2)));
        let mut b = good;
        b[1] = 7;
        assert_eq!(OperatorPose::decode(&b), Err(PoseError::Clutch(7)));
        let nan = OperatorPose {
            position: [f64::NAN, 0.0, 0.0],
            ..pose()
        };
        assert_eq!(
            OperatorPose::decode(&nan.encode()),
            Err(PoseError::NotFinite)
        );
        let far = OperatorPose {
            position: [1e3, 0.0, 0.0],
            ..pose()
        };
        assert_eq!(
            OperatorPose::decode(&far.encode()),
            Err(PoseError::OutOfReach)
        );
        let skew = OperatorPose {
            orientation: [1.0, 1.0, 0.0, 0.0],
            ..pose()
        };
        assert_eq!(
            OperatorPose::decode(&skew.encode()),
            Err(PoseError::NotUnit)
        );
    }

    #[test]
    fn keys_follow_node_object_stream() {
        assert_eq!(
            stream_key("slave", "follow", TELEMETRY),
            "penelope/slave/follow/telemetry"
        );
        assert_eq!(objects_key("slave"), "penelope/slave/objects");
    }
}
