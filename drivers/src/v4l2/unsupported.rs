//! [`V4l2Camera`] in a build without the `v4l2` feature: opening a camera says so
//! ([`V4l2Error::Unsupported`]), and nothing else can be reached.

use std::convert::Infallible;
use std::time::Duration;

use super::error::V4l2Error;
use super::format::NegotiatedFormat;
use super::pipeline::CapturedFrame;
use super::settings::V4l2Settings;
use super::stats::CaptureStats;
use crate::pinhole::PinholeIntrinsics;

/// `V4L2_CID_EXPOSURE_ABSOLUTE`: the exposure in 100 µs units.
pub const CID_EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;

/// What the driver says the device is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceIdentity {
    /// The driver (`uvcvideo`).
    pub driver: String,
    /// The device's name.
    pub card: String,
    /// Where it is attached (`usb-0000:00:14.0-1`).
    pub bus: String,
}

/// A V4L2 camera: none can be opened in this build.
#[derive(Debug)]
pub struct V4l2Camera {
    never: Infallible,
}

impl V4l2Camera {
    /// Always [`V4l2Error::Unsupported`] in this build (the settings are checked first).
    ///
    /// # Errors
    /// The settings' own error, else [`V4l2Error::Unsupported`].
    pub fn open(settings: &V4l2Settings) -> Result<V4l2Camera, V4l2Error> {
        settings.validate()?;
        Err(V4l2Error::Unsupported(settings.device.clone()))
    }

    /// The next frame.
    ///
    /// # Errors
    /// Never: no camera exists to ask.
    pub fn next(&mut self, _timeout: Duration) -> Result<CapturedFrame, V4l2Error> {
        match self.never {}
    }

    /// The format in use.
    pub fn negotiated(&self) -> NegotiatedFormat {
        match self.never {}
    }

    /// The pinhole model.
    pub fn intrinsics(&self) -> PinholeIntrinsics {
        match self.never {}
    }

    /// The counters.
    pub fn stats(&self) -> CaptureStats {
        match self.never {}
    }

    /// What the driver says the device is.
    pub fn identity(&self) -> &DeviceIdentity {
        match self.never {}
    }

    /// The settings it was opened with.
    pub fn settings(&self) -> &V4l2Settings {
        match self.never {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_build_without_v4l2_says_so_when_a_camera_is_opened() {
        let err = V4l2Camera::open(&V4l2Settings::new("/dev/video0")).unwrap_err();
        assert!(matches!(err, V4l2Error::Unsupported(_)), "{err}");
        assert!(err.to_string().contains("--features v4l2"), "{err}");
    }
}
