//! A V4L2 capture device (a UVC webcam): opened, its format, size and rate negotiated,
//! memory-mapped streaming with a few buffers (the newest frame wins), each frame's kernel
//! timestamp mapped onto the node's monotonic clock and its image made into a JPEG.
//!
//! Blocking calls and allocation: a camera is read from its own (non-real-time) thread.

use std::path::{Path, PathBuf};
use std::time::Duration;

use penelope_rt_core::clock::MonotonicClock;
use v4l::buffer::Type as BufferType;
use v4l::capability::Flags as CapabilityFlags;
use v4l::io::mmap::Stream as MmapStream;
use v4l::io::traits::CaptureStream;
use v4l::video::Capture;
use v4l::video::capture::Parameters;
use v4l::{Device, Format, FourCC};

use super::error::V4l2Error;
use super::format::{NegotiatedFormat, choose_format};
use super::pipeline::{BufferSource, CapturedFrame, FramePipeline, RawBuffer};
use super::settings::V4l2Settings;
use super::stamper::FrameStamper;
use super::stats::CaptureStats;
use super::timestamp::BufferStamp;
use crate::pinhole::PinholeIntrinsics;

/// `V4L2_CID_EXPOSURE_ABSOLUTE` (camera class base + 2): the exposure, in 100 µs units.
pub const CID_EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;
/// The exposure is read again every this many frames (auto exposure changes it; on UVC a
/// read is a USB control transfer, too slow for every frame).
const EXPOSURE_REFRESH_FRAMES: u64 = 30;
/// `POLLIN`.
const POLLIN: i16 = 0x0001;

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

/// The device's memory-mapped stream as a [`BufferSource`].
struct DeviceStream {
    path: PathBuf,
    stream: MmapStream<'static>,
    /// The first frame, dequeued by `open` to show that the camera streams.
    pending: Option<RawBuffer>,
}

impl BufferSource for DeviceStream {
    fn dequeue(
        &mut self,
        wait: Duration,
        mut reuse: Vec<u8>,
    ) -> Result<Option<RawBuffer>, V4l2Error> {
        if let Some(first) = self.pending.take() {
            return Ok(Some(first));
        }
        let path = self.path.as_path();
        let ms = i32::try_from(wait.as_millis()).unwrap_or(i32::MAX);
        // Poll first: `v4l` re-queues the previous buffer before it waits, and a wait of its
        // own that timed out would leave it queueing that buffer twice on the next call.
        match self.stream.handle().poll(POLLIN, ms) {
            Ok(0) => return Ok(None),
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => return Ok(None),
            Err(e) => return Err(V4l2Error::from_io(path, "poll", e)),
        }
        let (bytes, meta) = CaptureStream::next(&mut self.stream)
            .map_err(|e| V4l2Error::from_io(path, "VIDIOC_DQBUF", e))?;
        let dequeued_ns = MonotonicClock::read().0;
        let used = (meta.bytesused as usize).min(bytes.len());
        reuse.clear();
        reuse.extend_from_slice(&bytes[..used]);
        Ok(Some(RawBuffer {
            data: reuse,
            stamp: stamp_of(meta),
            dequeued_ns,
        }))
    }
}

/// A V4L2 camera, streaming.
pub struct V4l2Camera {
    settings: V4l2Settings,
    identity: DeviceIdentity,
    device: Device,
    source: DeviceStream,
    pipeline: FramePipeline,
    negotiated: NegotiatedFormat,
    intrinsics: PinholeIntrinsics,
    exposure_ns: Option<u64>,
}

/// Opens a device node and checks it is a V4L2 device that captures video by streaming.
pub(super) fn open_capture_device(path: &Path) -> Result<(Device, DeviceIdentity), V4l2Error> {
    let device = Device::with_path(path).map_err(|e| V4l2Error::from_io(path, "open", e))?;
    let not_capture = |driver: String, card: String| V4l2Error::NotACaptureDevice {
        device: path.to_path_buf(),
        driver,
        card,
    };
    let caps = match device.query_caps() {
        Ok(caps) => caps,
        // ENOTTY: not a V4L2 device at all (a file, another kind of node)
        Err(e) if e.raw_os_error() == Some(nix::errno::Errno::ENOTTY as i32) => {
            return Err(not_capture("none".into(), "not a V4L2 device".into()));
        }
        Err(e) => return Err(V4l2Error::from_io(path, "VIDIOC_QUERYCAP", e)),
    };
    if !caps
        .capabilities
        .contains(CapabilityFlags::VIDEO_CAPTURE | CapabilityFlags::STREAMING)
    {
        return Err(not_capture(caps.driver, caps.card));
    }
    let identity = DeviceIdentity {
        driver: caps.driver,
        card: caps.card,
        bus: caps.bus,
    };
    Ok((device, identity))
}

/// The exposure the driver reports, ns (`None`: no such control, or not readable).
fn read_exposure(device: &Device) -> Option<u64> {
    match device.control(CID_EXPOSURE_ABSOLUTE).ok()?.value {
        v4l::control::Value::Integer(units) if units > 0 => Some(units as u64 * 100_000),
        _ => None,
    }
}

impl V4l2Camera {
    /// Opens the camera, negotiates its format, size and rate (the driver's answer is used:
    /// see [`negotiated`](Self::negotiated)), starts streaming and waits for the first frame.
    pub fn open(settings: &V4l2Settings) -> Result<V4l2Camera, V4l2Error> {
        settings.validate()?;
        let path = settings.device.as_path();
        let io = |what: &'static str| move |e| V4l2Error::from_io(path, what, e);
        let (device, identity) = open_capture_device(path)?;

        let offered: Vec<[u8; 4]> = device
            .enum_formats()
            .map_err(io("VIDIOC_ENUM_FMT"))?
            .iter()
            .map(|d| d.fourcc.repr)
            .collect();
        let no_format = || V4l2Error::NoUsableFormat {
            device: path.to_path_buf(),
            offered: offered
                .iter()
                .map(|c| String::from_utf8_lossy(c).into_owned())
                .collect(),
        };
        let (format, code) = choose_format(&offered, settings.format).ok_or_else(no_format)?;
        let set = device
            .set_format(&Format::new(
                settings.width,
                settings.height,
                FourCC::new(&code),
            ))
            .map_err(io("VIDIOC_S_FMT"))?;
        if set.fourcc.repr != code {
            return Err(no_format());
        }
        // The rate: what the driver set; a driver without frame-interval control says nothing.
        let params = device
            .set_params(&Parameters::with_fps(settings.rate_hz))
            .or_else(|_| device.params())
            .ok();
        let rate_hz = params
            .map(|p| p.interval)
            .filter(|i| i.numerator > 0 && i.denominator > 0)
            .map(|i| f64::from(i.denominator) / f64::from(i.numerator));
        let negotiated = NegotiatedFormat {
            format,
            width: set.width,
            height: set.height,
            stride: set.stride,
            rate_hz,
            buffers: settings.buffers,
        };
        let intrinsics =
            PinholeIntrinsics::from_horizontal_fov(set.width, set.height, settings.hfov_deg)
                .ok_or_else(|| {
                    V4l2Error::BadSettings(format!("field of view {}°", settings.hfov_deg))
                })?;

        let mut stream =
            MmapStream::with_buffers(&device, BufferType::VideoCapture, settings.buffers)
                .map_err(io("VIDIOC_REQBUFS"))?;
        // A bound on every wait inside the crate: ours poll first, so it is never reached
        // unless the device stops answering.
        stream.set_timeout(settings.first_frame_timeout);
        // The first dequeue queues every buffer and starts the stream.
        let first = match CaptureStream::next(&mut stream) {
            Ok((bytes, meta)) => {
                let dequeued_ns = MonotonicClock::read().0;
                let used = (meta.bytesused as usize).min(bytes.len());
                RawBuffer {
                    data: bytes[..used].to_vec(),
                    stamp: stamp_of(meta),
                    dequeued_ns,
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                return Err(V4l2Error::Timeout(settings.first_frame_timeout));
            }
            Err(e) => return Err(V4l2Error::from_io(path, "VIDIOC_STREAMON/DQBUF", e)),
        };
        Ok(V4l2Camera {
            settings: settings.clone(),
            identity,
            exposure_ns: read_exposure(&device),
            device,
            source: DeviceStream {
                path: path.to_path_buf(),
                stream,
                pending: Some(first),
            },
            pipeline: FramePipeline::new(
                negotiated,
                settings.jpeg_quality,
                FrameStamper::new(settings.stamp_policy()),
            ),
            negotiated,
            intrinsics,
        })
    }

    /// The next frame: the newest one the driver has (older ones waiting are dropped and
    /// counted), waiting up to `timeout` when none is ready. A garbled buffer is dropped,
    /// counted and returned as [`V4l2Error::Garbled`]; call again for the next frame.
    pub fn next(&mut self, timeout: Duration) -> Result<CapturedFrame, V4l2Error> {
        let frames = self.pipeline.stats().frames;
        if frames % EXPOSURE_REFRESH_FRAMES == EXPOSURE_REFRESH_FRAMES - 1 {
            self.exposure_ns = read_exposure(&self.device);
        }
        self.pipeline
            .next(&mut self.source, timeout, self.exposure_ns)
    }

    /// What the driver agreed to.
    pub fn negotiated(&self) -> NegotiatedFormat {
        self.negotiated
    }

    /// The pinhole intrinsics from the negotiated size and the configured field of view.
    pub fn intrinsics(&self) -> PinholeIntrinsics {
        self.intrinsics
    }

    /// The counters since `open`.
    pub fn stats(&self) -> CaptureStats {
        self.pipeline.stats()
    }

    /// What the driver says the device is.
    pub fn identity(&self) -> &DeviceIdentity {
        &self.identity
    }

    /// The settings it was opened with.
    pub fn settings(&self) -> &V4l2Settings {
        &self.settings
    }
}

/// The stamp fields of a dequeued buffer's metadata (`time_t` is 64 bits here, 32 on some
/// 32-bit targets: the conversion is the identity on this one).
#[allow(clippy::useless_conversion)]
fn stamp_of(meta: &v4l::buffer::Metadata) -> BufferStamp {
    BufferStamp::from_timeval(
        i64::from(meta.timestamp.sec),
        i64::from(meta.timestamp.usec),
        meta.flags.bits(),
        meta.sequence,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_device_node_is_no_such_device() {
        let s = V4l2Settings::new("/dev/penelope-no-such-video-node");
        assert!(matches!(
            V4l2Camera::open(&s),
            Err(V4l2Error::NoSuchDevice(_))
        ));
    }

    #[test]
    fn a_node_that_is_not_v4l2_is_not_a_capture_device() {
        let s = V4l2Settings::new("/dev/null");
        match V4l2Camera::open(&s) {
            Err(V4l2Error::NotACaptureDevice { device, .. }) => {
                assert_eq!(device, Path::new("/dev/null"))
            }
            Err(other) => panic!("{other}"),
            Ok(_) => panic!("/dev/null opened as a camera"),
        }
    }

    #[test]
    fn bad_settings_are_refused_before_the_device_is_opened() {
        let s = V4l2Settings {
            buffers: 0,
            ..V4l2Settings::new("/dev/null")
        };
        assert!(matches!(
            V4l2Camera::open(&s),
            Err(V4l2Error::BadSettings(_))
        ));
    }
}
