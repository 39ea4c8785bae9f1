//! Cameras on a node: `sensor/sim-camera`, a simulated camera watching a simulated robot on the
//! same node, and `sensor/camera`, a V4L2 device; their frames served on the common clock.
//!
//! - [`config`]: their keys and their checks;
//! - [`capture`]: a device camera's thread, taking frames from a [`FrameSource`];
//! - [`thread`]: the camera thread, fed by the watched robot's ticks (the plant's truth),
//!   rendering, encoding and releasing frames;
//! - the subscribers' side (per subscriber a bounded queue that drops the oldest frame, the
//!   camera link's faults, the counts) is with the node's other subscriptions, in
//!   [`crate::objects::runtime`] (`FrameSubscriptions`).
//!
//! `docs/cameras.md` is the guide.

pub mod capture;
pub mod config;
pub mod thread;

pub use capture::{FrameSource, SourceOpener};
pub use config::{CameraConfig, CameraSetup, SimCameraConfig};
pub use thread::{CameraRunner, CameraShared, CameraWorld, SendClock};

use penelope_drivers::pinhole::PinholeIntrinsics;
use penelope_hal::Pose;
use penelope_protocol::proto::{CameraModelMsg, PoseMsg};

/// The model camera `name`'s frames carry: its intrinsics, and its pose in the base frame of
/// the robot it watches when it is placed.
fn model_msg(name: &str, k: &PinholeIntrinsics, placed: Option<(&Pose, &str)>) -> CameraModelMsg {
    CameraModelMsg {
        frame_id: name.to_string(),
        width: k.width,
        height: k.height,
        fx: k.fx,
        fy: k.fy,
        cx: k.cx,
        cy: k.cy,
        pose_in_robot_base: placed.map(|(pose, _)| PoseMsg::from(pose)),
        robot: placed.map(|(_, robot)| robot.to_string()),
    }
}
