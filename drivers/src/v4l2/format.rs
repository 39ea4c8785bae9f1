//! The pixel format negotiated with the driver: MJPEG preferred (the camera compresses, the
//! frame passes through), else YUYV (converted and encoded here).

use std::fmt;

/// A pixel format this module can turn into JPEG.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelFormat {
    /// Motion JPEG (`MJPG`, or `JPEG` as some drivers call it).
    Mjpeg,
    /// YUV 4:2:2 interleaved (`YUYV`).
    Yuyv,
}

impl PixelFormat {
    /// The format's four-character code as V4L2 names it.
    pub fn fourcc(self) -> [u8; 4] {
        match self {
            PixelFormat::Mjpeg => *b"MJPG",
            PixelFormat::Yuyv => *b"YUYV",
        }
    }

    /// The format a driver's four-character code names, if usable here.
    pub fn from_fourcc(code: [u8; 4]) -> Option<Self> {
        match &code {
            b"MJPG" | b"JPEG" => Some(PixelFormat::Mjpeg),
            b"YUYV" => Some(PixelFormat::Yuyv),
            _ => None,
        }
    }
}

impl fmt::Display for PixelFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PixelFormat::Mjpeg => "MJPEG",
            PixelFormat::Yuyv => "YUYV",
        })
    }
}

/// Which pixel format to ask for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FormatPreference {
    /// MJPEG if offered, else YUYV.
    #[default]
    Auto,
    /// MJPEG only.
    Mjpeg,
    /// YUYV only.
    Yuyv,
}

/// The format (and the code the driver offers it under) to ask for, given the driver's
/// offered four-character codes; `None` when nothing usable is offered.
pub fn choose_format(
    offered: &[[u8; 4]],
    preference: FormatPreference,
) -> Option<(PixelFormat, [u8; 4])> {
    let find = |wanted: PixelFormat| {
        offered
            .iter()
            .find(|&&c| PixelFormat::from_fourcc(c) == Some(wanted))
            .map(|&c| (wanted, c))
    };
    match preference {
        FormatPreference::Auto => find(PixelFormat::Mjpeg).or_else(|| find(PixelFormat::Yuyv)),
        FormatPreference::Mjpeg => find(PixelFormat::Mjpeg),
        FormatPreference::Yuyv => find(PixelFormat::Yuyv),
    }
}

/// What the driver agreed to: this is what the camera runs at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NegotiatedFormat {
    /// The pixel format.
    pub format: PixelFormat,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Bytes a line of a raw frame (`bytesperline`).
    pub stride: u32,
    /// Frames per second the driver set (`None`: it does not say).
    pub rate_hz: Option<f64>,
    /// Memory-mapped buffers asked for (a driver may allocate more; `v4l` does not say).
    pub buffers: u32,
}

impl fmt::Display for NegotiatedFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}x{}", self.format, self.width, self.height)?;
        match self.rate_hz {
            Some(r) => write!(f, " at {r:.2} fps")?,
            None => write!(f, " at an unreported rate")?,
        }
        write!(f, ", {} buffers", self.buffers)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mjpeg_is_preferred_then_yuyv_and_others_are_unusable() {
        let offered = [*b"YUYV", *b"MJPG", *b"H264"];
        assert_eq!(
            choose_format(&offered, FormatPreference::Auto),
            Some((PixelFormat::Mjpeg, *b"MJPG"))
        );
        assert_eq!(
            choose_format(&offered, FormatPreference::Yuyv),
            Some((PixelFormat::Yuyv, *b"YUYV"))
        );
        assert_eq!(
            choose_format(&[*b"YUYV"], FormatPreference::Auto),
            Some((PixelFormat::Yuyv, *b"YUYV"))
        );
        assert_eq!(
            choose_format(&[*b"JPEG"], FormatPreference::Mjpeg),
            Some((PixelFormat::Mjpeg, *b"JPEG"))
        );
        assert_eq!(choose_format(&[*b"YUYV"], FormatPreference::Mjpeg), None);
        assert_eq!(
            choose_format(&[*b"H264", *b"NV12"], FormatPreference::Auto),
            None
        );
    }
}
