//! Cameras on Linux V4L2 (UVC webcams): capture with memory-mapped streaming, the kernel's
//! capture timestamps mapped onto the node's monotonic clock (the middle of the exposure), and
//! frames out as JPEG. The guide is `docs/v4l2.md`.
//!
//! - [`V4l2Camera`]: open, negotiate, [`next`](V4l2Camera::next) frame, counters.
//! - [`FramePipeline`]: dequeued buffers to frames (the newest wins, garbled ones dropped).
//! - [`timestamp`]: a buffer's stamp and flags to a capture instant, or a counted fallback.
//! - [`mjpeg`]: MJPEG buffers checked and given the standard Huffman tables when missing.
//! - [`yuyv`]: raw YUYV frames to RGB and JPEG.
//! - [`probe`]: what a device offers (formats, sizes, rates).

mod camera;
mod error;
mod format;
mod intrinsics;
pub mod mjpeg;
mod pipeline;
mod probe;
mod sequence;
mod settings;
mod stamper;
mod stats;
pub mod timestamp;
pub mod yuyv;

pub use camera::{CID_EXPOSURE_ABSOLUTE, DeviceIdentity, V4l2Camera};
pub use error::V4l2Error;
pub use format::{FormatPreference, NegotiatedFormat, PixelFormat, choose_format};
pub use intrinsics::PinholeIntrinsics;
pub use pipeline::{BufferSource, CapturedFrame, FramePipeline, RawBuffer};
pub use probe::{DeviceReport, FormatReport, SizeReport, probe};
pub use sequence::SequenceTracker;
pub use settings::V4l2Settings;
pub use stamper::FrameStamper;
pub use stats::CaptureStats;
pub use timestamp::{FallbackReason, TimestampSource};
