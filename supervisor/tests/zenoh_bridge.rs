//! The Zenoh bridge end to end, on loopback only with scouting off (nothing leaves the
//! machine): a test's own Zenoh peer listens on `tcp/127.0.0.1:<free port>`, a node on a
//! simulated clock connects to it. The test's peer receives every tick of a controller; its
//! publisher drives a slave through a `trajectory/teleop` channel fed from Zenoh within the
//! demo's tracking bound; malformed poses are refused and counted and never reach the loop; the
//! queryable answers the object tree.
//!
//! Every wait is for something to happen (a count to grow, a reply to come), bounded; none is
//! for a time to pass.
#![cfg(feature = "zenoh")]

mod common;

use std::sync::mpsc;
use std::time::{Duration, Instant};

use common::zenoh_peer::{bridged_node, stats, test_peer};
use penelope_protocol::proto::{Call, ControllerMethod, Method, Reply, TelemetryRecord};
use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::system::SystemFile;
use penelope_supervisor::zenoh_bridge::ZenohSettings;
use penelope_supervisor::zenoh_bridge::encoding::OperatorPose;
use penelope_testkit::net::{free_tcp_port, free_udp_port};
use penelope_testkit::wait::wait_until;
use zenoh::Wait;

/// The slave's half of a task whose master is an operator station on Zenoh: a PUMA 200 on a
/// simulated board following the poses on `station/hand/pose`.
const SLAVE_SYSTEM: &str = include_str!("data/zenoh_station_slave.toml");

/// Node `slave` on a simulated clock with a bridge to the test's peer, the system applied.
fn slave_node(port: u16) -> Node {
    bridged_node("slave", port, SLAVE_SYSTEM, None)
}

fn status_last(node: &Node, controller: &str) -> TelemetryRecord {
    match node.call(Call::Object {
        object: controller.into(),
        method: Method::Controller(ControllerMethod::Status),
    }) {
        Ok(Reply::Status(s)) => {
            let last = s.last.expect("ticked");
            assert!(last.fault.is_none(), "{controller}: {:?}", last.fault);
            *last
        }
        other => panic!("{other:?}"),
    }
}

/// The operator's hand: a 3 cm by 2 cm by 1 cm figure at half a hertz around `start`.
fn hand(start: [f64; 3], t: f64) -> [f64; 3] {
    let w = std::f64::consts::TAU * 0.5;
    [
        start[0] + 0.03 * (w * t).sin(),
        start[1] + 0.02 * (1.0 - (w * t).cos()),
        start[2] + 0.01 * (2.0 * w * t).sin(),
    ]
}

fn pose(position: [f64; 3]) -> Vec<u8> {
    OperatorPose {
        clutch: false,
        position,
        orientation: [1.0, 0.0, 0.0, 0.0],
    }
    .encode()
    .to_vec()
}

#[test]
fn a_zenoh_subscriber_receives_every_tick_and_the_events_of_a_controller() {
    let port = free_tcp_port();
    let peer = test_peer(port);
    let (tx, ticks) = mpsc::channel::<serde_json::Value>();
    let _telemetry = peer
        .declare_subscriber("penelope/slave/follow/telemetry")
        .callback(move |s| {
            let v = serde_json::from_slice(&s.payload().to_bytes()).expect("JSON ticks");
            let _ = tx.send(v);
        })
        .wait()
        .unwrap();
    let (etx, events) = mpsc::channel::<serde_json::Value>();
    let _events = peer
        .declare_subscriber("penelope/slave/*/events")
        .callback(move |s| {
            let _ = etx.send(serde_json::from_slice(&s.payload().to_bytes()).unwrap());
        })
        .wait()
        .unwrap();
    let node = slave_node(port);
    wait_until("the bridge publishes the controller", || {
        stats(&node).controllers > 0
    });
    // No operator: the slave holds, then its reference goes stale (an event).
    let step = Duration::from_millis(1);
    let mut seqs = Vec::new();
    for _ in 0..10 {
        for _ in 0..100 {
            node.creator().advance(step).unwrap();
        }
        let ticks_so_far = match node.call(Call::Object {
            object: "follow".into(),
            method: Method::Controller(ControllerMethod::Status),
        }) {
            Ok(Reply::Status(s)) => s.ticks,
            other => panic!("{other:?}"),
        };
        // Ready when every tick the loop made so far has come.
        while (seqs.len() as u64) < ticks_so_far {
            let v = ticks
                .recv_timeout(Duration::from_secs(20))
                .expect("a tick within the bound");
            seqs.push(v["sample"]["seq"].as_u64().expect("a sequence number"));
        }
    }
    assert!(seqs.len() >= 1000, "{} ticks", seqs.len());
    assert!(
        seqs.windows(2).all(|w| w[1] == w[0] + 1),
        "every tick, in order: {:?}",
        &seqs[..10]
    );
    let s = stats(&node);
    assert_eq!(s.ticks_dropped, 0);
    assert!(s.ticks >= seqs.len() as u64);
    // The first tick (a state seen for the first time) is an event; so is going stale.
    let first = events
        .recv_timeout(Duration::from_secs(20))
        .expect("an event");
    assert_eq!(first["controller"], "follow");
    println!(
        "zenoh telemetry: {} ticks in order, first event {first}, bridge {s:?}",
        seqs.len()
    );
    node.shutdown();
}

#[test]
fn a_zenoh_publisher_drives_the_slave_within_the_demos_tracking_bound() {
    let port = free_tcp_port();
    let peer = test_peer(port);
    let node = slave_node(port);
    let publisher = peer.declare_publisher("station/hand/pose").wait().unwrap();
    // The operator station's hand rests at its own start (its frame, not the slave's).
    let start = [0.4, 0.1, 0.3];
    // Ready when the bridge took a pose: the subscription reached the test's peer.
    wait_until("the bridge takes a first pose", || {
        publisher.put(pose(start)).wait().unwrap();
        stats(&node).poses_taken > 0
    });
    let step = Duration::from_millis(1);
    for _ in 0..20 {
        node.creator().advance(step).unwrap();
    }
    let anchor = status_last(&node, "follow").tool_position;
    let comm = Duration::from_millis(2);
    let (mut squared, mut samples, mut worst) = (0.0f64, 0usize, 0.0f64);
    for k in 1..=2000u32 {
        let t = f64::from(k) * comm.as_secs_f64();
        let taken = stats(&node).poses_taken;
        publisher.put(pose(hand(start, t))).wait().unwrap();
        wait_until("the bridge takes the pose", || {
            stats(&node).poses_taken > taken
        });
        node.creator().advance(step).unwrap();
        node.creator().advance(step).unwrap();
        if k % 10 == 0 {
            // Mapped: scale 1, no rotation, so the slave moves as the hand did, a tick later.
            let target = hand(start, t);
            let expected: Vec<f64> = (0..3).map(|i| anchor[i] + target[i] - start[i]).collect();
            let at = status_last(&node, "follow").tool_position;
            let e = (0..3)
                .map(|i| (at[i] - expected[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            squared += e * e;
            worst = worst.max(e);
            samples += 1;
        }
    }
    let rms_mm = (squared / samples as f64).sqrt() * 1e3;
    println!(
        "zenoh-driven slave over 4 s: tracking {rms_mm:.3} mm RMS, worst {:.3} mm ({samples} \
         samples), bridge {:?}",
        worst * 1e3,
        stats(&node)
    );
    // The demo's bound (2 mm RMS) for the slave's tracking of the mapped master.
    assert!(rms_mm < 2.0, "{rms_mm} mm RMS");
    node.shutdown();
}

#[test]
fn malformed_poses_are_refused_counted_and_never_reach_the_loop() {
    let port = free_tcp_port();
    let peer = test_peer(port);
    let node = slave_node(port);
    let publisher = peer.declare_publisher("station/hand/pose").wait().unwrap();
    let start = [0.4, 0.1, 0.3];
    wait_until("the bridge takes a first pose", || {
        publisher.put(pose(start)).wait().unwrap();
        stats(&node).poses_taken > 0
    });
    let step = Duration::from_millis(1);
    for _ in 0..10 {
        node.creator().advance(step).unwrap();
    }
    let held = status_last(&node, "follow").tool_position;
    let taken = stats(&node).poses_taken;
    let far = {
        let mut b = pose([0.5, 0.1, 0.3]);
        b[2..10].copy_from_slice(&f64::NAN.to_le_bytes());
        b
    };
    let mut skewed = pose([0.45, 0.1, 0.3]);
    skewed[26..34].copy_from_slice(&2.0f64.to_le_bytes());
    let mut bad_tag = pose([0.45, 0.1, 0.3]);
    bad_tag[0] = 0x7f;
    let malformed: [Vec<u8>; 5] = [
        Vec::new(),
        b"{\"position\": [0.5, 0, 0]}".to_vec(),
        far,
        skewed,
        bad_tag,
    ];
    for payload in &malformed {
        publisher.put(payload.clone()).wait().unwrap();
    }
    wait_until("every malformed payload is refused", || {
        stats(&node).poses_refused >= malformed.len() as u64
    });
    // Resent (newest wins in the loop's cell) while the loop runs on: the slave holds.
    for _ in 0..20 {
        // Counted before the put: the bridge may take it before the put returns.
        let taken_now = stats(&node).poses_taken;
        publisher.put(pose(start)).wait().unwrap();
        wait_until("the bridge takes the resent pose", || {
            stats(&node).poses_taken > taken_now
        });
        node.creator().advance(step).unwrap();
        node.creator().advance(step).unwrap();
    }
    let s = stats(&node);
    assert_eq!(s.poses_refused, malformed.len() as u64);
    // (The readiness probes still in flight when `taken` was read may land after it.)
    assert!(s.poses_taken >= taken + 20, "{s:?}");
    let at = status_last(&node, "follow").tool_position;
    let moved = (0..3)
        .map(|i| (at[i] - held[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(moved < 1e-3, "the slave moved {moved} m");
    // The channel says so.
    let info = node.creator().info("link").expect("the channel");
    let zenoh = info
        .relations
        .iter()
        .find(|(k, _)| k == "zenoh")
        .map(|(_, v)| v.clone())
        .expect("a bridged channel shows its counters");
    assert!(zenoh.contains("5 refused"), "{zenoh}");
    println!("{zenoh}");
    node.shutdown();
}

#[test]
fn the_queryable_answers_the_object_tree() {
    let port = free_tcp_port();
    let peer = test_peer(port);
    let node = slave_node(port);
    // Ready when a reply comes: the queryable's declaration reached the test's peer.
    let mut tree = None;
    wait_until("the object tree is answered", || {
        let replies = peer.get("penelope/slave/objects").wait().unwrap();
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                tree = Some(serde_json::from_slice::<serde_json::Value>(
                    &sample.payload().to_bytes(),
                ));
            }
        }
        tree.is_some()
    });
    let tree = tree.unwrap().expect("JSON");
    let names: Vec<&str> = tree
        .as_array()
        .expect("a list of objects")
        .iter()
        .filter_map(|o| o["name"].as_str())
        .collect();
    for name in ["puma-io", "puma", "link", "follow"] {
        assert!(names.contains(&name), "{name} in {names:?}");
    }
    // One object by name.
    let replies = peer.get("penelope/slave/objects/follow").wait().unwrap();
    let reply = replies.recv().expect("a reply");
    let one: serde_json::Value =
        serde_json::from_slice(&reply.result().expect("ok").payload().to_bytes()).unwrap();
    assert_eq!(one["name"], "follow");
    assert!(stats(&node).queries >= 2);
    node.shutdown();
}

#[test]
fn a_channels_link_statistics_reach_a_zenoh_subscriber() {
    let port = free_tcp_port();
    let peer = test_peer(port);
    let (tx, links) = mpsc::channel::<serde_json::Value>();
    let _links = peer
        .declare_subscriber("penelope/slave/link/link")
        .callback(move |s| {
            let _ = tx.send(serde_json::from_slice(&s.payload().to_bytes()).unwrap());
        })
        .wait()
        .unwrap();
    // The demo on two nodes, its channel on the data plane; the slave's node runs the bridge.
    let system = include_str!("../../config/demo-two-nodes.toml")
        .replace("127.0.0.1:7410", &format!("127.0.0.1:{}", free_udp_port()))
        .replace("127.0.0.1:7420", &format!("127.0.0.1:{}", free_udp_port()));
    let file = SystemFile::parse(&system).unwrap();
    let start = |name: &str, zenoh: bool| {
        let mut config = NodeConfig::new(name, NamingChoice::None);
        config.creator.rt.priority = None;
        config.creator.clock = ClockMode::Simulated;
        config.zenoh = zenoh.then(|| ZenohSettings {
            connect: Some(format!("tcp/127.0.0.1:{port}")),
            config: None,
            operators: Vec::new(),
        });
        let node = Node::start(config).unwrap();
        file.apply(&node).unwrap();
        node
    };
    let (master, slave) = (start("master", false), start("slave", true));
    // Until a record with samples taken comes: the link carried the master's samples.
    let give_up = Instant::now() + Duration::from_secs(20);
    let record = loop {
        for _ in 0..50 {
            master.creator().advance(Duration::from_millis(1)).unwrap();
            slave.creator().advance(Duration::from_millis(1)).unwrap();
        }
        if let Ok(r) = links.try_recv()
            && r["samples_taken"].as_u64().unwrap_or(0) > 0
        {
            break r;
        }
        assert!(Instant::now() < give_up, "no link record with samples");
    };
    assert_eq!(record["down"], false);
    assert!(stats(&slave).link_records > 0);
    println!("zenoh link record: {record}");
    master.shutdown();
    slave.shutdown();
}
