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
