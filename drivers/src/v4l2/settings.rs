//! What a V4L2 camera is asked for. The driver's answer (format, size, rate) is what is used,
//! and reported ([`NegotiatedFormat`](super::NegotiatedFormat)).

use std::path::PathBuf;
use std::time::Duration;

use super::error::V4l2Error;
use super::format::FormatPreference;
use super::timestamp::StampPolicy;

/// A V4L2 camera's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct V4l2Settings {
    /// The device node (`/dev/video0`).
    pub device: PathBuf,
    /// Requested width, pixels (the driver picks the nearest it has).
    pub width: u32,
    /// Requested height, pixels.
    pub height: u32,
    /// Requested frame rate, frames per second.
    pub rate_hz: u32,
    /// Which pixel format to ask for.
    pub format: FormatPreference,
    /// The sensor's readout, µs: from the end of the exposure to the end of the frame, for
    /// drivers that stamp the end of the frame.
    pub readout_us: u32,
    /// Capture instant to dequeue, µs, assumed when the kernel's stamp cannot be used.
    pub fallback_latency_us: u32,
    /// A kernel stamp older than this before its dequeue is refused, ms.
    pub max_stamp_age_ms: u32,
    /// Memory-mapped buffers (2..=8: few, so that a frame is never old; the newest wins).
    pub buffers: u32,
    /// JPEG quality (1..=100) of raw (YUYV) frames; MJPEG frames pass through.
    pub jpeg_quality: u8,
    /// Horizontal field of view, degrees: the pinhole intrinsics (V4L2 gives none).
    pub hfov_deg: f64,
    /// How long `open` waits for the first frame (a UVC camera takes up to a second or two).
    pub first_frame_timeout: Duration,
}

impl V4l2Settings {
    /// 640x480 at 30 fps, MJPEG preferred, three buffers, 10 ms readout, 50 ms fallback
    /// latency, stamps at most 500 ms old, JPEG quality 85, 60° field of view.
    pub fn new(device: impl Into<PathBuf>) -> Self {
        V4l2Settings {
            device: device.into(),
            width: 640,
            height: 480,
            rate_hz: 30,
            format: FormatPreference::Auto,
            readout_us: 10_000,
            fallback_latency_us: 50_000,
            max_stamp_age_ms: 500,
            buffers: 3,
            jpeg_quality: 85,
            hfov_deg: 60.0,
            first_frame_timeout: Duration::from_secs(5),
        }
    }

    /// Checks the settings' ranges.
    pub fn validate(&self) -> Result<(), V4l2Error> {
        let bad = |why: String| Err(V4l2Error::BadSettings(why));
        if self.width == 0 || self.height == 0 || self.width > 65535 || self.height > 65535 {
            return bad(format!("size {}x{}", self.width, self.height));
        }
        if self.rate_hz == 0 || self.rate_hz > 1000 {
            return bad(format!("rate {} Hz (1..=1000)", self.rate_hz));
        }
        if !(2..=8).contains(&self.buffers) {
            return bad(format!("{} buffers (2..=8)", self.buffers));
        }
        if !(1..=100).contains(&self.jpeg_quality) {
            return bad(format!("JPEG quality {} (1..=100)", self.jpeg_quality));
        }
        if !(self.hfov_deg > 0.0 && self.hfov_deg < 180.0) {
            return bad(format!("field of view {}° (0..180)", self.hfov_deg));
        }
        if self.max_stamp_age_ms == 0 {
            return bad("max_stamp_age_ms 0".into());
        }
        Ok(())
    }

    /// The timestamp mapping's policy from these settings.
    pub fn stamp_policy(&self) -> StampPolicy {
        StampPolicy {
            readout_ns: u64::from(self.readout_us) * 1_000,
            fallback_latency_ns: u64::from(self.fallback_latency_us) * 1_000,
            max_age_ns: u64::from(self.max_stamp_age_ms) * 1_000_000,
            future_tolerance_ns: 1_000_000,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_settings_validate_and_bad_ones_are_refused() {
        let s = V4l2Settings::new("/dev/video0");
        s.validate().unwrap();
        assert_eq!(s.stamp_policy().max_age_ns, 500_000_000);
        for bad in [
            V4l2Settings {
                buffers: 1,
                ..s.clone()
            },
            V4l2Settings {
                rate_hz: 0,
                ..s.clone()
            },
            V4l2Settings {
                width: 0,
                ..s.clone()
            },
            V4l2Settings {
                jpeg_quality: 0,
                ..s.clone()
            },
            V4l2Settings {
                hfov_deg: 200.0,
                ..s.clone()
            },
        ] {
            assert!(
                matches!(bad.validate(), Err(V4l2Error::BadSettings(_))),
                "{bad:?}"
            );
        }
    }
}
