//! Sensors published on the data plane (issue 13): a naming service and in-process nodes on the
//! real clock, behind a shared secret, over loopback only.
//!
//! - one sensor read from two other nodes in parallel: both readers get the same samples, and
//!   the sensor's node serves no TCP request while they read;
//! - a controller on one node whose sensor is on another (placed by a system file) gets the
//!   sensor's wrench in its loop, matching the sensor's model at the tool's pose;
//! - a forged datagram to the publisher is refused and counted, and it keeps serving;
//! - a sensor on another node without `publish` is refused, in the file and at activation.
//!
//! Every wait is for a condition, bounded by a deadline, never for a fixed time.

use std::collections::BTreeMap;
use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::time::{Duration, Instant};

use nalgebra::Vector3;
use penelope_hal::{Pose, Transition};
use penelope_protocol::net::server::{Server, ServerConfig};
use penelope_protocol::proto::{
    Call, CallError, ControllerMethod, CreatorCall, JointAxis, Method, Reply, RobotMethod,
    SensorMethod, WireError,
};
use penelope_runtime::dataplane::endpoint::Endpoint;
use penelope_runtime::dataplane::frame::{DATAPLANE_VERSION, DatagramKey, Header, StreamId};
use penelope_runtime::dataplane::sensor_stream::{
    Probe, SensorSubscriber, WrenchSample, sensor_reader_keys,
};
use penelope_supervisor::naming::{NamingLimits, NamingService};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::system::{SystemFile, SystemFileError};
use penelope_testkit::wait::wait_until;

const SECRET: &[u8] = b"sensor streams test secret";
/// The wall's stiffness, N/m (no damping: the wrench depends on the pose only).
const STIFFNESS: f64 = 5000.0;

/// A naming service of its own on loopback, and nodes registered in it.
struct Lab {
    naming: Server,
    nodes: Vec<Node>,
}

impl Lab {
    fn start(names: &[&str]) -> Lab {
        let service = Arc::new(NamingService::new("naming", NamingLimits::default()));
        let mut config = ServerConfig::new("naming");
        config.secret = Some(SECRET.into());
        let naming = Server::bind("127.0.0.1:0".parse().unwrap(), config, service).unwrap();
        let nodes = names
            .iter()
            .map(|name| {
                let mut config = NodeConfig::new(*name, NamingChoice::Remote(naming.local_addr()));
                config.secret = Some(SECRET.into());
                config.creator.rt.priority = None;
                Node::start(config).unwrap()
            })
            .collect();
        Lab { naming, nodes }
    }

    fn node(&self, name: &str) -> &Node {
        self.nodes.iter().find(|n| n.name() == name).unwrap()
    }

    fn stop(self) {
        for n in self.nodes {
            n.shutdown();
        }
        self.naming.shutdown();
    }
}

fn object(node: &Node, name: &str, method: Method) -> Result<Reply, WireError> {
    node.call(Call::Object {
        object: name.into(),
        method,
    })
}

/// A wall (free space above) at height `z`, published on any free loopback port.
fn wall_sensor(z: f64) -> String {
    format!(
        "publish = \"127.0.0.1:0\"\n[[shapes]]\nkind = \"plane\"\npoint = [0.0, 0.0, {z}]\n\
         normal = [0.0, 0.0, 1.0]\nstiffness = {STIFFNESS}\ndamping = 0.0\n"
    )
}

/// Where the sensor at `path` is published, asked as node `reader` asks it at activation.
fn published_at(reader: &Node, path: &str) -> SocketAddr {
    match reader
        .remote()
        .call(path, Method::Sensor(SensorMethod::Stream))
    {
        Ok(Reply::Address(a)) => a.parse().unwrap(),
        other => panic!("{other:?}"),
    }
}

/// The publisher's counters, from `describe` of the sensor: subscribers, samples published,
/// probes taken, datagrams refused, bad tags.
fn publisher_counts(node: &Node, sensor: &str) -> [u64; 5] {
    let info = node.creator().info(sensor).unwrap();
    let line = info
        .relations
        .iter()
        .find(|(k, _)| k == "publisher")
        .map(|(_, v)| v.clone())
        .expect("a publishing sensor shows its publisher");
    let numbers: Vec<u64> = line
        .split(|c: char| !c.is_ascii_digit())
        .filter(|w| !w.is_empty())
        .map(|w| w.parse().unwrap())
        .collect();
    [numbers[0], numbers[1], numbers[2], numbers[3], numbers[4]]
}

/// Reads the sensor at `address` for `count` new samples (at most 20 s), probing at `probe`
/// each poll when given, as a controller's feed does.
fn read_samples(address: SocketAddr, probe: Option<Probe>, count: usize) -> Vec<WrenchSample> {
    // The keys of this sensor's directions, as a reader's node derives them from its path.
    let keys = sensor_reader_keys(&DatagramKey::from_secret(SECRET), "/wrist/sensors/ft");
    let mut reader = SensorSubscriber::connect_directed(address, Some(keys)).unwrap();
    let t0 = Instant::now();
    let mut samples = Vec::new();
    while samples.len() < count && t0.elapsed() < Duration::from_secs(20) {
        let now = i64::try_from(t0.elapsed().as_nanos()).unwrap();
        if let Some(s) = reader.poll(now, probe.as_ref()) {
            samples.push(s);
        }
        std::thread::sleep(Duration::from_micros(300));
    }
    samples
}

/// Creates and configures sensor `ft` (a wall 0.5 m up, published) on `wrist`, and waits until
/// `reader` can resolve it.
fn publish_wall_sensor(wrist: &Node, reader: &Node) {
    wrist
        .call(Call::Creator(CreatorCall::Create {
            kind: "sensor/virtual".into(),
            name: "ft".into(),
            config: wall_sensor(0.5),
        }))
        .unwrap();
    object(wrist, "ft", Method::Transition(Transition::Configure)).unwrap();
    wait_until("the sensor's naming entry", || {
        reader
            .remote()
            .call("/wrist/sensors/ft", Method::Describe)
            .is_ok()
    });
}

#[test]
fn one_sensor_read_from_two_nodes_in_parallel_gives_both_the_same_samples() {
    let lab = Lab::start(&["wrist", "a", "b"]);
    let (wrist, a, b) = (lab.node("wrist"), lab.node("a"), lab.node("b"));
    publish_wall_sensor(wrist, a);
    // Each reader's node asks where the sensor is published (one request each), then reads
    // the data plane only.
    let (at_a, at_b) = (
        published_at(a, "/wrist/sensors/ft"),
        published_at(b, "/wrist/sensors/ft"),
    );
    assert_eq!(at_a, at_b);
    let requests_before = wrist.stats().requests;
    let published_before = publisher_counts(wrist, "ft")[1];

    // Reader a probes 1 cm into the wall (as the controller of the robot carrying the sensor
    // would); reader b, a monitor, only receives.
    let probe = Probe {
        pose: Pose::translation(0.1, 0.0, 0.49),
        velocity: Vector3::zeros(),
    };
    let count = 1500;
    let reader_a = std::thread::spawn(move || read_samples(at_a, Some(probe), count));
    let reader_b = std::thread::spawn(move || read_samples(at_b, None, count));
    let (seen_a, seen_b) = (reader_a.join().unwrap(), reader_b.join().unwrap());
    assert!(seen_a.len() == count && seen_b.len() == count);

    // The same stream: one session, increasing sequence numbers, and for every sequence both
    // saw, the same wrench, bit for bit.
    let by_sequence = |seen: &[WrenchSample]| -> BTreeMap<u64, WrenchSample> {
        assert!(seen.windows(2).all(|w| w[0].sequence < w[1].sequence));
        seen.iter().map(|s| (s.sequence, *s)).collect()
    };
    let (map_a, map_b) = (by_sequence(&seen_a), by_sequence(&seen_b));
    let common: Vec<u64> = map_a
        .keys()
        .filter(|k| map_b.contains_key(k))
        .copied()
        .collect();
    assert!(common.len() > count / 2, "only {} in common", common.len());
    for seq in &common {
        let (x, y) = (map_a[seq], map_b[seq]);
        assert_eq!(x, y, "sequence {seq}");
    }
    // In contact, both saw the wall push back as its model says: 5000 N/m x 1 cm.
    let last_common = map_a[common.last().unwrap()];
    assert!(
        (last_common.wrench.force.z - STIFFNESS * 0.01).abs() < 1e-6,
        "{last_common:?}"
    );

    // No TCP request reached the sensor's node while thousands of samples went out.
    let requests_after = wrist.stats().requests;
    let [subscribers, published, probes, refused, _] = publisher_counts(wrist, "ft");
    println!(
        "two readers: {} and {} samples, {} sequence numbers in common (identical), {} samples \
         published, {probes} probes taken, {subscribers} subscribers, {refused} refused; \
         requests to the sensor's node: {requests_before} before, {requests_after} after",
        seen_a.len(),
        seen_b.len(),
        common.len(),
        published - published_before,
    );
    assert!(published - published_before >= count as u64);
    assert_eq!(requests_after, requests_before);
    assert_eq!(refused, 0);
    lab.stop();
}

#[test]
fn a_forged_datagram_to_the_publisher_is_refused_and_counted_and_it_keeps_serving() {
    let lab = Lab::start(&["wrist", "a"]);
    let (wrist, a) = (lab.node("wrist"), lab.node("a"));
    publish_wall_sensor(wrist, a);
    let address = published_at(a, "/wrist/sensors/ft");

    // A subscription tagged with another system's key, and raw bytes that are no datagram.
    let mut forger = Endpoint::bind(
        "127.0.0.1:0".parse().unwrap(),
        Some(DatagramKey::from_secret(b"another lab")),
    )
    .unwrap();
    let header = Header {
        version: DATAPLANE_VERSION,
        stream: StreamId(17),
        session: 1,
        sequence: 1,
        sent_ns: 0,
    };
    forger.send(&header, &(0u8, None::<u8>), address).unwrap();
    // A member of this system, but a reader of another sensor: its subscription does not
    // verify under this sensor's key.
    let mut other_sensor = Endpoint::bind_directed(
        "127.0.0.1:0".parse().unwrap(),
        Some(sensor_reader_keys(
            &DatagramKey::from_secret(SECRET),
            "/wrist/sensors/other",
        )),
    )
    .unwrap();
    other_sensor
        .send(&header, &(0u8, None::<u8>), address)
        .unwrap();
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .send_to(b"\x07 not a datagram", address)
        .unwrap();
    wait_until("the refusals counted", || {
        publisher_counts(wrist, "ft")[3] >= 3
    });
    let [subscribers, _, _, refused, bad_tags] = publisher_counts(wrist, "ft");
    assert_eq!((subscribers, refused, bad_tags), (0, 3, 2));

    // A member still reads it, and the forger got nothing.
    let samples = read_samples(address, None, 100);
    assert_eq!(samples.len(), 100);
    assert!(forger.receive::<u8>().is_none());
    assert!(other_sensor.receive::<u8>().is_none());
    println!("forged: {refused} refused ({bad_tags} bad tag); then 100 samples read");
    lab.stop();
}

/// The tool position of a PUMA 560 at its start pose (on a scratch node, no naming).
fn start_tool_position() -> [f64; 3] {
    let mut config = NodeConfig::new("scratch", NamingChoice::None);
    config.creator.rt.priority = None;
    let scratch = Node::start(config).unwrap();
    let create = |kind: &str, name: &str| {
        scratch
            .call(Call::Creator(CreatorCall::Create {
                kind: kind.into(),
                name: name.into(),
                config: String::new(),
            }))
            .unwrap();
    };
    create("board/sim", "io");
    create("robot/puma560", "puma");
    let joints = (0..6).map(|j| JointAxis { joint: j, axis: j }).collect();
    let map = RobotMethod::MapJoints {
        board: "io".into(),
        joints,
    };
    object(&scratch, "puma", Method::Robot(map)).unwrap();
    for o in ["io", "puma"] {
        object(&scratch, o, Method::Transition(Transition::Configure)).unwrap();
    }
    let fk = RobotMethod::ForwardKinematics { q: None };
    let Ok(Reply::Pose(p)) = object(&scratch, "puma", Method::Robot(fk)) else {
        panic!("forward kinematics")
    };
    scratch.shutdown();
    p.position
}

/// A PUMA on node `arm` holding its start pose, with its wrist sensor on node `wrist`: a wall
/// 1 cm above the tool, `sensor_keys` added to the sensor's.
fn arm_and_wrist(tool: [f64; 3], sensor_keys: &str) -> String {
    let [x, y, z] = tool;
    let wall = z + 0.01;
    format!(
        r#"
[sensors.ft]
kind = "virtual"
node = "wrist"
{sensor_keys}
[[sensors.ft.shapes]]
kind = "plane"
point = [{x}, {y}, {wall}]
normal = [0.0, 0.0, 1.0]
stiffness = {STIFFNESS}
damping = 0.0

[boards.io]
kind = "sim"
node = "arm"

[robots.puma]
kind = "puma560"
node = "arm"
joints = [{{ board = "io", axes = [0, 1, 2, 3, 4, 5] }}]

[trajectories.hold]
kind = "spline"
node = "arm"
[[trajectories.hold.waypoints]]
at_s = 1.0
pose = "start"

[controllers.pid]
kind = "joint-pid"
node = "arm"
robot = "puma"
trajectory = "hold"
sensor = "ft"
"#
    )
}

#[test]
fn a_controller_reads_its_sensor_on_another_node_over_the_data_plane() {
    let tool = start_tool_position();
    let wall = tool[2] + 0.01;

    // In the file, the controller names its sensor; on another node, that becomes its naming
    // path, and a sensor there without `publish` is refused, naming the key.
    let refused = SystemFile::parse(&arm_and_wrist(tool, ""));
    match refused {
        Err(SystemFileError::Invalid { key, message, .. }) => {
            assert_eq!(key, "controllers.pid.sensor");
            assert!(message.contains("publish"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    let file = SystemFile::parse(&arm_and_wrist(tool, "publish = \"127.0.0.1:0\"")).unwrap();
    let pid = file.objects.iter().find(|o| o.name == "pid").unwrap();
    assert_eq!(pid.sensor.as_deref(), Some("/wrist/sensors/ft"));

    let lab = Lab::start(&["wrist", "arm"]);
    let (wrist, arm) = (lab.node("wrist"), lab.node("arm"));
    file.apply(wrist).expect("the wrist's half");
    wait_until("the sensor's naming entry", || {
        arm.remote()
            .call("/wrist/sensors/ft", Method::Describe)
            .is_ok()
    });
    file.apply(arm)
        .expect("the arm's half, its controller active");
    let requests_at_start = wrist.stats().requests;

    // The loop's wrench is the wall's at the tool's pose: 5000 N/m times the depth.
    let status = || match object(arm, "pid", Method::Controller(ControllerMethod::Status)) {
        Ok(Reply::Status(s)) => s,
        other => panic!("{other:?}"),
    };
    wait_until("the wall's wrench in the loop", || {
        status().last.is_some_and(|l| l.wrench.force[2] > 1.0)
    });
    let published_before = publisher_counts(wrist, "ft")[1];
    wait_until("1000 more samples", || {
        publisher_counts(wrist, "ft")[1] > published_before + 1000
    });
    let last = status().last.unwrap();
    let expected = STIFFNESS * (wall - last.tool_position[2]);
    let got = last.wrench.force[2];
    println!(
        "controller on `arm`, sensor on `wrist`: Fz {got:.4} N in the loop, model at the tool's \
         pose {expected:.4} N; requests to the sensor's node {} while the loop ran; {:?}",
        wrist.stats().requests - requests_at_start,
        publisher_counts(wrist, "ft"),
    );
    // The tool holds still within a fraction of a millimetre: 0.5 N is 0.1 mm of the wall.
    assert!((got - expected).abs() < 0.5, "{got} vs {expected}");
    assert!((got - STIFFNESS * 0.01).abs() < 2.5, "about 50 N: {got}");
    assert!(last.wrench.force[0].abs() < 1e-9 && last.wrench.force[1].abs() < 1e-9);
    assert_eq!(wrist.stats().requests, requests_at_start);
    let [subscribers, _, probes, refused, _] = publisher_counts(wrist, "ft");
    assert_eq!((subscribers, refused), (1, 0));
    assert!(probes > 100, "the feed's probes: {probes}");

    // A sensor on another node without `publish` is refused at activation, typed.
    wrist
        .call(Call::Creator(CreatorCall::Create {
            kind: "sensor/virtual".into(),
            name: "bare".into(),
            config: String::new(),
        }))
        .unwrap();
    object(wrist, "bare", Method::Transition(Transition::Configure)).unwrap();
    wait_until("the bare sensor's naming entry", || {
        arm.remote()
            .call("/wrist/sensors/bare", Method::Describe)
            .is_ok()
    });
    object(arm, "pid", Method::Transition(Transition::Deactivate)).unwrap();
    let set = ControllerMethod::SetSensor {
        sensor: "/wrist/sensors/bare".into(),
    };
    object(arm, "pid", Method::Controller(set)).unwrap();
    match object(arm, "pid", Method::Transition(Transition::Activate)) {
        Err(WireError::Call(CallError::NotReady(why))) => {
            assert!(
                why.contains("/wrist/sensors/bare") && why.contains("`publish`"),
                "{why}"
            );
        }
        other => panic!("{other:?}"),
    }
    // Deactivated, the controller left the publisher's table (it said so on leaving).
    wait_until("the reader gone", || publisher_counts(wrist, "ft")[0] == 0);
    lab.stop();
}

#[test]
fn a_sensor_on_another_node_is_refused_to_a_loop_on_a_simulated_clock() {
    let tool = start_tool_position();
    let file = SystemFile::parse(&arm_and_wrist(tool, "publish = \"127.0.0.1:0\"")).unwrap();
    let lab = Lab::start(&["wrist"]);
    file.apply(lab.node("wrist")).expect("the wrist's half");
    // The arm's node on a simulated clock: the published sensor measures in real time, so a
    // stepped loop would read it stale tick after tick; its activation is refused instead.
    let mut config = NodeConfig::new("arm", NamingChoice::Remote(lab.naming.local_addr()));
    config.secret = Some(SECRET.into());
    config.creator.rt.priority = None;
    config.creator.clock = penelope_runtime::objects::clock::ClockMode::Simulated;
    let arm = Node::start(config).unwrap();
    wait_until("the sensor's naming entry", || {
        arm.remote()
            .call("/wrist/sensors/ft", Method::Describe)
            .is_ok()
    });
    match file.apply(&arm) {
        Err(SystemFileError::Step { step, error, .. }) => {
            assert!(step.contains("activ"), "{step}");
            assert!(
                matches!(&error, WireError::Call(CallError::NotReady(m)) if m.contains("simulated clock")),
                "{error:?}"
            );
        }
        other => panic!("{other:?}"),
    }
    arm.shutdown();
    lab.stop();
}
