//! What a V4L2 device offers: its pixel formats, their frame sizes and rates (`penelope camera
//! probe`).

use std::path::Path;

#[cfg(feature = "v4l2")]
use v4l::frameinterval::FrameIntervalEnum;
#[cfg(feature = "v4l2")]
use v4l::framesize::FrameSizeEnum;
#[cfg(feature = "v4l2")]
use v4l::video::Capture;
#[cfg(feature = "v4l2")]
use v4l::{Device, FourCC};

use super::camera::DeviceIdentity;
#[cfg(feature = "v4l2")]
use super::camera::open_capture_device;
use super::error::V4l2Error;
#[cfg(feature = "v4l2")]
use super::format::PixelFormat;

/// A device's formats, sizes and rates.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceReport {
    /// What the driver says it is.
    pub identity: DeviceIdentity,
    /// Its pixel formats.
    pub formats: Vec<FormatReport>,
}

/// One pixel format.
#[derive(Clone, Debug, PartialEq)]
pub struct FormatReport {
    /// Its four-character code.
    pub fourcc: String,
    /// The driver's description.
    pub description: String,
    /// Whether a camera here can use it (MJPEG or YUYV).
    pub usable: bool,
    /// Its frame sizes (for a stepwise range: the smallest and the largest).
    pub sizes: Vec<SizeReport>,
}

/// One frame size.
#[derive(Clone, Debug, PartialEq)]
pub struct SizeReport {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Its frame rates, fps (for a stepwise range: the lowest and the highest).
    pub rates_hz: Vec<f64>,
}

/// Lists what the device at `path` offers.
///
/// # Errors
/// [`V4l2Error::Unsupported`] in a build without the `v4l2` feature.
#[cfg(not(feature = "v4l2"))]
pub fn probe(path: &Path) -> Result<DeviceReport, V4l2Error> {
    Err(V4l2Error::Unsupported(path.to_path_buf()))
}

/// Lists what the device at `path` offers.
#[cfg(feature = "v4l2")]
pub fn probe(path: &Path) -> Result<DeviceReport, V4l2Error> {
    let (device, identity) = open_capture_device(path)?;
    let descriptions = device
        .enum_formats()
        .map_err(|e| V4l2Error::from_io(path, "VIDIOC_ENUM_FMT", e))?;
    let formats = descriptions
        .into_iter()
        .map(|d| FormatReport {
            fourcc: String::from_utf8_lossy(&d.fourcc.repr).into_owned(),
            usable: PixelFormat::from_fourcc(d.fourcc.repr).is_some(),
            sizes: sizes_of(&device, d.fourcc),
            description: d.description,
        })
        .collect();
    Ok(DeviceReport { identity, formats })
}

#[cfg(feature = "v4l2")]
fn sizes_of(device: &Device, fourcc: FourCC) -> Vec<SizeReport> {
    let mut sizes = Vec::new();
    for size in device.enum_framesizes(fourcc).unwrap_or_default() {
        let pairs = match size.size {
            FrameSizeEnum::Discrete(d) => vec![(d.width, d.height)],
            FrameSizeEnum::Stepwise(s) => {
                vec![(s.min_width, s.min_height), (s.max_width, s.max_height)]
            }
        };
        for (width, height) in pairs {
            let mut rates_hz = Vec::new();
            for interval in device
                .enum_frameintervals(fourcc, width, height)
                .unwrap_or_default()
            {
                let fractions = match interval.interval {
                    FrameIntervalEnum::Discrete(f) => vec![f],
                    // the longest interval is the lowest rate
                    FrameIntervalEnum::Stepwise(s) => vec![s.max, s.min],
                };
                rates_hz.extend(
                    fractions
                        .into_iter()
                        .filter(|f| f.numerator > 0)
                        .map(|f| f64::from(f.denominator) / f64::from(f.numerator)),
                );
            }
            sizes.push(SizeReport {
                width,
                height,
                rates_hz,
            });
        }
    }
    sizes
}
