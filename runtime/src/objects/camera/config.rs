//! `sensor/sim-camera`'s configuration: its keys, their checks, and the camera they make.

use penelope_drivers::sim::camera::{CameraTiming, PinholeCamera, SimCamera};
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
        for (key, v) in [("width", self.width), ("height", self.height)] {
            if !(16..=4096).contains(&v) {
                return Err(bad(kind, format!("{key}: 16..=4096 pixels, not {v}")));
            }
        }
        check_range(kind, "fov_deg", self.fov_deg, 1.0, 169.9)?;
        check_range(kind, "rate_hz", self.rate_hz, 0.1, 240.0)?;
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
        if self.readout_us > 1_000_000 {
            return Err(bad(
                kind,
                format!("readout_us: 0..=1000000, not {}", self.readout_us),
            ));
        }
        if self.noise > 64 {
            return Err(bad(kind, format!("noise: 0..=64, not {}", self.noise)));
        }
        if !(1..=100).contains(&self.jpeg_quality) {
            return Err(bad(
                kind,
                format!("jpeg_quality: 1..=100, not {}", self.jpeg_quality),
            ));
        }
        if !(1..=MAX_QUEUE).contains(&self.queue) {
            return Err(bad(
                kind,
                format!("queue: 1..={MAX_QUEUE} frames, not {}", self.queue),
            ));
        }
        self.link
            .validate()
            .map_err(|e| bad(kind, format!("link: {e}")))?;
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
        assert_eq!((s.camera.camera.width, s.camera.camera.height), (640, 480));
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
}
