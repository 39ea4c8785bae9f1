//! The cameras' configurations: `sensor/sim-camera`'s and `sensor/camera`'s keys, their
//! checks (the keys they share checked by one function), and the setups they make.

use penelope_drivers::sim::camera::{CameraTiming, PinholeCamera, SimCamera};
use penelope_drivers::v4l2::{FormatPreference, V4l2Settings};
use penelope_hal::Pose;
use serde::{Deserialize, Serialize};

use crate::dataplane::faults::{FaultConfig, OutageWindow};
use crate::objects::config::describe::KindConfig;
use crate::objects::config::{bad, check_range};
use crate::objects::error::ObjectError;

/// The most frames a subscriber's queue holds.
pub const MAX_QUEUE: u32 = 64;

/// `sensor/sim-camera` configuration: a simulated camera watching a simulated robot on this
/// node (its plant's truth, its board's walls and spheres).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SimCameraConfig {
    /// The robot it watches (required): a robot on this node whose joints are on simulated
    /// boards.
    pub robot: String,
    /// Where the camera is, m, in the robot's base frame.
    pub eye: [f64; 3],
    /// The point it looks at, m, in the robot's base frame (not the eye).
    pub target: [f64; 3],
    /// Roughly up in the image, in the robot's base frame (not along the line of sight).
    pub up: [f64; 3],
    /// Image width, pixels, 16..=4096.
    pub width: u32,
    /// Image height, pixels, 16..=4096.
    pub height: u32,
    /// Horizontal field of view, degrees, 1..=170 (exclusive of 170).
    pub fov_deg: f64,
    /// Frames per second, 0.1..=240.
    pub rate_hz: f64,
    /// Exposure, µs (the capture instant is its middle), 1..=1000000 and under a frame period.
    pub exposure_us: u32,
    /// Readout after the exposure, µs, 0..=1000000.
    pub readout_us: u32,
    /// Uniform pixel noise, ± levels per channel, 0..=64.
    pub noise: u8,
    /// The noise's seed (and the link faults').
    pub seed: u64,
    /// JPEG quality, 1..=100.
    pub jpeg_quality: u8,
    /// Frames a subscriber's queue holds, 1..=64: when full, the oldest is dropped (counted).
    pub queue: u32,
    /// The camera's link's faults (delay, jitter, loss...), applied to every frame on its
    /// way to each subscriber, seeded; none by default.
    pub link: FaultConfig,
}

impl Default for SimCameraConfig {
    fn default() -> Self {
        SimCameraConfig {
            robot: String::new(),
            eye: [1.6, -1.2, 1.0],
            target: [0.3, 0.0, 0.3],
            up: [0.0, 0.0, 1.0],
            width: 640,
            height: 480,
            fov_deg: 60.0,
            rate_hz: 30.0,
            exposure_us: 8000,
            readout_us: 12000,
            noise: 2,
            seed: 0,
            jpeg_quality: 80,
            queue: 4,
            link: FaultConfig::default(),
        }
    }
}

impl KindConfig for SimCameraConfig {
    fn example() -> Self {
        SimCameraConfig {
            robot: "puma".into(),
            link: FaultConfig {
                delay_ms: 20.0,
                jitter_ms: 5.0,
                loss: 0.01,
                outages: vec![OutageWindow {
                    from_s: 10.0,
                    to_s: 12.5,
                }],
                ..FaultConfig::default()
            },
            ..Self::default()
        }
    }
}

/// A checked configuration: what the camera thread runs with.
#[derive(Clone, Debug)]
pub struct CameraSetup {
    /// The robot watched.
    pub robot: String,
    /// The renderer: optics, placement (in the robot's base frame), noise.
    pub camera: SimCamera,
    /// When frames are taken and ready.
    pub timing: CameraTiming,
    /// JPEG quality, 1..=100.
    pub jpeg_quality: u8,
    /// Frames a subscriber's queue holds.
    pub queue: usize,
    /// The link's faults.
    pub link: FaultConfig,
}

impl SimCameraConfig {
    /// Checks every key: a clear error naming the key at fault.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<CameraSetup, ObjectError> {
        if self.robot.trim().is_empty() {
            return Err(bad(kind, "robot: the robot it watches is required"));
        }
        for (key, v) in [("eye", self.eye), ("target", self.target), ("up", self.up)] {
            for x in v {
                check_range(kind, key, x, -100.0, 100.0)?;
            }
        }
        check_stream(
            kind,
            self.width,
            self.height,
            self.rate_hz,
            self.jpeg_quality,
            self.queue,
            &self.link,
        )?;
        check_range(kind, "fov_deg", self.fov_deg, 1.0, 169.9)?;
        let period_us = 1e6 / self.rate_hz;
        if self.exposure_us == 0 || f64::from(self.exposure_us) >= period_us {
            return Err(bad(
                kind,
                format!(
                    "exposure_us: 1 to under a frame period ({period_us:.0} µs at {} Hz), not {}",
                    self.rate_hz, self.exposure_us
                ),
            ));
        }
        check_readout(kind, self.readout_us)?;
        if self.noise > 64 {
            return Err(bad(kind, format!("noise: 0..=64, not {}", self.noise)));
        }
        let pinhole = PinholeCamera::look_at(
            self.eye,
            self.target,
            self.up,
            self.width,
            self.height,
            self.fov_deg,
        )
        .map_err(|e| {
            bad(
                kind,
                format!("eye, target, up: {e} (the eye must not be on the target, nor up along the line of sight)"),
            )
        })?;
        Ok(CameraSetup {
            robot: self.robot.clone(),
            camera: SimCamera {
                camera: pinhole,
                noise: self.noise,
                seed: self.seed,
            },
            timing: CameraTiming {
                rate_hz: self.rate_hz,
                exposure_us: self.exposure_us,
                readout_us: self.readout_us,
            },
            jpeg_quality: self.jpeg_quality,
            queue: self.queue as usize,
            link: self.link.clone(),
        })
    }
}

/// The keys every camera kind has, checked alike: image size, rate, JPEG quality, the
/// subscribers' queue and the link's faults.
fn check_stream(
    kind: &str,
    width: u32,
    height: u32,
    rate_hz: f64,
    jpeg_quality: u8,
    queue: u32,
    link: &FaultConfig,
) -> Result<(), ObjectError> {
    for (key, v) in [("width", width), ("height", height)] {
        if !(16..=4096).contains(&v) {
            return Err(bad(kind, format!("{key}: 16..=4096 pixels, not {v}")));
        }
    }
    check_range(kind, "rate_hz", rate_hz, 0.1, 240.0)?;
    if !(1..=100).contains(&jpeg_quality) {
        return Err(bad(
            kind,
            format!("jpeg_quality: 1..=100, not {jpeg_quality}"),
        ));
    }
    if !(1..=MAX_QUEUE).contains(&queue) {
        return Err(bad(
            kind,
            format!("queue: 1..={MAX_QUEUE} frames, not {queue}"),
        ));
    }
    link.validate().map_err(|e| bad(kind, format!("link: {e}")))
}

fn check_readout(kind: &str, readout_us: u32) -> Result<(), ObjectError> {
    if readout_us > 1_000_000 {
        return Err(bad(
            kind,
            format!("readout_us: 0..=1000000, not {readout_us}"),
        ));
    }
    Ok(())
}

/// The pixel format a `sensor/camera` asks its device for.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize, schemars::JsonSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum CameraFormat {
    /// MJPEG if the device offers it, else YUYV.
    #[default]
    Auto,
    /// MJPEG only (the frames pass through).
    Mjpeg,
    /// YUYV only (encoded to JPEG on the camera's thread).
    Yuyv,
}

impl From<CameraFormat> for FormatPreference {
    fn from(f: CameraFormat) -> Self {
        match f {
            CameraFormat::Auto => FormatPreference::Auto,
            CameraFormat::Mjpeg => FormatPreference::Mjpeg,
            CameraFormat::Yuyv => FormatPreference::Yuyv,
        }
    }
}

/// `sensor/camera` configuration: a V4L2 camera (a UVC webcam) on this node, its frames'
/// kernel capture stamps mapped onto the common clock (`docs/v4l2.md`).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// The device node (required), e.g. `/dev/video0`.
    pub device: String,
    /// Requested image width, pixels, 16..=4096 (the driver picks the nearest it has).
    pub width: u32,
    /// Requested image height, pixels, 16..=4096.
    pub height: u32,
    /// Requested frames per second, 1..=240.
    pub rate_hz: u32,
    /// Pixel format asked for: `auto` (MJPEG if offered, else YUYV), `mjpeg` or `yuyv`.
    pub format: CameraFormat,
    /// Horizontal field of view, degrees, 1..=170 (exclusive): the pinhole model (V4L2 gives
    /// no calibration).
    pub hfov_deg: f64,
    /// The sensor's readout, µs, 0..=1000000: for drivers that stamp the end of the frame.
    pub readout_us: u32,
    /// JPEG quality of YUYV frames, 1..=100 (MJPEG frames pass through).
    pub jpeg_quality: u8,
    /// Frames a subscriber's queue holds, 1..=64: when full, the oldest is dropped (counted).
    pub queue: u32,
    /// The camera's link's faults, applied to every frame on its way to each subscriber.
    pub link: FaultConfig,
    /// The robot in whose base frame `eye`, `target` and `up` place the camera (for
    /// overlays); none: the frames carry no pose.
    pub robot: Option<String>,
    /// Where the camera is, m, in the robot's base frame (with `robot`).
    pub eye: Option<[f64; 3]>,
    /// The point it looks at, m, in the robot's base frame (with `robot`).
    pub target: Option<[f64; 3]>,
    /// Roughly up in the image, in the robot's base frame (with `robot`; default +z).
    pub up: Option<[f64; 3]>,
}

impl Default for CameraConfig {
    fn default() -> Self {
        CameraConfig {
            device: String::new(),
            width: 640,
            height: 480,
            rate_hz: 30,
            format: CameraFormat::Auto,
            hfov_deg: 60.0,
            readout_us: 10_000,
            jpeg_quality: 85,
            queue: 4,
            link: FaultConfig::default(),
            robot: None,
            eye: None,
            target: None,
            up: None,
        }
    }
}

impl KindConfig for CameraConfig {
    fn example() -> Self {
        CameraConfig {
            device: "/dev/video0".into(),
            robot: Some("puma".into()),
            eye: Some([1.6, -1.2, 1.0]),
            target: Some([0.3, 0.0, 0.3]),
            up: Some([0.0, 0.0, 1.0]),
            link: FaultConfig {
                delay_ms: 20.0,
                outages: vec![OutageWindow {
                    from_s: 10.0,
                    to_s: 12.5,
                }],
                ..FaultConfig::default()
            },
            ..Self::default()
        }
    }
}

/// Where a `sensor/camera` is: a robot and the camera's pose in its base frame.
#[derive(Clone, Debug)]
pub struct CameraPlacement {
    /// The robot.
    pub robot: String,
    /// The camera's optical frame (x right, y down, z forward) in the robot's base frame.
    pub pose: Pose,
}

/// A checked `sensor/camera` configuration: what its device is opened with.
#[derive(Clone, Debug)]
pub struct DeviceCameraSetup {
    /// The device's settings.
    pub settings: V4l2Settings,
    /// Frames a subscriber's queue holds.
    pub queue: usize,
    /// The link's faults.
    pub link: FaultConfig,
    /// Its placement, if configured.
    pub placement: Option<CameraPlacement>,
}

impl CameraConfig {
    /// Checks every key: a clear error naming the key at fault.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<DeviceCameraSetup, ObjectError> {
        if self.device.trim().is_empty() {
            return Err(bad(
                kind,
                "device: the device node is required (e.g. /dev/video0)",
            ));
        }
        check_stream(
            kind,
            self.width,
            self.height,
            f64::from(self.rate_hz),
            self.jpeg_quality,
            self.queue,
            &self.link,
        )?;
        if self.rate_hz == 0 {
            return Err(bad(kind, "rate_hz: 1..=240, not 0"));
        }
        check_range(kind, "hfov_deg", self.hfov_deg, 1.0, 169.9)?;
        check_readout(kind, self.readout_us)?;
        let placement = match (&self.robot, self.eye, self.target) {
            (None, None, None) if self.up.is_none() => None,
            (Some(robot), Some(eye), Some(target)) if !robot.trim().is_empty() => {
                let up = self.up.unwrap_or([0.0, 0.0, 1.0]);
                for (key, v) in [("eye", eye), ("target", target), ("up", up)] {
                    for x in v {
                        check_range(kind, key, x, -100.0, 100.0)?;
                    }
                }
                let pinhole = PinholeCamera::look_at(
                    eye,
                    target,
                    up,
                    self.width,
                    self.height,
                    self.hfov_deg,
                )
                .map_err(|e| {
                    bad(
                        kind,
                        format!("eye, target, up: {e} (the eye must not be on the target, nor up along the line of sight)"),
                    )
                })?;
                Some(CameraPlacement {
                    robot: robot.clone(),
                    pose: pinhole.pose,
                })
            }
            _ => {
                return Err(bad(
                    kind,
                    "robot, eye, target: a placement needs all three (and optionally up), or none",
                ));
            }
        };
        let mut settings = V4l2Settings::new(self.device.trim());
        settings.width = self.width;
        settings.height = self.height;
        settings.rate_hz = self.rate_hz;
        settings.format = self.format.into();
        settings.readout_us = self.readout_us;
        settings.jpeg_quality = self.jpeg_quality;
        settings.hfov_deg = self.hfov_deg;
        settings.validate().map_err(|e| bad(kind, e.to_string()))?;
        Ok(DeviceCameraSetup {
            settings,
            queue: self.queue as usize,
            link: self.link.clone(),
            placement,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::objects::config::parse;

    fn setup(text: &str) -> Result<CameraSetup, ObjectError> {
        parse::<SimCameraConfig>("sensor/sim-camera", text)?.check("sensor/sim-camera")
    }

    #[test]
    fn a_camera_needs_only_its_robot_and_takes_the_documented_defaults() {
        let s = setup("robot = \"puma\"").unwrap();
        assert_eq!(
            (
                s.camera.camera.intrinsics.width,
                s.camera.camera.intrinsics.height
            ),
            (640, 480)
        );
        assert_eq!(s.timing.rate_hz, 30.0);
        assert_eq!(s.queue, 4);
        assert_eq!(s.link, FaultConfig::default());
    }

    #[test]
    fn every_key_is_checked_with_an_error_naming_it() {
        for (text, key) in [
            ("", "robot"),
            ("robot = \"p\"\neye = [nan, 0, 0]", "eye"),
            (
                "robot = \"p\"\neye = [0.3, 0, 0.3]\ntarget = [0.3, 0, 0.3]",
                "eye, target",
            ),
            ("robot = \"p\"\nup = [-1.3, 1.2, -0.7]", "eye, target, up"),
            ("robot = \"p\"\nrate_hz = 0", "rate_hz"),
            ("robot = \"p\"\nwidth = 0", "width"),
            ("robot = \"p\"\nfov_deg = 180", "fov_deg"),
            ("robot = \"p\"\nexposure_us = 40000", "exposure_us"),
            ("robot = \"p\"\njpeg_quality = 0", "jpeg_quality"),
            ("robot = \"p\"\nqueue = 0", "queue"),
            ("robot = \"p\"\nlink = { loss = 2.0 }", "link"),
            ("robot = \"p\"\nfps = 30", "fps"),
        ] {
            match setup(text) {
                Err(ObjectError::BadConfig { message, .. }) => {
                    assert!(message.contains(key), "{text}: {message}")
                }
                other => panic!("{text}: {other:?}"),
            }
        }
    }

    fn device(text: &str) -> Result<DeviceCameraSetup, ObjectError> {
        parse::<CameraConfig>("sensor/camera", text)?.check("sensor/camera")
    }

    #[test]
    fn a_device_camera_needs_its_device_and_a_whole_placement_or_none() {
        let s = device("device = \"/dev/video0\"").unwrap();
        assert_eq!(s.settings.device.to_str(), Some("/dev/video0"));
        assert_eq!(
            (s.settings.width, s.settings.rate_hz, s.queue),
            (640, 30, 4)
        );
        assert!(s.placement.is_none());
        let placed = device(
            "device = \"/dev/video0\"\nformat = \"yuyv\"\nrobot = \"puma\"\neye = [1.6, -1.2, 1.0]\ntarget = [0.3, 0, 0.3]",
        )
        .unwrap();
        assert_eq!(placed.settings.format, FormatPreference::Yuyv);
        assert_eq!(placed.placement.unwrap().robot, "puma");
        for (text, key) in [
            ("", "device"),
            ("device = \"/dev/video0\"\nrate_hz = 0", "rate_hz"),
            ("device = \"/dev/video0\"\nwidth = 8", "width"),
            ("device = \"/dev/video0\"\nhfov_deg = 0", "hfov_deg"),
            ("device = \"/dev/video0\"\nqueue = 65", "queue"),
            ("device = \"/dev/video0\"\njpeg_quality = 0", "jpeg_quality"),
            (
                "device = \"/dev/video0\"\nformat = \"h264\"",
                "expected one of `auto`, `mjpeg`, `yuyv`",
            ),
            (
                "device = \"/dev/video0\"\nrobot = \"puma\"",
                "robot, eye, target",
            ),
            ("device = \"/dev/video0\"\nlink = { loss = 2.0 }", "link"),
        ] {
            match device(text) {
                Err(ObjectError::BadConfig { message, .. }) => {
                    assert!(message.contains(key), "{text}: {message}")
                }
                other => panic!("{text}: {other:?}"),
            }
        }
    }
}
