//! Cameras on a node: `sensor/sim-camera`, a simulated camera watching a simulated robot on the
//! same node, its frames served on the common clock.
//!
//! - [`config`]: its keys and their checks;
//! - [`thread`]: the camera thread, fed by the watched robot's ticks (the plant's truth),
//!   rendering, encoding and releasing frames;
//! - [`subscribers`]: per subscriber a bounded queue that drops the oldest frame, the camera
//!   link's faults, the counts.
//!
//! `docs/cameras.md` is the guide.

pub mod config;
pub mod subscribers;
pub mod thread;

pub use config::{CameraSetup, SimCameraConfig};
pub use subscribers::{FrameSink, FrameSubscriberStats, FrameSubscriptionSpec, FrameSubscriptions};
pub use thread::{CameraRunner, CameraShared, CameraWorld, SendClock};
