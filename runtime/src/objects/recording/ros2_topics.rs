//! The ROS 2 topic set of a node, in one place: what a tick of a robot's controller and a
//! channel's link statistics become as ROS 2 messages ([`penelope_ros2_msgs`]), with their
//! topic names (CRTK's, under the robot's name). The rmw_zenoh bridge publishes them and a
//! recording's `ros2` profile writes them: both from this module, so they cannot disagree.
//!
//! Per robot `<robot>` (its object name made a valid ROS name, [`ros_name`]):
//!
//! | topic | type | from the tick |
//! |---|---|---|
//! | `/<robot>/measured_js` | `sensor_msgs/msg/JointState` | joint names (the model's), measured `q`, `qd`, and the commanded effort |
//! | `/<robot>/measured_cp` | `geometry_msgs/msg/PoseStamped` | the tool's pose at the measured `q`, in `<robot>/<root>` |
//! | `/<robot>/measured_cf` | `geometry_msgs/msg/WrenchStamped` | the sensed wrench, in the frame the sensor reports it in (robots with a sensor only) |
//! | `/<robot>/setpoint_js` | `sensor_msgs/msg/JointState` | the joint reference (positions of a joint reference, none otherwise) and the commanded effort |
//! | `/<robot>/operating_state` | `crtk_msgs/msg/OperatingState` | the safety state |
//! | `/tf` | `tf2_msgs/msg/TFMessage` | every link frame at the measured `q` |
//!
//! per camera `<camera>` on the node (`sensor/sim-camera`, `sensor/camera`), every frame:
//!
//! | topic | type | from the frame |
//! |---|---|---|
//! | `/<camera>/image_raw/compressed` | `sensor_msgs/msg/CompressedImage` | the JPEG, stamped with its capture instant on the common clock, in the camera's optical frame |
//! | `/<camera>/camera_info` | `sensor_msgs/msg/CameraInfo` | the pinhole intrinsics (no distortion), same stamp and frame |
//!
//! (`image_transport`'s names: `image_raw` with its `compressed` transport), and per
//! teleoperation channel linked to another node, `/diagnostics`
//! (`diagnostic_msgs/msg/DiagnosticArray`): one status, `<channel>: link`, OK, WARN once the
//! link has been lost (and restored) or ERROR while it is down, its figures as key-values.
//!
//! # Frames
//! The same tree as a recording's `/tf` ([`super::scene`]): `world` → `<robot>/<root>` (the
//! robot's placement) → `<robot>/<frame>` for each link frame (their poses in the root frame;
//! the last is the tool), and `<robot>/<tool>` → `<robot>/sensor` (the sensor's mount) when the
//! robot has a force sensor. `measured_cp` is the tool's pose in `<robot>/<root>`.
//!
//! `measured_cf` is the wrench the tick carries (`TelemetrySample::wrench`, the contact force
//! as the sensor measured it, moments about the frame's origin), unconverted, stamped with the
//! frame its [`Frame`] tag names: `<robot>/sensor` for a sensor's own frame (the usual case:
//! the simulated and Net F/T sensors report there), `<robot>/<tool>` for the tool or flange
//! frame (a flange-frame wrench is taken as in the tool frame, as the scene does),
//! `<robot>/<root>` for the base or master frame. A ROS 2 user transforms it with `/tf`.
//!
//! # Time
//! Every header's stamp is the nanoseconds the caller passes (a tick's `sample.time`, the
//! node's clock; a recording passes the log time it writes the message at, which is the same
//! in a simulated run) as [`Time::from_ns`].
//!
//! This runs outside the real-time loops (the bridge's and the recorder's threads): it
//! allocates.

use penelope_hal::{Frame, Pose};
use penelope_protocol::proto::{CameraFrame, LinkRecord};
use penelope_ros2_msgs::{
    CameraInfo, CompressedImage, DiagnosticArray, DiagnosticStatus, Header, JointState, KeyValue,
    OperatingState, Point, PoseStamped, Quaternion, RosMessage, TFMessage, Time, Transform,
    TransformStamped, Vector3, Wrench, WrenchStamped,
};
use penelope_rt_core::safety::SafetyState;
use penelope_rt_core::telemetry::ReferenceKind;
use penelope_scene::{ScenePose, frame_id};

use super::scene::{SENSOR_FRAME, SceneRobot};
use crate::objects::tick::TickRecord;

/// The topic of every robot's frames.
pub const TF_TOPIC: &str = "/tf";
/// The topic of the channels' link statistics.
pub const DIAGNOSTICS_TOPIC: &str = "/diagnostics";
/// The frame every robot is placed in.
pub const WORLD_FRAME: &str = penelope_scene::WORLD_FRAME;

/// `name` as a ROS 2 name token: letters, digits and `_` kept, every other character `_`, and
/// a leading `_` before a digit (ROS names may not start with one). Penelope's object names
/// (letters, digits, `-`, `_`, `.`) map one to one unless two differ only there.
pub fn ros_name(name: &str) -> String {
    let mut out: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if out.is_empty() || out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert(0, '_');
    }
    out
}

/// Camera `camera`'s two topics: its compressed image's, then its calibration's.
pub fn camera_topics(camera: &str) -> [String; 2] {
    let name = ros_name(camera);
    [
        format!("/{name}/image_raw/compressed"),
        format!("/{name}/camera_info"),
    ]
}

/// A camera's frame as its two ROS 2 messages on [`camera_topics`] (see the module's table):
/// the image, then its calibration, both stamped `stamp_ns` (the frame's capture instant on
/// the caller's clock).
pub fn camera_messages(camera: &str, frame: &CameraFrame, stamp_ns: u64) -> [TopicMessage; 2] {
    let [image, info] = camera_topics(camera);
    let header = Header {
        stamp: Time::from_ns(stamp_ns),
        frame_id: frame.model.frame_id.clone(),
    };
    let m = &frame.model;
    [
        TopicMessage {
            topic: image,
            payload: Ros2Payload::Image(CompressedImage {
                header: header.clone(),
                format: frame.encoding.name().into(),
                data: frame.data.clone(),
            }),
        },
        TopicMessage {
            topic: info,
            payload: Ros2Payload::CameraInfo(Box::new(CameraInfo::pinhole(
                header,
                m.width,
                m.height,
                [m.fx, m.fy],
                [m.cx, m.cy],
            ))),
        },
    ]
}

/// Whether `topic` carries sensor-rate data (a robot's `measured_*` and `setpoint_js`, a
/// channel's `feedback_*`, a camera's image and calibration):
/// offered best effort, as ROS 2's sensor-data QoS profile; the others (`/tf`,
/// `operating_state`, `/diagnostics`) reliable.
pub fn sensor_rate(topic: &str) -> bool {
    [
        "/measured_js",
        "/measured_cp",
        "/measured_cf",
        "/setpoint_js",
        "/feedback_cp",
        "/feedback_cf",
        "/image_raw/compressed",
        "/camera_info",
    ]
    .iter()
    .any(|suffix| topic.ends_with(suffix))
}

/// A robot's topic names.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RobotTopics {
    /// `/<robot>/measured_js`.
    pub measured_js: String,
    /// `/<robot>/measured_cp`.
    pub measured_cp: String,
    /// `/<robot>/measured_cf`.
    pub measured_cf: String,
    /// `/<robot>/setpoint_js`.
    pub setpoint_js: String,
    /// `/<robot>/operating_state`.
    pub operating_state: String,
}

impl RobotTopics {
    /// The topics of the robot object named `robot`.
    pub fn new(robot: &str) -> Self {
        let ns = ros_name(robot);
        RobotTopics {
            measured_js: format!("/{ns}/measured_js"),
            measured_cp: format!("/{ns}/measured_cp"),
            measured_cf: format!("/{ns}/measured_cf"),
            setpoint_js: format!("/{ns}/setpoint_js"),
            operating_state: format!("/{ns}/operating_state"),
        }
    }
}

/// One robot's messages at one tick.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotMessages {
    /// Measured joints.
    pub measured_js: JointState,
    /// Measured tool pose.
    pub measured_cp: PoseStamped,
    /// Sensed wrench (`None`: the robot has no force sensor).
    pub measured_cf: Option<WrenchStamped>,
    /// The joint reference.
    pub setpoint_js: JointState,
    /// The CRTK operating state.
    pub operating_state: OperatingState,
    /// Its frames.
    pub tf: TFMessage,
}

/// Any message of the topic set, for writers that handle them alike.
#[derive(Clone, Debug, PartialEq)]
pub enum Ros2Payload {
    /// `sensor_msgs/msg/JointState`.
    JointState(JointState),
    /// `geometry_msgs/msg/PoseStamped`.
    PoseStamped(PoseStamped),
    /// `geometry_msgs/msg/WrenchStamped`.
    WrenchStamped(WrenchStamped),
    /// `crtk_msgs/msg/OperatingState`.
    OperatingState(OperatingState),
    /// `tf2_msgs/msg/TFMessage`.
    Tf(TFMessage),
    /// `diagnostic_msgs/msg/DiagnosticArray`.
    Diagnostics(DiagnosticArray),
    /// `sensor_msgs/msg/CompressedImage`.
    Image(CompressedImage),
    /// `sensor_msgs/msg/CameraInfo` (boxed: its matrices would make every payload large).
    CameraInfo(Box<CameraInfo>),
}

macro_rules! each_payload {
    ($self:ident, $m:ident => $body:expr) => {
        match $self {
            Ros2Payload::JointState($m) => $body,
            Ros2Payload::PoseStamped($m) => $body,
            Ros2Payload::WrenchStamped($m) => $body,
            Ros2Payload::OperatingState($m) => $body,
            Ros2Payload::Tf($m) => $body,
            Ros2Payload::Diagnostics($m) => $body,
            Ros2Payload::Image($m) => $body,
            Ros2Payload::CameraInfo(boxed) => {
                let $m = &**boxed;
                $body
            }
        }
    };
}

impl Ros2Payload {
    /// The message's type's description (name, schema text, RIHS01 hash).
    pub fn description(&self) -> &'static penelope_ros2_msgs::MessageDescription {
        fn of<M: RosMessage>(_: &M) -> &'static penelope_ros2_msgs::MessageDescription {
            M::DESCRIPTION
        }
        each_payload!(self, m => of(m))
    }

    /// Its CDR, encapsulation header included, appended to `out`.
    pub fn encode_cdr(&self, out: &mut Vec<u8>) {
        each_payload!(self, m => m.encode_cdr(out))
    }
}

/// A message and the topic it goes on.
#[derive(Clone, Debug, PartialEq)]
pub struct TopicMessage {
    /// The topic.
    pub topic: String,
    /// The message.
    pub payload: Ros2Payload,
}

impl RobotMessages {
    /// The messages with their topics (`/tf` last), `measured_cf` left out without a sensor.
    pub fn into_topics(self, topics: &RobotTopics) -> Vec<TopicMessage> {
        let on = |topic: &String, payload| TopicMessage {
            topic: topic.clone(),
            payload,
        };
        let mut out = vec![
            on(
                &topics.measured_js,
                Ros2Payload::JointState(self.measured_js),
            ),
            on(
                &topics.measured_cp,
                Ros2Payload::PoseStamped(self.measured_cp),
            ),
        ];
        if let Some(cf) = self.measured_cf {
            out.push(on(&topics.measured_cf, Ros2Payload::WrenchStamped(cf)));
        }
        out.push(on(
            &topics.setpoint_js,
            Ros2Payload::JointState(self.setpoint_js),
        ));
        out.push(on(
            &topics.operating_state,
            Ros2Payload::OperatingState(self.operating_state),
        ));
        out.push(TopicMessage {
            topic: TF_TOPIC.into(),
            payload: Ros2Payload::Tf(self.tf),
        });
        out
    }
}

fn header(stamp_ns: u64, frame_id: String) -> Header {
    Header {
        stamp: Time::from_ns(stamp_ns),
        frame_id,
    }
}

fn vector3(v: &penelope_hal::nalgebra::Vector3<f64>) -> Vector3 {
    Vector3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

fn transform(pose: &Pose) -> Transform {
    let p = ScenePose::from(pose);
    Transform {
        translation: Vector3 {
            x: p.position.x,
            y: p.position.y,
            z: p.position.z,
        },
        rotation: Quaternion {
            x: p.orientation.x,
            y: p.orientation.y,
            z: p.orientation.z,
            w: p.orientation.w,
        },
    }
}

fn stamped(stamp_ns: u64, parent: String, child: String, pose: &Pose) -> TransformStamped {
    TransformStamped {
        header: header(stamp_ns, parent),
        child_frame_id: child,
        transform: transform(pose),
    }
}

/// CRTK's state for a safety state: inactive → `DISABLED`, running → `ENABLED`, holding (a
/// stale reference: a slave holds, a master pushes nothing) → `PAUSED`, fault or e-stop →
/// `FAULT`.
pub fn crtk_state(state: SafetyState) -> &'static str {
    match state {
        SafetyState::Inactive => OperatingState::DISABLED,
        SafetyState::Running => OperatingState::ENABLED,
        SafetyState::Holding => OperatingState::PAUSED,
        SafetyState::Fault | SafetyState::EStop => OperatingState::FAULT,
    }
}

/// `robot`'s messages at tick `record`, stamped `stamp_ns` (see the [module](self)).
///
/// `measured_js`: the model's joint names, measured positions and velocities, and the efforts
/// commanded this tick (what the loop drives the joints with; a slave's measured contact is on
/// `measured_cf`). `setpoint_js`: the same names, the joint reference's positions when the
/// reference in force is a joint one (empty otherwise: a Cartesian reference has no joint
/// setpoint until the controller solves it) and the commanded efforts.
/// `operating_state`: [`crtk_state`]; `is_homed` true (Penelope's robots know their joints
/// from absolute positions or from the simulated plant, there is no homing step); `is_busy`
/// while the loop runs on a reference.
pub fn robot_messages(robot: &SceneRobot, record: &TickRecord, stamp_ns: u64) -> RobotMessages {
    let sample = &record.sample;
    let model = &robot.model;
    let n = model.joint_names().len().min(sample.q.len());
    let names: Vec<String> = model.joint_names()[..n].to_vec();
    let take = |v: &penelope_hal::JointVector| v.iter().take(n).copied().collect::<Vec<f64>>();
    let frames = model.link_names();
    let poses = model.link_frames(&sample.q);
    let root = frame_id(&robot.robot, frames.first().map_or("", String::as_str));
    let tool = frame_id(&robot.robot, frames.last().map_or("", String::as_str));
    let tool_pose = poses.last().copied().unwrap_or_else(Pose::identity);
    let sensor = frame_id(&robot.robot, SENSOR_FRAME);

    let measured_js = JointState {
        header: header(stamp_ns, String::new()),
        name: names.clone(),
        position: take(&sample.q),
        velocity: take(&sample.qd),
        effort: take(&sample.effort),
    };
    let setpoint_js = JointState {
        header: header(stamp_ns, String::new()),
        name: names,
        position: if sample.reference_kind == ReferenceKind::Joint {
            take(&sample.reference_q)
        } else {
            Vec::new()
        },
        velocity: Vec::new(),
        effort: take(&sample.effort),
    };
    let cp = transform(&tool_pose);
    let measured_cp = PoseStamped {
        header: header(stamp_ns, root.clone()),
        pose: penelope_ros2_msgs::Pose {
            position: Point {
                x: cp.translation.x,
                y: cp.translation.y,
                z: cp.translation.z,
            },
            orientation: cp.rotation,
        },
    };
    let measured_cf = robot.sensor_mount.map(|_| {
        let frame = match sample.wrench.frame {
            Frame::Sensor => sensor.clone(),
            Frame::Tool | Frame::Flange => tool.clone(),
            Frame::Base | Frame::Master => root.clone(),
        };
        WrenchStamped {
            header: header(stamp_ns, frame),
            wrench: Wrench {
                force: vector3(&sample.wrench.force),
                torque: vector3(&sample.wrench.torque),
            },
        }
    });
    let operating_state = OperatingState {
        header: header(stamp_ns, String::new()),
        state: crtk_state(sample.state).into(),
        is_homed: true,
        is_busy: sample.state == SafetyState::Running
            && sample.reference_kind != ReferenceKind::None,
    };
    let mut transforms = Vec::with_capacity(frames.len() + 1);
    transforms.push(stamped(
        stamp_ns,
        WORLD_FRAME.into(),
        root.clone(),
        &robot.placement,
    ));
    for (frame, pose) in frames.iter().zip(&poses).skip(1) {
        transforms.push(stamped(
            stamp_ns,
            root.clone(),
            frame_id(&robot.robot, frame),
            pose,
        ));
    }
    if let Some(mount) = &robot.sensor_mount {
        transforms.push(stamped(stamp_ns, tool, sensor, mount));
    }
    RobotMessages {
        measured_js,
        measured_cp,
        measured_cf,
        setpoint_js,
        operating_state,
        tf: TFMessage { transforms },
    }
}

/// Channel `channel`'s link statistics as `/diagnostics`, stamped `stamp_ns`: one status named
/// `<channel>: link`, ERROR while the link is down, WARN once it has been lost (and came back),
/// OK otherwise; every figure of the record as a key-value (durations in ns, absent ones
/// empty).
pub fn link_diagnostics(channel: &str, record: &LinkRecord, stamp_ns: u64) -> DiagnosticArray {
    let (level, message) = if record.down {
        (DiagnosticStatus::ERROR, "down".to_string())
    } else if record.losses > 0 {
        (
            DiagnosticStatus::WARN,
            format!(
                "up; lost {} times, restored {} times",
                record.losses, record.restorations
            ),
        )
    } else {
        (DiagnosticStatus::OK, "up".to_string())
    };
    let optional = |v: Option<i64>| v.map_or_else(String::new, |v| v.to_string());
    let values = [
        ("time_ns", record.time_ns.to_string()),
        ("down", record.down.to_string()),
        ("losses", record.losses.to_string()),
        ("restorations", record.restorations.to_string()),
        ("samples_taken", record.samples_taken.to_string()),
        ("samples_dropped", record.samples_dropped.to_string()),
        ("samples_missed", record.samples_missed.to_string()),
        ("refused", record.refused.to_string()),
        ("clock_offset_ns", optional(record.clock_offset_ns)),
        ("round_trip_ns", optional(record.round_trip_ns)),
        ("one_way_delay_ns", optional(record.one_way_delay_ns)),
        ("jitter_ns", optional(record.jitter_ns)),
        ("last_heard_ns", optional(record.last_heard_ns)),
        ("heartbeat_loss", record.heartbeat_loss.to_string()),
        ("trips", record.trips.to_string()),
        ("trip_p50_ns", optional(record.trip_p50_ns)),
        ("trip_p99_ns", optional(record.trip_p99_ns)),
        ("trip_max_ns", optional(record.trip_max_ns)),
    ]
    .into_iter()
    .map(|(key, value)| KeyValue {
        key: key.into(),
        value,
    })
    .collect();
    DiagnosticArray {
        header: header(stamp_ns, String::new()),
        status: vec![DiagnosticStatus {
            level,
            name: format!("{channel}: link"),
            message,
            hardware_id: String::new(),
            values,
        }],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_hal::{JointVector, Timestamp};
    use penelope_rt_core::telemetry::TelemetrySample;

    fn puma(sensor: bool) -> SceneRobot {
        let model = penelope_drivers::model::puma560();
        SceneRobot {
            robot: "slave-arm".into(),
            controller: "follow".into(),
            model,
            placement: Pose::translation(0.0, 1.0, 0.0),
            contacts: Vec::new(),
            sensor_mount: sensor.then(|| Pose::translation(0.0, 0.0, 0.05)),
        }
    }

    fn tick(state: SafetyState, kind: ReferenceKind) -> TickRecord {
        TickRecord {
            sample: TelemetrySample {
                time: Timestamp::from_nanos(2_500_000_001),
                seq: 3,
                q: JointVector::from_fn(|j, _| 0.1 * (j as f64 + 1.0)),
                qd: JointVector::from_fn(|j, _| -0.01 * j as f64),
                effort: JointVector::from_fn(|j, _| j as f64),
                reference_kind: kind,
                reference_q: JointVector::from_fn(|j, _| 0.2 * j as f64),
                wrench: penelope_hal::Wrench {
                    force: penelope_hal::nalgebra::Vector3::new(1.0, -2.0, 3.0),
                    torque: penelope_hal::nalgebra::Vector3::new(0.1, 0.2, 0.3),
                    frame: Frame::Sensor,
                },
                state,
                ..TelemetrySample::default()
            },
            truth: None,
            clutch: None,
        }
    }

    #[test]
    fn a_tick_becomes_the_crtk_topic_set() {
        let robot = puma(true);
        let record = tick(SafetyState::Running, ReferenceKind::Joint);
        let stamp = record.sample.time.as_nanos();
        let m = robot_messages(&robot, &record, stamp);
        let names = robot.model.joint_names();
        assert_eq!(m.measured_js.name, names);
        assert_eq!(m.measured_js.position.len(), 6);
        assert_eq!(m.measured_js.position[2], 0.1 * 3.0);
        assert_eq!(m.measured_js.velocity[1], -0.01);
        assert_eq!(m.measured_js.effort[5], 5.0);
        assert_eq!(
            m.measured_js.header.stamp,
            Time {
                sec: 2,
                nanosec: 500_000_001
            }
        );
        assert_eq!(m.setpoint_js.position[3], 0.2 * 3.0);
        // The tool pose is the model's forward kinematics, in the robot's root frame.
        let frames = robot.model.link_names();
        assert_eq!(
            m.measured_cp.header.frame_id,
            format!("slave-arm/{}", frames[0])
        );
        let fk = *robot.model.link_frames(&record.sample.q).last().unwrap();
        let p = fk.translation.vector;
        assert_eq!(
            [
                m.measured_cp.pose.position.x,
                m.measured_cp.pose.position.y,
                m.measured_cp.pose.position.z
            ],
            [p.x, p.y, p.z]
        );
        let cf = m.measured_cf.as_ref().expect("a robot with a sensor");
        assert_eq!(cf.header.frame_id, "slave-arm/sensor");
        assert_eq!((cf.wrench.force.y, cf.wrench.torque.z), (-2.0, 0.3));
        assert_eq!(m.operating_state.state, "ENABLED");
        assert!(m.operating_state.is_busy && m.operating_state.is_homed);
        // /tf: world -> root, root -> every other frame, tool -> sensor.
        let tf = &m.tf.transforms;
        assert_eq!(tf.len(), frames.len() + 1);
        assert_eq!(tf[0].header.frame_id, "world");
        assert_eq!(tf[0].transform.translation.y, 1.0);
        assert_eq!(tf.last().unwrap().child_frame_id, "slave-arm/sensor");
        assert_eq!(
            tf.last().unwrap().header.frame_id,
            format!("slave-arm/{}", frames.last().unwrap())
        );
        let topics = RobotTopics::new(&robot.robot);
        assert_eq!(topics.measured_js, "/slave_arm/measured_js");
        let all = m.into_topics(&topics);
        let named: Vec<(&str, &str)> = all
            .iter()
            .map(|t| (t.topic.as_str(), t.payload.description().type_name))
            .collect();
        assert_eq!(
            named,
            [
                ("/slave_arm/measured_js", "sensor_msgs/msg/JointState"),
                ("/slave_arm/measured_cp", "geometry_msgs/msg/PoseStamped"),
                ("/slave_arm/measured_cf", "geometry_msgs/msg/WrenchStamped"),
                ("/slave_arm/setpoint_js", "sensor_msgs/msg/JointState"),
                ("/slave_arm/operating_state", "crtk_msgs/msg/OperatingState"),
                ("/tf", "tf2_msgs/msg/TFMessage"),
            ]
        );
        // Each payload's CDR decodes back to it.
        for t in &all {
            let mut bytes = Vec::new();
            t.payload.encode_cdr(&mut bytes);
            let back = match &t.payload {
                Ros2Payload::JointState(_) => {
                    Ros2Payload::JointState(JointState::decode_cdr(&bytes).unwrap())
                }
                Ros2Payload::PoseStamped(_) => {
                    Ros2Payload::PoseStamped(PoseStamped::decode_cdr(&bytes).unwrap())
                }
                Ros2Payload::WrenchStamped(_) => {
                    Ros2Payload::WrenchStamped(WrenchStamped::decode_cdr(&bytes).unwrap())
                }
                Ros2Payload::OperatingState(_) => {
                    Ros2Payload::OperatingState(OperatingState::decode_cdr(&bytes).unwrap())
                }
                Ros2Payload::Tf(_) => Ros2Payload::Tf(TFMessage::decode_cdr(&bytes).unwrap()),
                Ros2Payload::Diagnostics(_) => {
                    Ros2Payload::Diagnostics(DiagnosticArray::decode_cdr(&bytes).unwrap())
                }
                Ros2Payload::Image(_) | Ros2Payload::CameraInfo(_) => {
                    unreachable!("a tick makes no camera messages")
                }
            };
            assert_eq!(back, t.payload, "{}", t.topic);
        }
    }

    #[test]
    fn the_tf_frames_are_the_recordings_scene_frames() {
        let robot = puma(false);
        let record = tick(SafetyState::Holding, ReferenceKind::Cartesian);
        let m = robot_messages(&robot, &record, 7);
        assert!(m.measured_cf.is_none(), "no sensor, no measured_cf");
        assert!(
            m.setpoint_js.position.is_empty(),
            "a Cartesian reference has no joint setpoint"
        );
        assert_eq!(m.operating_state.state, "PAUSED");
        assert!(!m.operating_state.is_busy);
        let frames = robot.model.link_names();
        let poses = robot.model.link_frames(&record.sample.q);
        let scene =
            penelope_scene::robot_transforms(&robot.robot, &frames, &poses, &robot.placement, 7);
        assert_eq!(scene.transforms.len(), m.tf.transforms.len());
        for (ours, theirs) in m.tf.transforms.iter().zip(&scene.transforms) {
            assert_eq!(ours.header.frame_id, theirs.parent_frame_id);
            assert_eq!(ours.child_frame_id, theirs.child_frame_id);
            assert_eq!(ours.transform.translation.x, theirs.translation.x);
            assert_eq!(ours.transform.rotation.w, theirs.rotation.w);
        }
    }

    #[test]
    fn states_and_links_map_to_crtk_and_diagnostic_levels() {
        assert_eq!(crtk_state(SafetyState::Inactive), "DISABLED");
        assert_eq!(crtk_state(SafetyState::EStop), "FAULT");
        assert_eq!(crtk_state(SafetyState::Fault), "FAULT");
        let mut link = LinkRecord {
            time_ns: 5,
            down: false,
            losses: 0,
            restorations: 0,
            samples_taken: 10,
            samples_dropped: 0,
            samples_missed: 0,
            refused: 0,
            clock_offset_ns: None,
            round_trip_ns: Some(250_000),
            one_way_delay_ns: None,
            jitter_ns: None,
            last_heard_ns: None,
            heartbeat_loss: 0.0,
            trips: 0,
            trip_p50_ns: None,
            trip_p99_ns: None,
            trip_max_ns: None,
        };
        let d = link_diagnostics("link", &link, 9);
        assert_eq!(d.status[0].level, DiagnosticStatus::OK);
        assert_eq!(d.status[0].name, "link: link");
        let rtt = d.status[0]
            .values
            .iter()
            .find(|kv| kv.key == "round_trip_ns")
            .unwrap();
        assert_eq!(rtt.value, "250000");
        link.losses = 1;
        link.restorations = 1;
        assert_eq!(
            link_diagnostics("link", &link, 9).status[0].level,
            DiagnosticStatus::WARN
        );
        link.down = true;
        assert_eq!(
            link_diagnostics("link", &link, 9).status[0].level,
            DiagnosticStatus::ERROR
        );
        assert_eq!(ros_name("2nd-arm.x"), "_2nd_arm_x");
    }
}
