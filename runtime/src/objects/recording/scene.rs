//! The 3D scene of a recording: every robot the recording covers, from the ticks of the
//! controller that drives it, in Foxglove's well-known messages ([`penelope_scene`]):
//!
//! - `/robot_description/<robot>` once per robot at the start (`penelope.RobotDescription`:
//!   its URDF and frames);
//! - `/tf` (`foxglove.FrameTransforms`): every link frame of the robot at the tick's measured
//!   joints, `world` → `<robot>/<root>` (robots side by side along world y, 1 m apart in
//!   creation order) → `<robot>/<frame>`, decimated to [`SceneConfig::rate_hz`] of tick time
//!   (default [`DEFAULT_SCENE_HZ`]);
//! - `/scene` (`foxglove.SceneUpdate`), with each `/tf`: the contact shapes of the robot's
//!   simulated environment (in every message, so a viewer that seeks finds them), the sensed
//!   wrench's force as an arrow at the sensor frame (`<robot>/sensor`, below the tool frame in
//!   `/tf`: the sensor's mount) and the displayed force (the
//!   commanded wrench after the force limits: what the motors are made to produce) as an arrow
//!   at the tool (a master's handle); an arrow under 1 mN is not drawn.
//!
//! It runs in the recorder's thread, from the ticks the loops already hand over through their
//! rings: nothing here touches a real-time loop.

use penelope_drivers::model::SerialRobotModel;
use penelope_hal::nalgebra::Vector3;
use penelope_hal::{Frame, Pose, Wrench};
use penelope_protocol::proto::ContactShapeMsg;
use penelope_scene::{
    ContactShape, DISPLAYED_COLOR, FRAME_TRANSFORMS, FrameTransform, METRES_PER_NEWTON,
    ROBOT_DESCRIPTION, RobotDescription, SCENE_UPDATE, SENSED_COLOR, ScenePose, SceneUpdate,
    TOPIC_SCENE, TOPIC_TF, Timestamp, frame_id, robot_description_topic, robot_transforms,
    wall_entity, wrench_arrow,
};

use super::RecordingError;
use super::mcap_log::McapLog;
use crate::objects::tick::TickRecord;

/// The default rate of a recording's `/tf` and `/scene`, Hz of tick time.
pub const DEFAULT_SCENE_HZ: f64 = 100.0;
/// The highest rate a recording's scene may be asked for, Hz (a tick is at most 10 kHz).
pub const MAX_SCENE_HZ: f64 = 10_000.0;
/// The name of a robot's sensor frame below its tool frame (`<robot>/sensor`).
pub const SENSOR_FRAME: &str = "sensor";

/// One robot of a recording's scene.
#[derive(Clone, Debug)]
pub struct SceneRobot {
    /// The robot object's name (the prefix of its frame ids).
    pub robot: String,
    /// The recorded controller whose ticks carry its joints.
    pub controller: String,
    /// Its model (frames, URDF).
    pub model: SerialRobotModel,
    /// Where its root stands in the world.
    pub placement: Pose,
    /// The contact shapes of its simulated environment, in its root frame.
    pub contacts: Vec<ContactShapeMsg>,
    /// Its force sensor's frame in its tool frame (`None`: no sensor): drawn as
    /// `<robot>/sensor`, where the sensed wrench's arrow starts.
    pub sensor_mount: Option<Pose>,
}

/// What a recording draws in 3D.
#[derive(Clone, Debug)]
pub struct SceneConfig {
    /// The robots.
    pub robots: Vec<SceneRobot>,
    /// `/tf` and `/scene` per second of tick time (0: none of them, descriptions only).
    pub rate_hz: f64,
}

impl Default for SceneConfig {
    fn default() -> Self {
        SceneConfig {
            robots: Vec::new(),
            rate_hz: DEFAULT_SCENE_HZ,
        }
    }
}

/// A scene rate out of 0..=[`MAX_SCENE_HZ`] Hz (or not a number).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("the scene rate must be 0..={max} Hz, got {0}", max = MAX_SCENE_HZ)]
pub struct BadSceneRate(pub f64);

/// Checks a scene rate: finite, 0..=[`MAX_SCENE_HZ`].
///
/// # Errors
/// [`BadSceneRate`].
pub fn check_rate(rate_hz: f64) -> Result<f64, BadSceneRate> {
    if rate_hz.is_finite() && (0.0..=MAX_SCENE_HZ).contains(&rate_hz) {
        Ok(rate_hz)
    } else {
        Err(BadSceneRate(rate_hz))
    }
}

/// One robot being drawn: its frames (asked once), where its ticks come from, and when it was
/// last drawn.
struct Drawn {
    robot: SceneRobot,
    frames: Vec<String>,
    walls: Vec<ContactShape>,
    /// The index of its controller among the recorder's streams.
    stream: Option<usize>,
    last_ns: Option<u64>,
}

/// Writes the scene of a recording, tick by tick (see the [module](self)).
pub struct SceneWriter {
    drawn: Vec<Drawn>,
    /// Tick time between two drawings of a robot, ns (`None`: descriptions only).
    period_ns: Option<u64>,
}

/// A simulated environment's shape on the wire.
pub fn contact_shape_msg(shape: &penelope_drivers::sim::environment::Shape) -> ContactShapeMsg {
    use penelope_drivers::sim::environment::Shape;
    match *shape {
        Shape::Plane { point, normal } => ContactShapeMsg::Plane {
            point: point.into(),
            normal: normal.into_inner().into(),
        },
        Shape::Sphere { center, radius } => ContactShapeMsg::Sphere {
            center: center.into(),
            radius,
        },
    }
}

fn contact_shape(c: &ContactShapeMsg) -> ContactShape {
    match *c {
        ContactShapeMsg::Plane { point, normal } => ContactShape::Plane { point, normal },
        ContactShapeMsg::Sphere { center, radius } => ContactShape::Sphere { center, radius },
    }
}

impl SceneWriter {
    /// The writer of `scene`, whose robots' ticks come from the recorder's streams named
    /// `streams` (in order).
    pub fn new(scene: SceneConfig, streams: &[String]) -> Self {
        let period_ns = (scene.rate_hz > 0.0).then(|| (1e9 / scene.rate_hz).round() as u64);
        let drawn = scene
            .robots
            .into_iter()
            .map(|robot| Drawn {
                frames: robot.model.link_names(),
                walls: robot.contacts.iter().map(contact_shape).collect(),
                stream: streams.iter().position(|s| *s == robot.controller),
                robot,
                last_ns: None,
            })
            .collect();
        SceneWriter { drawn, period_ns }
    }

    /// Writes every robot's description, at node time `time_ns`.
    ///
    /// # Errors
    /// [`RecordingError`] when a write fails.
    pub fn describe(&self, log: &mut McapLog, time_ns: u64) -> Result<(), RecordingError> {
        for d in &self.drawn {
            let description = RobotDescription {
                robot: d.robot.robot.clone(),
                urdf: d.robot.model.urdf(),
                frames: d.frames.clone(),
            };
            let topic = robot_description_topic(&d.robot.robot);
            log.scene(&topic, ROBOT_DESCRIPTION, time_ns, &description)?;
        }
        Ok(())
    }

    /// Draws the robot of stream `stream` at `record` when its period has passed since it was
    /// last drawn: its `/tf` and its `/scene`.
    ///
    /// # Errors
    /// [`RecordingError`] when a write fails.
    pub fn tick(
        &mut self,
        log: &mut McapLog,
        stream: usize,
        record: &TickRecord,
    ) -> Result<(), RecordingError> {
        let Some(period) = self.period_ns else {
            return Ok(());
        };
        let time = record.sample.time.as_nanos();
        for d in self.drawn.iter_mut().filter(|d| d.stream == Some(stream)) {
            if d.last_ns.is_some_and(|t| time < t.saturating_add(period)) {
                continue;
            }
            d.last_ns = Some(time);
            let stamp = log.log_time(time);
            let name = &d.robot.robot;
            let poses = d.robot.model.link_frames(&record.sample.q);
            let mut tf = robot_transforms(name, &d.frames, &poses, &d.robot.placement, stamp);
            let root = frame_id(name, d.frames.first().map_or("", String::as_str));
            let tool = frame_id(name, d.frames.last().map_or("", String::as_str));
            let tool_pose = poses.last().copied().unwrap_or_else(Pose::identity);
            // The sensed wrench starts at the sensor's frame, drawn below the tool's.
            let sensor = d.robot.sensor_mount.map(|mount| {
                let id = frame_id(name, SENSOR_FRAME);
                let at = ScenePose::from(&mount);
                tf.transforms.push(FrameTransform {
                    timestamp: Timestamp::from_ns(stamp),
                    parent_frame_id: tool.clone(),
                    child_frame_id: id.clone(),
                    translation: at.position,
                    rotation: at.orientation,
                });
                (id, mount)
            });
            log.scene(TOPIC_TF, FRAME_TRANSFORMS, time, &tf)?;
            let mut entities: Vec<_> = d
                .walls
                .iter()
                .enumerate()
                .map(|(k, w)| wall_entity(&format!("{name}/contact{k}"), &root, w, stamp))
                .collect();
            let mount = sensor.as_ref().map_or_else(Pose::identity, |(_, m)| *m);
            let sensed_frame = sensor.as_ref().map_or(&tool, |(id, _)| id);
            let sensed = force_in_base(&record.sample.wrench, &tool_pose, &mount);
            let sensed_pose = if sensor.is_some() {
                tool_pose * mount
            } else {
                tool_pose
            };
            let displayed = force_in_base(&record.sample.commanded_wrench, &tool_pose, &mount);
            for (what, frame, force, pose, color) in [
                (
                    "sensed_wrench",
                    sensed_frame,
                    sensed,
                    sensed_pose,
                    SENSED_COLOR,
                ),
                (
                    "displayed_force",
                    &tool,
                    displayed,
                    tool_pose,
                    DISPLAYED_COLOR,
                ),
            ] {
                let f = pose.rotation.inverse() * force;
                entities.push(wrench_arrow(
                    &format!("{name}/{what}"),
                    frame,
                    [f.x, f.y, f.z],
                    METRES_PER_NEWTON,
                    color,
                    stamp,
                ));
            }
            let update = SceneUpdate {
                deletions: Vec::new(),
                entities,
            };
            log.scene(TOPIC_SCENE, SCENE_UPDATE, time, &update)?;
        }
        Ok(())
    }
}

/// A wrench's force in the robot's base frame (`tool`: the tool's pose in it; `mount`: the
/// sensor's in the tool's). A flange-frame wrench is taken as in the tool frame, a master-frame
/// one as in the base frame.
fn force_in_base(w: &Wrench, tool: &Pose, mount: &Pose) -> Vector3<f64> {
    match w.frame {
        Frame::Base | Frame::Master => w.force,
        Frame::Tool | Frame::Flange => tool.rotation * w.force,
        Frame::Sensor => tool.rotation * (mount.rotation * w.force),
    }
}
