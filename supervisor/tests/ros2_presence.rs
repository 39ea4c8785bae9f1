//! The ROS 2 presence on the Zenoh bridge, end to end on loopback (scouting off): a test's Zenoh
//! peer where rmw_zenoh's router would be, a node on a simulated clock whose channel is fed
//! from Zenoh. The node declares its liveliness tokens; the slave's `servo_cp` and `clutch`,
//! published as a ROS 2 node would (CDR and rmw_zenoh's attachment), reach the channel as its
//! operator pose with the clutch; a payload that does not decode, or one without the attachment,
//! is refused and counted, and the loop never notices. (The independent client's view, with
//! Zenoh's Python binding and rosbags, is python/tests/test_ros2_rmw_zenoh.py.)
//!
//! Every wait is for something to happen, bounded; none is for a time to pass.
#![cfg(feature = "zenoh")]

mod common;

use std::time::Duration;

use common::zenoh_peer::{bridged_node, stats, test_peer};
use penelope_protocol::proto::{Call, ControllerMethod, Method, Reply, TelemetryRecord};
use penelope_ros2_msgs::{CameraInfo, CompressedImage, JointState, Joy, PoseStamped, RosMessage};
use penelope_runtime::objects::bridged::BridgedCounts;
use penelope_supervisor::node::Node;
use penelope_supervisor::ros2::Ros2Settings;
use penelope_supervisor::ros2::graph::topic_key;
use penelope_testkit::net::free_tcp_port;
use penelope_testkit::wait::wait_until;
use zenoh::Wait;
use zenoh_ext::ZSerializer;

/// A PUMA 200 following the poses of an operator station on Zenoh (channel `link`).
const SLAVE_SYSTEM: &str = include_str!("data/zenoh_station_slave.toml");

/// A PUMA 560 on a simulated board held at its start pose by a joint PID: a robot that takes
/// servo targets itself.
const SERVO_SYSTEM: &str = r#"
[boards.sim0]
kind = "sim"

[robots.arm]
kind = "puma560"
start = "start"
joints = [{ board = "sim0", joints = [0, 1, 2, 3, 4, 5] }]

[trajectories.hold]
kind = "step"
pose = "start"

[controllers.pid]
kind = "joint-pid"
robot = "arm"
trajectory = "hold"
period_us = 1000
# The defaults plus an integral term: the simulated joints' friction leaves no steady error.
kp = [3600.0, 6400.0, 3600.0, 400.0, 400.0, 400.0]
kd = [40.0, 40.0, 40.0, 10.0, 10.0, 10.0]
ki = [8000.0, 8000.0, 8000.0, 800.0, 800.0, 800.0]
integral_limit = [30.0, 30.0, 30.0, 3.0, 3.0, 3.0]
"#;

fn slave_node(port: u16) -> Node {
    ros2_node(port, SLAVE_SYSTEM)
}

fn ros2_node(port: u16, system: &str) -> Node {
    let ros2 = Ros2Settings {
        domain_id: 3,
        rate_hz: 100,
    };
    bridged_node("slave", port, system, Some(ros2))
}

fn status_last(node: &Node) -> TelemetryRecord {
    status_of(node, "follow")
}

fn status_of(node: &Node, controller: &str) -> TelemetryRecord {
    match node.call(Call::Object {
        object: controller.into(),
        method: Method::Controller(ControllerMethod::Status),
    }) {
        Ok(Reply::Status(s)) => *s.last.expect("ticked"),
        other => panic!("{other:?}"),
    }
}

/// The liveliness tokens of domain 3 as the test's peer sees them, once it sees `count` (a
/// token propagates after it is declared: asked again until every one arrived). A node
/// declares each subscription before its token, on one session: once the peer sees the token,
/// it routes puts to the subscription.
fn graph(peer: &zenoh::Session, count: usize) -> Vec<String> {
    let mut graph = Vec::new();
    wait_until("the peer sees the node's tokens", || {
        graph = peer
            .liveliness()
            .get("@ros2_lv/3/**")
            .timeout(Duration::from_secs(10))
            .wait()
            .unwrap()
            .iter()
            .filter_map(|r| r.into_result().ok().map(|s| s.key_expr().to_string()))
            .collect();
        graph.len() >= count
    });
    graph
}

/// What channel `link` took and refused.
fn channel(node: &Node) -> BridgedCounts {
    node.creator()
        .bridged_channels()
        .counts("link")
        .expect("a bridged channel")
}

/// rmw_zenoh's attachment (Jazzy's named form).
fn attachment(sequence: i64) -> zenoh::bytes::ZBytes {
    let mut out = ZSerializer::new();
    out.serialize("sequence_number");
    out.serialize(sequence);
    out.serialize("source_timestamp");
    out.serialize(1_764_300_000_000_000_000i64);
    out.serialize("source_gid");
    out.serialize([7u8; 16]);
    out.finish()
}

fn operator_pose(position: [f64; 3]) -> Vec<u8> {
    let mut m = PoseStamped::default();
    m.header.frame_id = "station".into();
    m.pose.position.x = position[0];
    m.pose.position.y = position[1];
    m.pose.position.z = position[2];
    m.pose.orientation.w = 1.0;
    m.to_cdr()
}

fn joy(button: i32) -> Vec<u8> {
    Joy {
        buttons: vec![button],
        ..Joy::default()
    }
    .to_cdr()
}

#[test]
fn ros2_servo_cp_and_the_clutch_drive_a_slave_fed_from_zenoh_and_bad_ones_are_counted() {
    let port = free_tcp_port();
    let peer = test_peer(port);
    let node = slave_node(port);
    // The node, five publishers of the PUMA's topic set (no sensor: no measured_cf), and its
    // servo_jp, servo_cp and clutch subscriptions.
    let graph = graph(&peer, 9);
    assert_eq!(stats(&node).ros2.tokens, 9);
    let kinds = |kind: &str| graph.iter().filter(|t| t.contains(kind)).count();
    assert_eq!(
        (kinds("/NN/"), kinds("/MP/"), kinds("/MS/")),
        (1, 5, 3),
        "{graph:#?}"
    );
    assert!(
        graph.iter().all(|t| t.contains("/%/%/penelope_slave")),
        "{graph:#?}"
    );

    let key = |topic: &str, description: &'static penelope_ros2_msgs::MessageDescription| {
        topic_key(3, topic, description.type_name, &description.type_hash())
    };
    let servo_cp = peer
        .declare_publisher(key("/puma/servo_cp", PoseStamped::DESCRIPTION))
        .wait()
        .unwrap();
    let clutch = peer
        .declare_publisher(key("/puma/clutch", Joy::DESCRIPTION))
        .wait()
        .unwrap();
    // What the slave end sends back, for the station: its tool pose on /link/feedback_cp.
    let (feedback_tx, feedback) = std::sync::mpsc::channel::<PoseStamped>();
    let _feedback = peer
        .declare_subscriber(key("/link/feedback_cp", PoseStamped::DESCRIPTION))
        .callback(move |s| {
            let m = PoseStamped::decode_cdr(&s.payload().to_bytes()).expect("a PoseStamped");
            let _ = feedback_tx.send(m);
        })
        .wait()
        .unwrap();
    let start = [0.4, 0.1, 0.3];
    let mut sequence = 0;
    let mut put = |publisher: &zenoh::pubsub::Publisher<'_>, payload: Vec<u8>| {
        sequence += 1;
        publisher
            .put(payload)
            .attachment(attachment(sequence))
            .wait()
            .unwrap();
    };
    let advance = |ticks: u32| {
        for _ in 0..ticks {
            node.creator().advance(Duration::from_millis(1)).unwrap();
        }
    };
    // Each message waited for: taken by the channel (a pose) or by the subscription (the Joy).
    let mut offer = |publisher: &zenoh::pubsub::Publisher<'_>, payload: Vec<u8>, pose: bool| {
        let (was_channel, was_ros2) = (channel(&node).taken, stats(&node).ros2.taken);
        put(publisher, payload);
        wait_until("the message taken", || {
            if pose {
                channel(&node).taken > was_channel
            } else {
                stats(&node).ros2.taken > was_ros2
            }
        });
    };
    // The station streams its pose every communication period (2 ms), as an operator's does.
    let stream = |offer: &mut dyn FnMut(&zenoh::pubsub::Publisher<'_>, Vec<u8>, bool),
                  position: [f64; 3],
                  ticks: u32| {
        for _ in 0..ticks / 2 {
            offer(&servo_cp, operator_pose(position), true);
            advance(2);
        }
    };
    let offset = |dz: f64| [start[0], start[1], start[2] + dz];
    stream(&mut offer, start, 500);
    let anchor = status_last(&node).tool_position;
    let moved = |node: &Node| status_last(node).tool_position[2] - anchor[2];

    // The clutch pressed (button 0 of a Joy message) where the hand is, then held while the
    // hand moves 2 cm up: the slave holds.
    offer(&clutch, joy(1), false);
    stream(&mut offer, start, 20);
    stream(&mut offer, offset(0.02), 300);
    let held = moved(&node);
    assert!(held.abs() < 1e-3, "clutched, the slave moved {held} m");
    // Released: the hand's motion from where it is now moves the slave (re-anchored): 1 cm up.
    offer(&clutch, joy(0), false);
    stream(&mut offer, offset(0.02), 20);
    stream(&mut offer, offset(0.03), 500);
    let followed = moved(&node);
    println!(
        "ros2 servo_cp and clutch into the channel: clutched the slave moved {:.3} mm for the hand's 20 mm; \
         released it moved {:.3} mm for the hand's next 10 mm",
        held * 1e3,
        followed * 1e3
    );
    assert!(
        (followed - 0.01).abs() < 2e-3,
        "released, the slave moved {followed} m"
    );
    // The feedback: every message in the slave's base frame; the newest at the slave's tool.
    let tool = status_last(&node).tool_position;
    let mut newest = feedback
        .recv_timeout(Duration::from_secs(20))
        .expect("feedback");
    let mut count = 1;
    wait_until("feedback from the slave's last tick", || {
        while let Ok(m) = feedback.try_recv() {
            assert_eq!(m.header.frame_id, "puma/base_link");
            newest = m;
            count += 1;
        }
        let p = &newest.pose.position;
        (p.x - tool[0]).abs() < 1e-3 && (p.y - tool[1]).abs() < 1e-3 && (p.z - tool[2]).abs() < 1e-3
    });
    println!("ros2 feedback_cp: {count} messages, the newest at the slave's tool");

    // Refused and counted, never reaching the channel: a payload that is no PoseStamped, a
    // pose with NaN (the channel's own check), and a message without rmw_zenoh's attachment.
    let (before, before_channel) = (stats(&node), channel(&node));
    put(&servo_cp, b"\x00\x01\x00\x00not a pose".to_vec());
    put(&servo_cp, operator_pose([f64::NAN, 0.0, 0.0]));
    servo_cp.put(operator_pose(start)).wait().unwrap();
    wait_until("three refusals counted", || {
        stats(&node).ros2.refused >= before.ros2.refused + 3
    });
    let after = stats(&node);
    let counts = channel(&node);
    assert_eq!(counts.taken, before_channel.taken, "{counts:?}");
    // The NaN one reached the channel's check and was refused there.
    assert_eq!(counts.refused, before_channel.refused + 1, "{counts:?}");
    node.creator().advance(Duration::from_millis(5)).unwrap();
    let last = status_last(&node);
    assert!(last.fault.is_none(), "{:?}", last.fault);
    println!("ros2 presence: {after:?}");
    node.shutdown();
}

#[test]
fn ros2_servo_jp_drives_a_robot_and_its_servo_cp_is_refused_while_the_clutch_is_held() {
    let port = free_tcp_port();
    let peer = test_peer(port);
    let node = ros2_node(port, SERVO_SYSTEM);
    graph(&peer, 9);
    let key = |topic: &str, description: &'static penelope_ros2_msgs::MessageDescription| {
        topic_key(3, topic, description.type_name, &description.type_hash())
    };
    let declare = |topic: &str, description| {
        peer.declare_publisher(key(topic, description))
            .wait()
            .unwrap()
    };
    let servo_jp = declare("/arm/servo_jp", JointState::DESCRIPTION);
    let servo_cp = declare("/arm/servo_cp", PoseStamped::DESCRIPTION);
    let clutch = declare("/arm/clutch", Joy::DESCRIPTION);
    let mut sequence = 0;
    // Published, then waited for until the subscription counted it (taken or refused);
    // whether it was taken.
    let mut send = |publisher: &zenoh::pubsub::Publisher<'_>, payload: Vec<u8>| {
        let before = stats(&node).ros2;
        sequence += 1;
        publisher
            .put(payload)
            .attachment(attachment(sequence))
            .wait()
            .unwrap();
        wait_until("the message counted", || {
            let now = stats(&node).ros2;
            now.taken + now.refused > before.taken + before.refused
        });
        stats(&node).ros2.taken > before.taken
    };
    for _ in 0..20 {
        node.creator().advance(Duration::from_millis(1)).unwrap();
    }
    let start = status_of(&node, "pid").q;
    // servo_jp: joint 0 by 0.02 rad (within the step limit), held by streaming it.
    let mut target = start.clone();
    target[0] += 0.02;
    let joints = JointState {
        position: target.clone(),
        ..JointState::default()
    };
    for _ in 0..100 {
        assert!(send(&servo_jp, joints.to_cdr()), "servo_jp refused");
        for _ in 0..5 {
            node.creator().advance(Duration::from_millis(1)).unwrap();
        }
    }
    let q = status_of(&node, "pid").q;
    println!(
        "ros2 servo_jp: joint 0 {:.4} -> {:.4} rad (target {:.4})",
        start[0], q[0], target[0]
    );
    assert!((q[0] - target[0]).abs() < 2e-3, "{q:?} for {target:?}");
    // A step past the servo step limit (0.05 rad) is refused by the robot's own check.
    let mut far = target.clone();
    far[0] += 0.3;
    let jump = JointState {
        position: far,
        ..JointState::default()
    };
    assert!(!send(&servo_jp, jump.to_cdr()), "a 0.3 rad jump taken");
    // The clutch held: servo_cp is refused (the operator's hand is off); released, taken.
    let mut pose = PoseStamped::default();
    let tool = status_of(&node, "pid").tool_position;
    pose.pose.position.x = tool[0];
    pose.pose.position.y = tool[1];
    pose.pose.position.z = tool[2];
    pose.pose.orientation.w = 1.0;
    assert!(send(&clutch, joy(1)));
    assert!(
        !send(&servo_cp, pose.to_cdr()),
        "servo_cp taken while clutched"
    );
    assert!(send(&clutch, joy(0)));
    println!("ros2 presence: {:?}", stats(&node).ros2);
    node.shutdown();
}

#[test]
fn a_cameras_frames_are_published_as_compressed_images_with_their_camera_info() {
    let port = free_tcp_port();
    let peer = test_peer(port);
    let system = format!(
        "{SERVO_SYSTEM}
[sensors.wrist_cam]
kind = \"sim-camera\"
robot = \"arm\"
eye = [1.5, -1.0, 1.0]
target = [0.0, 0.0, 0.5]
up = [0.0, 0.0, 1.0]
width = 160
height = 120
rate_hz = 50.0
"
    );
    let node = ros2_node(port, &system);
    let key = |topic: &str, description: &'static penelope_ros2_msgs::MessageDescription| {
        topic_key(3, topic, description.type_name, &description.type_hash())
    };
    let images = peer
        .declare_subscriber(key(
            "/wrist_cam/image_raw/compressed",
            CompressedImage::DESCRIPTION,
        ))
        .wait()
        .unwrap();
    let infos = peer
        .declare_subscriber(key("/wrist_cam/camera_info", CameraInfo::DESCRIPTION))
        .wait()
        .unwrap();
    // The publishers' tokens: once the peer sees them, the node's puts reach its subscribers.
    wait_until("the camera's publishers in the graph", || {
        graph(&peer, 1)
            .iter()
            .filter(|t| t.contains("wrist_cam"))
            .count()
            >= 2
    });
    // Simulated time: frames are released as the ticks reach their readout.
    let mut received = Vec::new();
    let mut info = None;
    wait_until("three frames and a camera info", || {
        node.creator().advance(Duration::from_millis(5)).unwrap();
        while let Ok(Some(sample)) = images.try_recv() {
            received.push(CompressedImage::decode_cdr(&sample.payload().to_bytes()).unwrap());
        }
        if let Ok(Some(sample)) = infos.try_recv() {
            info = Some(CameraInfo::decode_cdr(&sample.payload().to_bytes()).unwrap());
        }
        received.len() >= 3 && info.is_some()
    });
    for image in &received {
        assert_eq!(image.format, "jpeg");
        assert_eq!(&image.data[..2], &[0xff, 0xd8], "a JPEG");
        assert!(!image.header.frame_id.is_empty());
        // ROS time: the Unix epoch, as the robots' topics are stamped.
        assert!(
            image.header.stamp.sec > 1_600_000_000,
            "{:?}",
            image.header.stamp
        );
    }
    // 50 fps: consecutive frames 20 ms apart on the capture clock.
    let apart = received[1].header.stamp.as_ns() - received[0].header.stamp.as_ns();
    assert_eq!(apart, 20_000_000, "capture instants 20 ms apart");
    let info = info.unwrap();
    assert_eq!((info.width, info.height), (160, 120));
    assert_eq!(info.k[8], 1.0);
    // The principal point at the image's centre.
    let centre = (info.k[2] - 80.0).abs() <= 0.5 && (info.k[5] - 60.0).abs() <= 0.5;
    assert!(info.k[0] > 0.0 && centre, "{:?}", info.k);
    assert_eq!(info.header.frame_id, received[0].header.frame_id);
    println!("ros2 presence with a camera: {:?}", stats(&node).ros2);
    node.shutdown();
}
