//! The ROS 2 presence on the bridge's Zenoh session (feature `zenoh`): the node's liveliness
//! tokens, the publishers of the CRTK topic set, the cameras' images and calibrations and
//! `/diagnostics`, and the subscriptions that turn ROS 2 servo targets and operator poses into
//! the node's own calls. Driven by the Zenoh bridge's thread: it hands over what it discovers
//! and every tick and frame it drains; the subscriptions' callbacks run on Zenoh's threads and
//! reach the loops only through the robots' servo methods and the bridged channels' cells.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::sync::{Arc, Weak};
use std::time::{SystemTime, UNIX_EPOCH};

use penelope_protocol::proto::{CameraFrame, Class, LinkRecord, Method, PoseMsg, RobotMethod};
use penelope_ros2_msgs::{
    CameraInfo, CompressedImage, JointState, Joy, MessageDescription, OperatingState, PoseStamped,
    RosMessage, TFMessage, WrenchStamped,
};
use penelope_runtime::objects::Creator;
use penelope_runtime::objects::bridged::{BridgedChannels, OperatorPose};
use penelope_runtime::objects::recording::SceneRobot;
use penelope_runtime::objects::recording::ros2_topics::{
    self, DIAGNOSTICS_TOPIC, RobotTopics, Ros2Payload, TF_TOPIC, TopicMessage, ros_name,
};
use penelope_runtime::objects::tick::TickRecord;
use zenoh::Wait;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::sample::Sample;

use super::attachment::Attachment;
use super::graph::{self, Endpoint, EntityKind, NodeIdentity, Qos};
use super::{Ros2Error, Ros2Settings, Ros2Stats};

/// The presence's counters, shared with the subscriptions' callbacks.
#[derive(Debug, Default)]
pub(crate) struct Counters {
    tokens: AtomicU64,
    published: AtomicU64,
    taken: AtomicU64,
    refused: AtomicU64,
}

impl Counters {
    /// What they say now.
    pub(crate) fn stats(&self) -> Ros2Stats {
        let n = |a: &AtomicU64| a.load(Ordering::Relaxed);
        Ros2Stats {
            tokens: n(&self.tokens),
            published: n(&self.published),
            taken: n(&self.taken),
            refused: n(&self.refused),
        }
    }

    fn count(&self, taken: bool) {
        let counter = if taken { &self.taken } else { &self.refused };
        counter.fetch_add(1, Ordering::Relaxed);
    }
}

/// A topic's publisher, its token, and what its attachments carry.
struct TopicPublisher {
    publisher: Publisher<'static>,
    _token: LivelinessToken,
    gid: [u8; 16],
    sequence: i64,
}

/// A robot whose topics are published: its description, topic names, and the tick time it
/// was last published at.
struct Robot {
    robot: SceneRobot,
    topics: RobotTopics,
    last_ns: Option<u64>,
}

/// The node in the ROS 2 graph: see the [module](self).
pub(crate) struct Ros2Presence {
    session: zenoh::Session,
    domain_id: u32,
    identity: NodeIdentity,
    next_entity: u32,
    _node_token: LivelinessToken,
    period_ns: u64,
    /// Unix time minus the node's clock when the presence started: headers are stamped in
    /// ROS time (the Unix epoch), as other ROS 2 nodes' are.
    unix_offset_ns: i64,
    /// By controller.
    robots: BTreeMap<String, Robot>,
    /// By topic.
    publishers: BTreeMap<String, TopicPublisher>,
    subscriptions: Vec<(Subscriber<()>, LivelinessToken)>,
    /// Robots whose subscriptions are declared.
    served: BTreeSet<String>,
    /// Controllers with no robot yet (a system file binds one after creating the controller):
    /// looked at again on each discovery.
    pending: BTreeSet<String>,
    /// The running cameras whose frames are published, by name: a tap of their frames.
    cameras: BTreeMap<String, Receiver<CameraFrame>>,
    /// The node's estimate of the common clock less its own clock, ns (frames are stamped on
    /// the common clock; headers in ROS time, from the node's clock).
    common_offset_ns: i64,
    counters: Arc<Counters>,
    scratch: Vec<u8>,
}

/// Nanoseconds since the Unix epoch.
fn unix_now_ns() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

/// The type and QoS a topic of the set is declared with: the sensor-rate topics best effort
/// (ROS 2's sensor-data profile), `/tf`, `operating_state` and `/diagnostics` reliable.
fn endpoint(topic: &str, description: &'static MessageDescription) -> Endpoint {
    Endpoint {
        topic: topic.to_string(),
        type_name: description.type_name.to_string(),
        type_hash: description.type_hash(),
        qos: if ros2_topics::sensor_rate(topic) {
            Qos::SENSOR_DATA
        } else {
            Qos::DEFAULT
        },
    }
}

impl Ros2Presence {
    /// Declares node `penelope_<node>` in `settings`' domain on `session`.
    ///
    /// # Errors
    /// [`Ros2Error::NodeToken`] when the token cannot be declared.
    pub(crate) fn start(
        session: &zenoh::Session,
        node: &str,
        settings: Ros2Settings,
        node_time_ns: u64,
    ) -> Result<Ros2Presence, Ros2Error> {
        let identity = NodeIdentity {
            domain_id: settings.domain_id,
            zid: session.zid().to_string(),
            node_id: 0,
            name: format!("penelope_{}", ros_name(node)),
            namespace: "/".into(),
            enclave: "/".into(),
        };
        let token = graph::node_token(&identity);
        let node_token = session
            .liveliness()
            .declare_token(token.clone())
            .wait()
            .map_err(|e| Ros2Error::NodeToken(format!("{token}: {e}")))?;
        let counters = Arc::new(Counters::default());
        counters.tokens.fetch_add(1, Ordering::Relaxed);
        Ok(Ros2Presence {
            session: session.clone(),
            domain_id: settings.domain_id,
            identity,
            next_entity: 1,
            _node_token: node_token,
            period_ns: 1_000_000_000 / u64::from(settings.rate_hz.max(1)),
            unix_offset_ns: unix_now_ns()
                .saturating_sub(i64::try_from(node_time_ns).unwrap_or(i64::MAX)),
            robots: BTreeMap::new(),
            publishers: BTreeMap::new(),
            subscriptions: Vec::new(),
            served: BTreeSet::new(),
            pending: BTreeSet::new(),
            cameras: BTreeMap::new(),
            common_offset_ns: 0,
            counters,
            scratch: Vec::new(),
        })
    }

    /// Its counters, for the bridge's statistics.
    pub(crate) fn counters(&self) -> Arc<Counters> {
        self.counters.clone()
    }

    /// The liveliness token of a new publisher or subscription of `endpoint`, and its GID.
    fn declare_token(
        &mut self,
        kind: EntityKind,
        endpoint: &Endpoint,
    ) -> Option<(LivelinessToken, [u8; 16])> {
        let token = graph::endpoint_token(&self.identity, self.next_entity, kind, endpoint);
        self.next_entity += 1;
        match self
            .session
            .liveliness()
            .declare_token(token.clone())
            .wait()
        {
            Ok(declared) => {
                self.counters.tokens.fetch_add(1, Ordering::Relaxed);
                Some((declared, graph::gid(&token)))
            }
            Err(e) => {
                log::warn!("ros2: cannot declare {token}: {e}");
                None
            }
        }
    }

    /// Declares the publisher of `topic` (type `description`) unless it exists.
    fn declare_publisher(&mut self, topic: &str, description: &'static MessageDescription) {
        if self.publishers.contains_key(topic) {
            return;
        }
        let endpoint = endpoint(topic, description);
        let key = graph::topic_key(
            self.domain_id,
            topic,
            &endpoint.type_name,
            &endpoint.type_hash,
        );
        // Dropped, never blocking, under congestion: as rmw_zenoh's keep-last publishers.
        let publisher = match self
            .session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Drop)
            .wait()
        {
            Ok(p) => p,
            Err(e) => {
                log::warn!("ros2: cannot declare the publisher of {key}: {e}");
                return;
            }
        };
        let Some((token, gid)) = self.declare_token(EntityKind::Publisher, &endpoint) else {
            return;
        };
        self.publishers.insert(
            topic.to_string(),
            TopicPublisher {
                publisher,
                _token: token,
                gid,
                sequence: 0,
            },
        );
    }

    /// Declares a subscription of `topic` (type `description`) whose messages go to `take`
    /// (false: refused, counted).
    fn declare_subscription(
        &mut self,
        topic: &str,
        description: &'static MessageDescription,
        take: impl Fn(&[u8]) -> bool + Send + Sync + 'static,
    ) {
        let endpoint = Endpoint {
            qos: Qos::DEFAULT,
            ..endpoint(topic, description)
        };
        let key = graph::topic_key(
            self.domain_id,
            topic,
            &endpoint.type_name,
            &endpoint.type_hash,
        );
        let counters = self.counters.clone();
        let subscriber = self
            .session
            .declare_subscriber(key.clone())
            .callback(move |sample: Sample| {
                // A message without rmw_zenoh's attachment is no ROS 2 publisher's.
                let attached = sample
                    .attachment()
                    .is_some_and(|a| Attachment::from_zbytes(a).is_ok());
                counters.count(attached && take(&sample.payload().to_bytes()));
            })
            .wait();
        let subscriber = match subscriber {
            Ok(s) => s,
            Err(e) => {
                log::warn!("ros2: cannot subscribe to {key}: {e}");
                return;
            }
        };
        if let Some((token, _)) = self.declare_token(EntityKind::Subscription, &endpoint) {
            self.subscriptions.push((subscriber, token));
        }
    }

    /// Publishes the topic set of the robot `controller` drives, and takes servo targets for
    /// it; a controller with no robot yet is looked at again by [`Self::retry_pending`].
    pub(crate) fn add_controller(&mut self, creator: &Arc<Creator>, controller: &str) {
        let robot = creator
            .scene_for(&[controller.to_string()], 0.0)
            .ok()
            .and_then(|scene| scene.robots.into_iter().next());
        let Some(robot) = robot else {
            self.pending.insert(controller.to_string());
            return;
        };
        self.pending.remove(controller);
        let topics = RobotTopics::new(&robot.robot);
        self.declare_publisher(&topics.measured_js, JointState::DESCRIPTION);
        self.declare_publisher(&topics.measured_cp, PoseStamped::DESCRIPTION);
        if robot.sensor_mount.is_some() {
            self.declare_publisher(&topics.measured_cf, WrenchStamped::DESCRIPTION);
        }
        self.declare_publisher(&topics.setpoint_js, JointState::DESCRIPTION);
        self.declare_publisher(&topics.operating_state, OperatingState::DESCRIPTION);
        self.declare_publisher(TF_TOPIC, TFMessage::DESCRIPTION);
        if self.served.insert(robot.robot.clone()) {
            self.serve_robot(
                Arc::downgrade(creator),
                creator.bridged_channels(),
                &robot.robot,
            );
        }
        self.robots.insert(
            controller.to_string(),
            Robot {
                robot,
                topics,
                last_ns: None,
            },
        );
    }

    /// [`Self::add_controller`] again for the controllers that had no robot, while they exist.
    pub(crate) fn retry_pending(&mut self, creator: &Arc<Creator>) {
        for controller in std::mem::take(&mut self.pending) {
            if creator.info(&controller).is_some() {
                self.add_controller(creator, &controller);
            }
        }
    }

    /// `/<robot>/servo_jp` into the robot's `servo_jp`; `/<robot>/servo_cp` into the operator
    /// pose of the channel fed from Zenoh that drives the robot, if one does (the clutch of
    /// `/<robot>/clutch` with it), else into the robot's `servo_cp` (refused while the clutch
    /// is held: the operator's hand is off).
    fn serve_robot(&mut self, creator: Weak<Creator>, channels: BridgedChannels, robot: &str) {
        let ns = ros_name(robot);
        let call = move |creator: &Weak<Creator>, robot: &str, method: RobotMethod| {
            creator.upgrade().is_some_and(|c| {
                c.call_object(robot, Method::Robot(method))
                    .map_err(|e| log::debug!("ros2: {robot}: {e}"))
                    .is_ok()
            })
        };
        let (c, r) = (creator.clone(), robot.to_string());
        self.declare_subscription(
            &format!("/{ns}/servo_jp"),
            JointState::DESCRIPTION,
            move |bytes| {
                JointState::decode_cdr(bytes)
                    .is_ok_and(|m| call(&c, &r, RobotMethod::ServoJoints { q: m.position }))
            },
        );
        let clutch = Arc::new(AtomicBool::new(false));
        let held = clutch.clone();
        self.declare_subscription(&format!("/{ns}/clutch"), Joy::DESCRIPTION, move |bytes| {
            Joy::decode_cdr(bytes).is_ok_and(|joy| match joy.buttons.first() {
                Some(&button) => {
                    held.store(button != 0, Ordering::Relaxed);
                    true
                }
                None => false,
            })
        });
        let r = robot.to_string();
        self.declare_subscription(
            &format!("/{ns}/servo_cp"),
            PoseStamped::DESCRIPTION,
            move |bytes| {
                let Ok(m) = PoseStamped::decode_cdr(bytes) else {
                    return false;
                };
                let (p, q) = (m.pose.position, m.pose.orientation);
                let pose = OperatorPose {
                    clutch: clutch.load(Ordering::Relaxed),
                    position: [p.x, p.y, p.z],
                    orientation: [q.w, q.x, q.y, q.z],
                };
                if let Some(key) = channels.key_driving(&r) {
                    // The channel's own checks, as a Zenoh station's pose takes them.
                    return channels.offer_pose(&key, pose).is_ok();
                }
                !pose.clutch
                    && pose.checked().is_ok_and(|pose| {
                        call(
                            &creator,
                            &r,
                            RobotMethod::ServoTool {
                                pose: PoseMsg::from(&pose.pose()),
                            },
                        )
                    })
            },
        );
    }

    /// Starts publishing the frames of the node's running cameras not published yet
    /// (`/<camera>/image_raw/compressed`, `/<camera>/camera_info`), and takes the node's
    /// newest estimate of the common clock. A camera that is not running yet is looked at
    /// again on the next discovery.
    pub(crate) fn add_cameras(&mut self, creator: &Arc<Creator>) {
        self.common_offset_ns = creator.common_clock().estimate().offset_ns.unwrap_or(0);
        // Sensors not tapped yet: the taps are of the running cameras among them.
        let new: Vec<String> = creator
            .list()
            .into_iter()
            .filter(|o| o.class == Class::Sensor && !self.cameras.contains_key(&o.name))
            .map(|o| o.name)
            .collect();
        if new.is_empty() {
            return;
        }
        for (camera, tap) in creator.camera_taps_of(&new) {
            let [image, info] = ros2_topics::camera_topics(&camera);
            self.declare_publisher(&image, CompressedImage::DESCRIPTION);
            self.declare_publisher(&info, CameraInfo::DESCRIPTION);
            self.cameras.insert(camera, tap);
        }
    }

    /// Publishes every frame the cameras released since last time, stamped with its capture
    /// instant in ROS time; a camera that stopped (its tap closed) is let go, to be tapped
    /// again if it runs again.
    pub(crate) fn frames(&mut self) {
        let mut due = Vec::new();
        let mut stopped = Vec::new();
        for (camera, tap) in &self.cameras {
            loop {
                match tap.try_recv() {
                    Ok(frame) => due.push((camera.clone(), frame)),
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => {
                        stopped.push(camera.clone());
                        break;
                    }
                }
            }
        }
        for camera in stopped {
            self.cameras.remove(&camera);
        }
        for (camera, frame) in due {
            let stamp = frame
                .capture_ns
                .saturating_add_signed(self.unix_offset_ns.saturating_sub(self.common_offset_ns));
            for message in &ros2_topics::camera_messages(&camera, &frame, stamp) {
                self.publish(message);
            }
        }
    }

    /// Takes tick `record` of `controller`: publishes its robot's topic set when the period
    /// has passed (tick time) since it was last published.
    pub(crate) fn tick(&mut self, controller: &str, record: &TickRecord) {
        let Some(robot) = self.robots.get_mut(controller) else {
            return;
        };
        let time = record.sample.time.as_nanos();
        if robot
            .last_ns
            .is_some_and(|t| time < t.saturating_add(self.period_ns))
        {
            return;
        }
        robot.last_ns = Some(time);
        let stamp = time.saturating_add_signed(self.unix_offset_ns);
        let messages =
            ros2_topics::robot_messages(&robot.robot, record, stamp).into_topics(&robot.topics);
        for message in &messages {
            self.publish(message);
        }
    }

    /// Publishes what the slave end of `channel` (fed from Zenoh) sends back, for an operator
    /// station on ROS 2: `/<channel>/feedback_cp` (the slave's tool pose) and, when the sample
    /// carries one, `/<channel>/feedback_cf` (its sensed wrench, about the tool origin), both
    /// in the slave's base frame `<slave>/<root>`, stamped with the sample's time.
    pub(crate) fn feedback(
        &mut self,
        channels: &BridgedChannels,
        channel: &str,
        sample: &penelope_rt_core::teleop::TeleopSample,
    ) {
        let Some(slave) = channels.slave_of(channel) else {
            return;
        };
        let Some(root) = self
            .robots
            .values()
            .find(|r| r.robot.robot == slave)
            .and_then(|r| r.robot.model.link_names().into_iter().next())
        else {
            return;
        };
        let frame = penelope_scene::frame_id(&slave, &root);
        let stamp = sample
            .sent
            .as_nanos()
            .saturating_add_signed(self.unix_offset_ns);
        let header = || penelope_ros2_msgs::Header {
            stamp: penelope_ros2_msgs::Time::from_ns(stamp),
            frame_id: frame.clone(),
        };
        let (pose, wrench) = (sample.reference.pose(), sample.reference.wrench());
        let ns = ros_name(channel);
        if let Some(pose) = pose {
            let topic = format!("/{ns}/feedback_cp");
            self.declare_publisher(&topic, PoseStamped::DESCRIPTION);
            let q = pose.rotation.quaternion();
            let t = pose.translation.vector;
            let mut m = PoseStamped {
                header: header(),
                ..PoseStamped::default()
            };
            (m.pose.position.x, m.pose.position.y, m.pose.position.z) = (t.x, t.y, t.z);
            let o = &mut m.pose.orientation;
            (o.w, o.x, o.y, o.z) = (q.w, q.i, q.j, q.k);
            self.publish(&TopicMessage {
                topic,
                payload: Ros2Payload::PoseStamped(m),
            });
        }
        if let Some(w) = wrench {
            let topic = format!("/{ns}/feedback_cf");
            self.declare_publisher(&topic, WrenchStamped::DESCRIPTION);
            let mut m = WrenchStamped {
                header: header(),
                ..WrenchStamped::default()
            };
            let (f, t) = (&mut m.wrench.force, &mut m.wrench.torque);
            (f.x, f.y, f.z) = (w.force.x, w.force.y, w.force.z);
            (t.x, t.y, t.z) = (w.torque.x, w.torque.y, w.torque.z);
            self.publish(&TopicMessage {
                topic,
                payload: Ros2Payload::WrenchStamped(m),
            });
        }
    }

    /// Publishes channel `channel`'s link statistics on `/diagnostics`.
    pub(crate) fn link(&mut self, channel: &str, record: &LinkRecord) {
        let stamp = record.time_ns.saturating_add_signed(self.unix_offset_ns);
        self.declare_publisher(
            DIAGNOSTICS_TOPIC,
            penelope_ros2_msgs::DiagnosticArray::DESCRIPTION,
        );
        self.publish(&TopicMessage {
            topic: DIAGNOSTICS_TOPIC.into(),
            payload: Ros2Payload::Diagnostics(ros2_topics::link_diagnostics(
                channel, record, stamp,
            )),
        });
    }

    fn publish(&mut self, message: &TopicMessage) {
        let Some(topic) = self.publishers.get_mut(&message.topic) else {
            return;
        };
        self.scratch.clear();
        message.payload.encode_cdr(&mut self.scratch);
        topic.sequence += 1;
        let attachment = Attachment {
            sequence_number: topic.sequence,
            source_timestamp: unix_now_ns(),
            source_gid: topic.gid,
        };
        if topic
            .publisher
            .put(self.scratch.clone())
            .attachment(attachment.to_zbytes())
            .wait()
            .is_ok()
        {
            self.counters.published.fetch_add(1, Ordering::Relaxed);
        }
    }
}
