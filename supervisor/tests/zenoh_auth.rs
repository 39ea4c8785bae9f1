//! Issue 31, Zenoh authenticated: a node's bridge that listens with Zenoh's user-password
//! authentication and `operators` lets only the operator station move its slave. An anonymous
//! participant is refused at the transport; an authenticated participant that is no operator
//! connects, subscribes and queries, and its poses are dropped by Zenoh's access control; the
//! station's poses move the slave. Off-loopback Zenoh without authentication is refused.
//! Loopback only, scouting off; every wait is for something to happen, bounded.
#![cfg(feature = "zenoh")]

use std::time::{Duration, Instant};

use penelope_protocol::proto::{Call, ControllerMethod, Method, Reply};
use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig, NodeError};
use penelope_supervisor::system::SystemFile;
use penelope_supervisor::zenoh_bridge::encoding::OperatorPose;
use penelope_supervisor::zenoh_bridge::{BridgeStats, ZenohSettings};
use penelope_testkit::net::free_tcp_port;
use penelope_testkit::scratch::scratch_dir;
use penelope_testkit::wait::wait_until;
use zenoh::Wait;

/// The slave's half of a task whose master is an operator station on Zenoh.
const SLAVE_SYSTEM: &str = include_str!("data/zenoh_station_slave.toml");

/// A participant connecting to `port` on loopback, scouting off, as `user` (or anonymous).
fn participant(port: u16, user: Option<(&str, &str)>) -> zenoh::Result<zenoh::Session> {
    let mut c = zenoh::Config::default();
    c.insert_json5("mode", r#""peer""#).unwrap();
    c.insert_json5("listen/endpoints", "[]").unwrap();
    c.insert_json5("connect/endpoints", &format!(r#"["tcp/127.0.0.1:{port}"]"#))
        .unwrap();
    c.insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    if let Some((user, password)) = user {
        c.insert_json5("transport/auth/usrpwd/user", &format!("{user:?}"))
            .unwrap();
        c.insert_json5("transport/auth/usrpwd/password", &format!("{password:?}"))
            .unwrap();
    }
    zenoh::open(c).wait()
}

fn stats(node: &Node) -> BridgeStats {
    node.zenoh_stats().expect("the node runs a bridge")
}

fn tool(node: &Node) -> [f64; 3] {
    match node.call(Call::Object {
        object: "follow".into(),
        method: Method::Controller(ControllerMethod::Status),
    }) {
        Ok(Reply::Status(s)) => {
            let last = s.last.expect("ticked");
            assert!(last.fault.is_none(), "{:?}", last.fault);
            let p = last.tool_position;
            [p[0], p[1], p[2]]
        }
        other => panic!("{other:?}"),
    }
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

fn advance(node: &Node, ticks: u32) {
    for _ in 0..ticks {
        node.creator().advance(Duration::from_millis(1)).unwrap();
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

/// Node `slave` whose bridge listens on `port` (loopback) with user-password authentication:
/// it accepts `station` and `viewer`, and only `station` is an operator.
fn authenticated_slave(port: u16, dir: &std::path::Path) -> Node {
    let dictionary = dir.join("users.txt");
    std::fs::write(&dictionary, "station:station-pw\nviewer:viewer-pw\n").unwrap();
    let file = dir.join("zenoh.json5");
    std::fs::write(
        &file,
        format!(
            r#"{{
  mode: "peer",
  listen: {{ endpoints: ["tcp/127.0.0.1:{port}"] }},
  scouting: {{ multicast: {{ enabled: false }} }},
  transport: {{ auth: {{ usrpwd: {{ user: "slave", password: "slave-pw",
                                     dictionary_file: {:?} }} }} }},
}}"#,
            dictionary.display().to_string()
        ),
    )
    .unwrap();
    let mut config = NodeConfig::new("slave", NamingChoice::None);
    config.creator.rt.priority = None;
    config.creator.clock = ClockMode::Simulated;
    config.zenoh = Some(ZenohSettings {
        connect: None,
        config: Some(file),
        operators: vec!["station".into()],
    });
    let node = Node::start(config).expect("the node and its bridge start");
    SystemFile::parse(SLAVE_SYSTEM)
        .unwrap()
        .apply(&node)
        .expect("the slave's system");
    node
}

#[test]
fn only_the_authenticated_operator_station_moves_the_slave_over_zenoh() {
    let dir = scratch_dir("zauth", "operators");
    let port = free_tcp_port();
    let node = authenticated_slave(port, &dir);
    let start = [0.4, 0.1, 0.3];

    // The operator station, authenticated: its poses are taken.
    let station = participant(port, Some(("station", "station-pw"))).unwrap();
    let hand = station
        .declare_publisher("station/hand/pose")
        .wait()
        .unwrap();
    wait_until("the bridge takes the station's first pose", || {
        hand.put(pose(start)).wait().unwrap();
        stats(&node).poses_taken > 0
    });
    // The loop above may have put a pose more than the one taken first: a query over the
    // station's link, answered, means the node has seen every pose it put.
    let replies = station.get("penelope/slave/objects").wait().unwrap();
    replies
        .recv_timeout(Duration::from_secs(20))
        .expect("the node answers the station's query")
        .expect("a reply");
    advance(&node, 20);
    let rest = tool(&node);
    let taken = stats(&node).poses_taken;

    let (viewer, intruder) = a_viewers_poses_are_dropped(port, &node, start, taken);

    let anonymous = an_anonymous_participant_gets_no_transport(port, &node, &hand, start);
    let after = stats(&node);
    println!(
        "anonymous session: {}; poses taken {} -> {} (the station's only), refused {}",
        match &anonymous {
            Ok(_) => "opened, never connected".to_string(),
            Err(e) => format!("refused: {e}"),
        },
        taken,
        after.poses_taken,
        after.poses_refused
    );
    assert_eq!(
        after.poses_refused, 0,
        "nothing malformed reached the bridge"
    );
    advance(&node, 20);
    let held = tool(&node);
    assert!(
        distance(held, rest) < 1e-3,
        "the slave moved {} m on poses of no operator",
        distance(held, rest)
    );
    // The bridge took the station's poses and nothing else: every pose the viewer sent is 2
    // cm away, and the slave stayed.
    drop(intruder);

    the_station_moves_the_slave_one_cm(&node, &hand, start, rest);
    drop(hand);
    let _ = station.close().wait();
    let _ = viewer.close().wait();
    node.shutdown();
    let _ = std::fs::remove_dir_all(dir);
}

/// An authenticated participant that is no operator: it connects and may query the node, but
/// its poses (2 cm away from the station's) are dropped by the access control. Returns the
/// participant and its publisher, still declared.
fn a_viewers_poses_are_dropped(
    port: u16,
    node: &Node,
    start: [f64; 3],
    taken: u64,
) -> (zenoh::Session, zenoh::pubsub::Publisher<'static>) {
    let viewer = participant(port, Some(("viewer", "viewer-pw"))).unwrap();
    wait_until("the viewer is connected to the node", || {
        viewer.info().peers_zid().wait().next().is_some()
    });
    let intruder = viewer
        .declare_publisher("station/hand/pose")
        .wait()
        .unwrap();
    for i in 0..50 {
        let x = start[0] + 0.02 + f64::from(i) * 1e-4;
        intruder.put(pose([x, start[1], start[2]])).wait().unwrap();
    }
    // A query over the same link, after the puts: answered, so the node has seen them.
    let replies = viewer.get("penelope/slave/objects").wait().unwrap();
    let reply = replies
        .recv_timeout(Duration::from_secs(20))
        .expect("the node answers the viewer's query")
        .expect("a reply");
    assert!(reply.result().is_ok(), "the viewer may query");
    assert_eq!(stats(node).poses_taken, taken, "a viewer's pose was taken");
    (viewer, intruder)
}

/// An anonymous participant: the node's transport refuses it (no credentials). Returns its
/// session (opened, never connected) or why it could not open one.
fn an_anonymous_participant_gets_no_transport(
    port: u16,
    node: &Node,
    hand: &zenoh::pubsub::Publisher<'_>,
    start: [f64; 3],
) -> zenoh::Result<zenoh::Session> {
    let anonymous = participant(port, None);
    if let Ok(anonymous) = &anonymous {
        let stranger = anonymous
            .declare_publisher("station/hand/pose")
            .wait()
            .unwrap();
        for _ in 0..50 {
            stranger
                .put(pose([start[0] - 0.02, start[1], start[2]]))
                .wait()
                .unwrap();
        }
        // Its attempt to connect is over once the station's own next pose is taken; it has
        // no transport to the node.
        let before = stats(node).poses_taken;
        wait_until("the station's pose after the stranger's", || {
            hand.put(pose(start)).wait().unwrap();
            stats(node).poses_taken > before
        });
        assert_eq!(
            anonymous.info().peers_zid().wait().count(),
            0,
            "an anonymous participant is connected"
        );
    }
    anonymous
}

/// The station moves the slave 1 cm, at 25 mm/s (a jump would trip the velocity limit).
fn the_station_moves_the_slave_one_cm(
    node: &Node,
    hand: &zenoh::pubsub::Publisher<'_>,
    start: [f64; 3],
    rest: [f64; 3],
) {
    for k in 1..=200u32 {
        let taken = stats(node).poses_taken;
        let to = [start[0] + 0.01 * f64::from(k) / 200.0, start[1], start[2]];
        hand.put(pose(to)).wait().unwrap();
        wait_until("the station's pose is taken", || {
            stats(node).poses_taken > taken
        });
        advance(node, 2);
    }
    advance(node, 40);
    let moved = tool(node);
    println!("the station moved the slave {:.4} m", distance(moved, rest));
    assert!(
        (distance(moved, rest) - 0.01).abs() < 2e-3,
        "the slave moved {} m, not 1 cm",
        distance(moved, rest)
    );
}

#[test]
fn off_loopback_zenoh_without_authentication_is_refused_before_anything_is_sent() {
    let dir = scratch_dir("zauth", "wide");
    for (connect, config) in [
        // A documentation address (RFC 5737): nothing is sent there, the start is refused.
        (Some("tcp/192.0.2.1:7447"), None),
        (
            None,
            Some(r#"{ listen: { endpoints: ["tcp/0.0.0.0:0"] } }"#),
        ),
        (
            None,
            Some(r#"{ scouting: { multicast: { enabled: true } } }"#),
        ),
        // Listening off loopback with a password but no dictionary of the users it accepts.
        (
            None,
            Some(
                r#"{ listen: { endpoints: ["tcp/0.0.0.0:0"] },
                     transport: { auth: { usrpwd: { user: "a", password: "b" } } } }"#,
            ),
        ),
    ] {
        let file = config.map(|text| {
            let f = dir.join("zenoh.json5");
            std::fs::write(&f, text).unwrap();
            f
        });
        let mut c = NodeConfig::new("wide", NamingChoice::None);
        c.creator.rt.priority = None;
        c.zenoh = Some(ZenohSettings {
            connect: connect.map(str::to_string),
            config: file,
            operators: Vec::new(),
        });
        let t = Instant::now();
        match Node::start(c) {
            Err(NodeError::Zenoh(e)) => {
                let message = e.to_string();
                println!(
                    "{connect:?} {config:?}: refused in {:?}: {message}",
                    t.elapsed()
                );
                assert!(message.contains("off loopback"), "{message}");
                assert!(message.contains("transport.auth.usrpwd"), "{message}");
            }
            Err(other) => panic!("{connect:?} {config:?}: {other}"),
            Ok(node) => {
                node.shutdown();
                panic!("{connect:?} {config:?}: started without authentication");
            }
        }
    }
    // Operators without authentication: refused too.
    let mut c = NodeConfig::new("ops", NamingChoice::None);
    c.creator.rt.priority = None;
    c.zenoh = Some(ZenohSettings {
        connect: Some("tcp/127.0.0.1:9".into()),
        config: None,
        operators: vec!["station".into()],
    });
    match Node::start(c) {
        Err(NodeError::Zenoh(e)) => assert!(e.to_string().contains("usrpwd"), "{e}"),
        Err(other) => panic!("{other}"),
        Ok(node) => {
            node.shutdown();
            panic!("operators without authentication started");
        }
    }
    let _ = std::fs::remove_dir_all(dir);
}
