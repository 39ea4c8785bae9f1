//! A V4L2 capture device (a UVC webcam): opened, its format, size and rate negotiated,
//! memory-mapped streaming with a few buffers (the newest frame wins), each frame's kernel
//! timestamp mapped onto the node's monotonic clock and its image made into a JPEG.
//!
//! Blocking calls and allocation: a camera is read from its own (non-real-time) thread.

use std::path::Path;
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
use super::format::{NegotiatedFormat, PixelFormat, choose_format};
use super::intrinsics::PinholeIntrinsics;
use super::mjpeg::mjpeg_to_jpeg;
use super::settings::V4l2Settings;
use super::stamper::FrameStamper;
use super::stats::CaptureStats;
use super::timestamp::{BufferStamp, FLAG_ERROR, TimestampSource};
use super::yuyv::{encode_rgb_jpeg, yuyv_to_rgb};

/// `V4L2_CID_EXPOSURE_ABSOLUTE` (camera class base + 2): the exposure, in 100 µs units.
pub const CID_EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;
/// The exposure is read again every this many frames (auto exposure changes it; on UVC a
/// read is a USB control transfer, too slow for every frame).
const EXPOSURE_REFRESH_FRAMES: u64 = 30;
/// `POLLIN`.
const POLLIN: i16 = 0x0001;

/// One captured frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CapturedFrame {
    /// The driver's frame counter (`v4l2_buffer.sequence`).
    pub sequence: u32,
    /// The capture instant (middle of the exposure) on the node's monotonic clock, ns.
    pub capture_ns: u64,
    /// When it was dequeued, node monotonic clock, ns.
    pub dequeued_ns: u64,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// The image as a baseline JPEG file.
    pub jpeg: Vec<u8>,
    /// Where `capture_ns` came from.
    pub timestamp_source: TimestampSource,
    /// The exposure used for the capture instant, ns (`None`: the driver reports none).
    pub exposure_ns: Option<u64>,
}

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

/// A dequeued buffer's bytes and stamp, copied out so that its buffer goes back to the driver
/// at once.
struct RawBuffer {
    data: Vec<u8>,
    stamp: BufferStamp,
    dequeued_ns: u64,
}

/// A V4L2 camera, streaming.
pub struct V4l2Camera {
    settings: V4l2Settings,
    identity: DeviceIdentity,
    device: Device,
    stream: MmapStream<'static>,
    negotiated: NegotiatedFormat,
    intrinsics: PinholeIntrinsics,
    stamper: FrameStamper,
    exposure_ns: Option<u64>,
    /// The first frame, dequeued by `open` to show that the camera streams.
    pending: Option<RawBuffer>,
    /// Byte buffers of frames already handled, reused.
    spare: Vec<Vec<u8>>,
    rgb: Vec<u8>,
    stats: CaptureStats,
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
        let mut camera = V4l2Camera {
            settings: settings.clone(),
            identity,
            exposure_ns: read_exposure(&device),
            device,
            stream,
            negotiated,
            intrinsics,
            stamper: FrameStamper::new(settings.stamp_policy()),
            pending: None,
            spare: Vec::new(),
            rgb: Vec::new(),
            stats: CaptureStats::default(),
        };
        // The first dequeue queues every buffer and starts the stream.
        let first = match CaptureStream::next(&mut camera.stream) {
            Ok((bytes, meta)) => {
                let dequeued_ns = MonotonicClock::read().0;
                let used = (meta.bytesused as usize).min(bytes.len());
                let stamp = stamp_of(meta);
                RawBuffer {
                    data: bytes[..used].to_vec(),
                    stamp,
                    dequeued_ns,
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                return Err(V4l2Error::Timeout(settings.first_frame_timeout));
            }
            Err(e) => return Err(V4l2Error::from_io(path, "VIDIOC_STREAMON/DQBUF", e)),
        };
        camera.stamper.dequeued(&first.stamp, &mut camera.stats);
        camera.pending = Some(first);
        Ok(camera)
    }

    /// The next frame: the newest one the driver has (older ones waiting are dropped and
    /// counted), waiting up to `timeout` when none is ready. A garbled buffer is dropped,
    /// counted and returned as [`V4l2Error::Garbled`]; call again for the next frame.
    pub fn next(&mut self, timeout: Duration) -> Result<CapturedFrame, V4l2Error> {
        let mut raw = match self.pending.take() {
            Some(raw) => raw,
            None => self
                .dequeue_within(timeout)?
                .ok_or(V4l2Error::Timeout(timeout))?,
        };
        // The newest frame wins: any buffer already filled is newer than `raw`.
        for _ in 0..self.negotiated.buffers {
            match self.dequeue_within(Duration::ZERO)? {
                Some(newer) => {
                    self.stats.dropped_behind += 1;
                    let older = std::mem::replace(&mut raw, newer);
                    self.spare.push(older.data);
                }
                None => break,
            }
        }
        let result = self.frame_of(&raw);
        self.spare.push(raw.data);
        result
    }

    /// A filled buffer if one comes within `wait`, copied out (its buffer is re-queued at the
    /// next dequeue).
    fn dequeue_within(&mut self, wait: Duration) -> Result<Option<RawBuffer>, V4l2Error> {
        let path = self.settings.device.as_path();
        let ms = i32::try_from(wait.as_millis()).unwrap_or(i32::MAX);
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
        let mut data = self.spare.pop().unwrap_or_default();
        data.clear();
        data.extend_from_slice(&bytes[..used]);
        let stamp = stamp_of(meta);
        self.stamper.dequeued(&stamp, &mut self.stats);
        Ok(Some(RawBuffer {
            data,
            stamp,
            dequeued_ns,
        }))
    }

    /// The frame a buffer holds, stamped; a garbled one is counted.
    fn frame_of(&mut self, raw: &RawBuffer) -> Result<CapturedFrame, V4l2Error> {
        let garbled = |reason: String| V4l2Error::Garbled {
            sequence: raw.stamp.sequence,
            reason,
        };
        let (width, height) = (self.negotiated.width, self.negotiated.height);
        let jpeg = if raw.stamp.flags & FLAG_ERROR != 0 {
            Err(garbled("the driver flagged the buffer as corrupted".into()))
        } else {
            match self.negotiated.format {
                PixelFormat::Mjpeg => match mjpeg_to_jpeg(&raw.data) {
                    Ok(f) if f.size == (width, height) => {
                        self.stats.huffman_tables_inserted += u64::from(f.tables_inserted);
                        Ok(f.bytes)
                    }
                    Ok(f) => Err(garbled(format!(
                        "a {}x{} JPEG, {width}x{height} negotiated",
                        f.size.0, f.size.1
                    ))),
                    Err(e) => Err(garbled(e.to_string())),
                },
                PixelFormat::Yuyv => yuyv_to_rgb(
                    &raw.data,
                    width,
                    height,
                    self.negotiated.stride,
                    &mut self.rgb,
                )
                .and_then(|()| {
                    encode_rgb_jpeg(&self.rgb, width, height, self.settings.jpeg_quality)
                })
                .map_err(|e| garbled(e.to_string())),
            }
        };
        let jpeg = match jpeg {
            Ok(jpeg) => jpeg,
            Err(e) => {
                self.stats.garbled += 1;
                return Err(e);
            }
        };
        if self.stats.frames % EXPOSURE_REFRESH_FRAMES == EXPOSURE_REFRESH_FRAMES - 1 {
            self.exposure_ns = read_exposure(&self.device);
        }
        let instant = self.stamper.stamp(
            &raw.stamp,
            raw.dequeued_ns,
            self.exposure_ns,
            &mut self.stats,
        );
        self.stats.frames += 1;
        Ok(CapturedFrame {
            sequence: raw.stamp.sequence,
            capture_ns: instant.capture_ns,
            dequeued_ns: raw.dequeued_ns,
            width,
            height,
            jpeg,
            timestamp_source: instant.source,
            exposure_ns: self.exposure_ns,
        })
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
        self.stats
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
