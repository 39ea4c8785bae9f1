//! The cameras in the registry: `sensor/sim-camera` and `sensor/camera`, their catalog
//! entries, their one object (the checked setup of either, and the camera thread while
//! configured), configuring them (a simulated camera's robot must be on this node, on
//! simulated boards; a device camera opens its device), and what `describe` shows of them.

use std::sync::Arc;

use penelope_drivers::sim::environment::Shape;
use penelope_protocol::proto::SensorMethod;

use super::kind_entry::{KindEntry, MakeArgs};
use super::{KindState, Registry};
use crate::common_clock::CommonClock;
use crate::dataplane::faults::FaultConfig;
use crate::objects::camera::capture::{CaptureStartError, SourceOpener};
use crate::objects::camera::config::{CameraConfig, DeviceCameraSetup};
use crate::objects::camera::thread::CAMERA_TICK_CAPACITY;
use crate::objects::camera::{CameraRunner, CameraSetup, CameraWorld, SendClock, SimCameraConfig};
use crate::objects::config::describe::described;
use crate::objects::config::{bad, parse};
use crate::objects::error::ObjectError;
use crate::objects::kinds::Kind;
use crate::objects::runtime::Subscriptions;

/// `sensor/sim-camera`.
pub const SIM_CAMERA: Kind = Kind::named("sensor/sim-camera");

/// Its catalog entry.
pub(super) const ENTRY: KindEntry = KindEntry::new(
    SIM_CAMERA,
    "simulated camera watching a simulated robot on this node (its links, its board's walls and spheres, a red tool marker) from the plant's truth, with an exposure and readout delay; JPEG frames stamped on the common clock to subscribers (drop-oldest queues) and recordings",
    described::<SimCameraConfig>(),
    make,
);

/// `sensor/camera`.
pub const CAMERA: Kind = Kind::named("sensor/camera");

/// Its catalog entry.
pub(super) const DEVICE_ENTRY: KindEntry = KindEntry::new(
    CAMERA,
    "V4L2 camera (a UVC webcam) on this node: MJPEG frames passed through or YUYV encoded to JPEG, the kernel's capture stamps on the common clock, to subscribers (drop-oldest queues) and recordings; optionally placed in a robot's base frame (needs the `v4l2` build)",
    described::<CameraConfig>(),
    make_device,
);

/// Whether `kind` is a camera's (either kind).
pub(crate) fn is_camera(kind: Kind) -> bool {
    kind == SIM_CAMERA || kind == CAMERA
}

/// What a camera's thread needs from the creator: where subscriptions are, the common clock,
/// the node's clock.
#[derive(Clone, Debug)]
pub(crate) struct CameraEnv {
    pub subscriptions: Arc<Subscriptions>,
    pub clock: CommonClock,
    pub send_clock: SendClock,
}

/// A camera's setup: simulated or a device.
pub(crate) enum CameraSource {
    /// A `sensor/sim-camera`.
    Sim(CameraSetup),
    /// A `sensor/camera`.
    Device(DeviceCameraSetup),
}

/// A camera, either kind.
pub(crate) struct CameraObj {
    pub source: CameraSource,
    /// Its thread, while configured.
    pub runner: Option<CameraRunner>,
    /// Where its subscriptions are, once configured.
    pub subscriptions: Option<Arc<Subscriptions>>,
    /// A device camera's frame source for its next configure instead of its device
    /// ([`Creator::set_frame_source`](crate::objects::Creator::set_frame_source)).
    pub opener: Option<SourceOpener>,
}

fn make(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: SimCameraConfig = parse(k, a.config)?;
    Ok(KindState::Camera(Box::new(CameraObj {
        source: CameraSource::Sim(cfg.check(k)?),
        runner: None,
        subscriptions: None,
        opener: None,
    })))
}

fn make_device(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: CameraConfig = parse(k, a.config)?;
    Ok(KindState::Camera(Box::new(CameraObj {
        source: CameraSource::Device(cfg.check(k)?),
        runner: None,
        subscriptions: None,
        opener: None,
    })))
}

impl crate::objects::Creator {
    /// Gives device camera `name` (`sensor/camera`) the frame source `open` makes for its next
    /// configure, instead of its device: for tests of its thread without a device, or for a
    /// capture library of the caller's. Used once; a later configure opens the device.
    ///
    /// # Errors
    /// [`ObjectError::UnknownName`]; [`ObjectError::BadArgument`] for an object that is not a
    /// `sensor/camera`.
    pub fn set_frame_source(&self, name: &str, open: SourceOpener) -> Result<(), ObjectError> {
        let mut reg = self.lock()?;
        match &mut reg.get_mut(name)?.body {
            KindState::Camera(c) if matches!(c.source, CameraSource::Device(_)) => {
                c.opener = Some(open);
                Ok(())
            }
            _ => Err(ObjectError::BadArgument(format!(
                "`{name}` is not a sensor/camera: only a device camera takes a frame source"
            ))),
        }
    }
}

impl CameraObj {
    /// Frames a subscriber's queue holds.
    pub fn queue(&self) -> usize {
        match &self.source {
            CameraSource::Sim(s) => s.queue,
            CameraSource::Device(d) => d.queue,
        }
    }

    /// The camera link's faults.
    pub fn link(&self) -> &FaultConfig {
        match &self.source {
            CameraSource::Sim(s) => &s.link,
            CameraSource::Device(d) => &d.link,
        }
    }

    /// The link faults' seed.
    pub fn seed(&self) -> u64 {
        match &self.source {
            CameraSource::Sim(s) => s.camera.seed,
            CameraSource::Device(_) => 0,
        }
    }
}

impl Registry {
    /// Starts camera `name`'s thread on the ticks of the robot it watches, after checking that
    /// robot: on this node, its joints on simulated boards (the truth it renders).
    pub(super) fn configure_camera(&mut self, name: &str) -> Result<(), ObjectError> {
        let kind = SIM_CAMERA.as_str();
        let setup = match &mut self.get_mut(name)?.body {
            KindState::Camera(c) => match &c.source {
                CameraSource::Sim(s) => s.clone(),
                CameraSource::Device(d) => {
                    let settings = d.settings.clone();
                    let open: SourceOpener = c.opener.take().unwrap_or_else(|| {
                        Box::new(move || {
                            penelope_drivers::v4l2::V4l2Camera::open(&settings).map(|c| {
                                Box::new(c) as Box<dyn crate::objects::camera::FrameSource>
                            })
                        })
                    });
                    let placement = d.placement.clone();
                    return self.configure_capture(name, open, placement);
                }
            },
            _ => return Err(ObjectError::internal("camera body")),
        };
        let robot = setup.robot.as_str();
        let o = self.objects.get(robot).ok_or_else(|| {
            bad(
                kind,
                format!("robot: no robot `{robot}` on this node (a camera watches a robot on its own node)"),
            )
        })?;
        let KindState::Robot(r) = &o.body else {
            return Err(bad(
                kind,
                format!("robot: `{robot}` is a {}, not a robot", o.kind.as_str()),
            ));
        };
        if r.maps.is_empty() {
            return Err(ObjectError::NotReady(format!(
                "robot `{robot}` has no joints mapped onto a board yet (MapJoints first)"
            )));
        }
        let mut contacts: Vec<Shape> = Vec::new();
        for (board, _) in &r.maps {
            match self.get(board).map(|b| &b.body) {
                Ok(KindState::SimBoard(s)) => {
                    let env = crate::objects::kinds::environment(
                        Kind::SIM_BOARD.as_str(),
                        &s.config.shapes,
                    )?;
                    contacts.extend(env.shapes().iter().map(|c| c.shape));
                }
                _ => {
                    return Err(bad(
                        kind,
                        format!(
                            "robot: `{robot}` is on board `{board}`, not a simulated board: a simulated camera renders a simulated plant's truth"
                        ),
                    ));
                }
            }
        }
        let env = self.camera_env.clone().ok_or_else(|| {
            ObjectError::internal("a creator's registry without its camera environment")
        })?;
        let world = CameraWorld {
            model: r.model.clone(),
            contacts,
        };
        let stream = env.subscriptions.record_robot(robot, CAMERA_TICK_CAPACITY);
        let runner = CameraRunner::start(
            name,
            setup,
            world,
            stream,
            env.subscriptions.clone(),
            env.clock.clone(),
            env.send_clock,
        )
        .map_err(|e| ObjectError::thread("cannot start the camera thread", e))?;
        self.camera_started(name, runner, env.subscriptions)
    }

    fn camera_started(
        &mut self,
        name: &str,
        runner: CameraRunner,
        subscriptions: Arc<Subscriptions>,
    ) -> Result<(), ObjectError> {
        if let KindState::Camera(c) = &mut self.get_mut(name)?.body {
            c.runner = Some(runner);
            c.subscriptions = Some(subscriptions);
        }
        Ok(())
    }

    /// Starts device camera `name`'s thread on the source `open` gives (a V4L2 device, or a
    /// test's fake): refused with the device's typed error when it does not open.
    pub(crate) fn configure_capture(
        &mut self,
        name: &str,
        open: SourceOpener,
        placement: Option<crate::objects::camera::config::CameraPlacement>,
    ) -> Result<(), ObjectError> {
        let env = self.camera_env.clone().ok_or_else(|| {
            ObjectError::internal("a creator's registry without its camera environment")
        })?;
        let runner = CameraRunner::start_capture(
            name,
            open,
            placement,
            env.subscriptions.clone(),
            env.clock.clone(),
        )
        .map_err(|e| match e {
            CaptureStartError::Open(e) => bad(CAMERA.as_str(), format!("device: {e}")),
            CaptureStartError::Thread(e) => {
                ObjectError::thread("cannot start the camera thread", e)
            }
            CaptureStartError::Vanished => {
                ObjectError::internal("the camera thread ended while opening its device")
            }
        })?;
        self.camera_started(name, runner, env.subscriptions)
    }

    /// A tap of the frames of each of `cameras` that runs (a recording's), by name.
    pub(crate) fn camera_taps(
        &self,
        cameras: &[String],
    ) -> Vec<(
        String,
        std::sync::mpsc::Receiver<penelope_protocol::proto::CameraFrame>,
    )> {
        cameras
            .iter()
            .filter_map(|name| match self.objects.get(name).map(|o| &o.body) {
                Some(KindState::Camera(c)) => {
                    c.runner.as_ref().map(|r| (name.clone(), r.shared.tap()))
                }
                _ => None,
            })
            .collect()
    }

    /// Stops camera `name`'s thread and ends its subscriptions.
    pub(super) fn release_camera(&mut self, name: &str) {
        if let Some(KindState::Camera(c)) = self.objects.get_mut(name).map(|o| &mut o.body) {
            c.runner = None;
        }
        if let Some(env) = &self.camera_env {
            env.subscriptions.frames().end_camera(name);
        }
    }
}

impl CameraObj {
    /// What `describe` shows of camera `name`: its setup (a simulated camera's robot, optics
    /// and timing; a device camera's device and settings), its counters and its subscribers.
    pub(super) fn relations(&self, name: &str) -> Vec<(String, String)> {
        let mut out = match &self.source {
            CameraSource::Sim(s) => sim_relations(s),
            CameraSource::Device(d) => device_relations(d),
        };
        let load = |a: &std::sync::atomic::AtomicU64| a.load(std::sync::atomic::Ordering::Relaxed);
        if let Some(runner) = &self.runner {
            let counters = &runner.shared.counters;
            match &self.source {
                CameraSource::Sim(_) => {
                    let (render, encode) = counters.times();
                    out.push((
                        "frames".to_string(),
                        format!(
                            "rendered {} released {} skipped {} behind the clock {} ticks lost {} recording lost {}",
                            load(&counters.rendered),
                            load(&counters.released),
                            load(&counters.skipped),
                            load(&counters.behind),
                            load(&counters.ticks_dropped),
                            load(&counters.tap_dropped),
                        ),
                    ));
                    out.push((
                        "times".to_string(),
                        format!(
                            "render p50 {} µs max {} µs, encode p50 {} µs max {} µs",
                            render.p50_us, render.max_us, encode.p50_us, encode.max_us
                        ),
                    ));
                }
                CameraSource::Device(_) => {
                    out.push((
                        "frames".to_string(),
                        format!(
                            "released {} garbled {} timeouts {} recording lost {}",
                            load(&counters.released),
                            load(&counters.garbled),
                            load(&counters.timeouts),
                            load(&counters.tap_dropped),
                        ),
                    ));
                    let fault = counters.fault.lock().map(|f| f.clone()).unwrap_or_default();
                    if let Some(fault) = fault {
                        out.push((
                            "fault".to_string(),
                            format!("{fault}: frames ended (release and configure again)"),
                        ));
                    }
                }
            }
        }
        if let Some(subscriptions) = &self.subscriptions {
            for sub in subscriptions.frames().stats_of(name) {
                out.push((
                    "subscriber".to_string(),
                    format!(
                        "{} sent {} dropped {} lost on link {} queued {}",
                        sub.id, sub.sent, sub.dropped, sub.lost, sub.queued
                    ),
                ));
            }
        }
        out
    }
}

fn sim_relations(s: &CameraSetup) -> Vec<(String, String)> {
    let p = &s.camera.camera.intrinsics;
    vec![
        ("robot".to_string(), s.robot.clone()),
        (
            "image".to_string(),
            format!(
                "{}x{} fx {:.1} fy {:.1} cx {:.1} cy {:.1}, JPEG quality {}",
                p.width, p.height, p.fx, p.fy, p.cx, p.cy, s.jpeg_quality
            ),
        ),
        (
            "timing".to_string(),
            format!(
                "{} Hz, exposure {} µs, readout {} µs",
                s.timing.rate_hz, s.timing.exposure_us, s.timing.readout_us
            ),
        ),
    ]
}

fn device_relations(d: &DeviceCameraSetup) -> Vec<(String, String)> {
    let s = &d.settings;
    let mut out = vec![
        ("device".to_string(), s.device.display().to_string()),
        (
            "image".to_string(),
            format!(
                "{}x{} at {} Hz asked ({:?}), field of view {}°, readout {} µs, JPEG quality {}",
                s.width, s.height, s.rate_hz, s.format, s.hfov_deg, s.readout_us, s.jpeg_quality
            ),
        ),
    ];
    if let Some(p) = &d.placement {
        out.push(("robot".to_string(), p.robot.clone()));
    }
    out
}

/// A camera answers no sensor method: its frames come by subscription.
pub(super) fn camera_method(kind: Kind, m: SensorMethod) -> ObjectError {
    ObjectError::Unsupported {
        kind: kind.as_str().into(),
        method: format!("{m:?} (a camera's frames come by subscription: `watch_camera`)").into(),
    }
}
