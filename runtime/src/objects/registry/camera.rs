//! `sensor/sim-camera` in the registry: its catalog entry, its object (the checked setup, and
//! the camera thread while configured), configuring it (the robot it watches must be on this
//! node, on simulated boards), and what `describe` shows of it.

use std::sync::Arc;

use penelope_drivers::sim::environment::Shape;
use penelope_protocol::proto::SensorMethod;

use super::kind_entry::{KindEntry, MakeArgs};
use super::{KindState, Registry};
use crate::common_clock::CommonClock;
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

/// What a camera's thread needs from the creator: where subscriptions are, the common clock,
/// the node's clock.
#[derive(Clone, Debug)]
pub(crate) struct CameraEnv {
    pub subscriptions: Arc<Subscriptions>,
    pub clock: CommonClock,
    pub send_clock: SendClock,
}

/// A `sensor/sim-camera`.
pub(crate) struct CameraObj {
    pub setup: CameraSetup,
    /// Its thread, while configured.
    pub runner: Option<CameraRunner>,
    /// Where its subscriptions are, once configured.
    pub subscriptions: Option<Arc<Subscriptions>>,
}

fn make(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: SimCameraConfig = parse(k, a.config)?;
    Ok(KindState::Camera(Box::new(CameraObj {
        setup: cfg.check(k)?,
        runner: None,
        subscriptions: None,
    })))
}

impl Registry {
    /// Starts camera `name`'s thread on the ticks of the robot it watches, after checking that
    /// robot: on this node, its joints on simulated boards (the truth it renders).
    pub(super) fn configure_camera(&mut self, name: &str) -> Result<(), ObjectError> {
        let kind = SIM_CAMERA.as_str();
        let setup = match &self.get(name)?.body {
            KindState::Camera(c) => c.setup.clone(),
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
        if let KindState::Camera(c) = &mut self.get_mut(name)?.body {
            c.runner = Some(runner);
            c.subscriptions = Some(env.subscriptions.clone());
        }
        Ok(())
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
    /// What `describe` shows of camera `name`: its robot, optics and timing, and its counters.
    pub(super) fn relations(&self, name: &str) -> Vec<(String, String)> {
        let c = self;
        let s = &c.setup;
        let p = &s.camera.camera;
        let mut out = vec![
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
        ];
        let Some(runner) = &c.runner else {
            return out;
        };
        let counters = &runner.shared.counters;
        let load = |a: &std::sync::atomic::AtomicU64| a.load(std::sync::atomic::Ordering::Relaxed);
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

/// A camera answers no sensor method: its frames come by subscription.
pub(super) fn camera_method(kind: Kind, m: SensorMethod) -> ObjectError {
    ObjectError::Unsupported {
        kind: kind.as_str().into(),
        method: format!("{m:?} (a camera's frames come by subscription: `watch_camera`)").into(),
    }
}
