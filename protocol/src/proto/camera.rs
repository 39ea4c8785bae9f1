//! Camera frames: what a `sensor/sim-camera` or `sensor/camera` pushes to a subscriber
//! ([`ServerMsg::Frames`](super::ServerMsg::Frames) after [`Call::Subscribe`](super::Call::Subscribe)
//! on the camera), each frame stamped with its capture instant on the system's common clock,
//! so that a viewer can put beside it the force and pose samples measured at that instant.

use serde::{Deserialize, Serialize};

use super::PoseMsg;

/// How a frame's bytes are encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ImageEncoding {
    /// A baseline JPEG (JFIF) image.
    Jpeg,
}

impl ImageEncoding {
    /// Its name as `foxglove.CompressedImage`'s `format` and an HTTP media subtype give it.
    pub fn name(self) -> &'static str {
        match self {
            ImageEncoding::Jpeg => "jpeg",
        }
    }
}

/// A camera's optics and placement: the pinhole intrinsics of its (undistorted) image, and where
/// it looks from, so that a viewer can draw a point of the robot's world where the camera sees
/// it (a force arrow at the tool, say).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraModelMsg {
    /// The camera's optical frame's name (`foxglove.CameraCalibration`'s `frame_id`).
    pub frame_id: String,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal lengths, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// The optical frame (x right, y down, z forward) in the base frame of the robot the
    /// camera watches (`None`: not known, as for a camera nobody placed).
    pub pose_in_robot_base: Option<PoseMsg>,
    /// The robot it watches, by its name on its node (`None`: none).
    pub robot: Option<String>,
}

/// One camera frame, stamped on the system's common clock (ns).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraFrame {
    /// The camera's frame number, from 0 (a gap is a frame lost before it reached this
    /// subscriber: dropped from a full queue or lost on the link).
    pub seq: u64,
    /// The capture instant: the middle of the exposure.
    pub capture_ns: u64,
    /// When the frame existed on the camera's node: read out (simulated) or dequeued from the
    /// driver (V4L2).
    pub ready_ns: u64,
    /// When the node handed it to this subscriber's connection (after encoding and the camera
    /// link's faults).
    pub sent_ns: u64,
    /// The encoding of `data`.
    pub encoding: ImageEncoding,
    /// The encoded image.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
    /// The camera's optics and placement.
    pub model: CameraModelMsg,
}

/// Frames of one subscription (one per push: a frame is tens of kilobytes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameBatch {
    /// The subscription's id.
    pub subscription: u64,
    /// Frames this subscription lost so far: the oldest dropped from its full queue, or lost
    /// on the camera's link.
    pub dropped: u64,
    /// Frames in capture order.
    pub frames: Vec<CameraFrame>,
}
