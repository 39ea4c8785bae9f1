//! The end-to-end test of issue 7, over loopback: a naming service and two nodes in this process;
//! a client creates a PUMA 560 (on a simulated board) on node A and a virtual force sensor on
//! node B, a controller on A bound to the robot, a trajectory and the remote sensor, activates it,
//! calls methods remotely, watches telemetry (the remote wrench shows up in it), destroys
//! everything and finds the naming tree empty again (only the creators); then a node killed
//! mid-run expires from the tree after its lease.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use penelope_hal::{LifecycleState, NamedPose, Pose};
use penelope_protocol::client::{
    Client, ControllerProxy, Lifecycle, NodeProxy, RobotProxy, SensorProxy, TrajectoryProxy,
};
use penelope_protocol::net::conn::{ClientConfig, RpcError};
use penelope_protocol::net::server::{NetError, Server, ServerConfig};
use penelope_protocol::proto::{
    CallError, Method, NameEntry, PoseMsg, ProtocolError, Reply, SensorMethod, WireError,
};
use penelope_supervisor::naming::{NamingLimits, NamingService};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig, NodeError};

const LEASE: Duration = Duration::from_millis(400);

fn loopback() -> SocketAddr {
    "127.0.0.1:0".parse().unwrap()
}

fn start_node(name: &str, naming: SocketAddr) -> Node {
    let mut config = NodeConfig::new(name, NamingChoice::Remote(naming));
    config.lease = LEASE;
    Node::start(config).unwrap()
}

fn entries(client: &Client, context: &str) -> Vec<String> {
    client
        .naming()
        .list(context)
        .unwrap()
        .iter()
        .map(|e| match e {
            NameEntry::Context { name } => format!("{name}/"),
            NameEntry::Object { name, .. } => name.clone(),
        })
        .collect()
}

#[test]
fn two_nodes_a_client_and_the_naming_tree() {
    // The naming service alone, and two nodes registered in it.
    let naming = Arc::new(NamingService::new("naming", NamingLimits::default()));
    let naming_server =
        Server::bind(loopback(), ServerConfig::new("naming"), naming.clone()).unwrap();
    let naming_addr = naming_server.local_addr();
    let node_a = start_node("A", naming_addr);
    let node_b = start_node("B", naming_addr);

    let client = Client::connect(naming_addr, ClientConfig::admin("e2e")).unwrap();
    assert_eq!(entries(&client, "/"), ["A/", "B/"]);
    assert_eq!(entries(&client, "/A"), ["creator"]);
    let a = client.node("A").unwrap();
    let b = client.node("B").unwrap();
    assert!(a.kinds().unwrap().iter().any(|k| k.kind == "robot/puma560"));

    let robot = a_puma_on_a_simulated_board(&client, &a);

    // Remote methods on the robot: joint positions and forward kinematics.
    let q = robot.joint_positions().unwrap();
    let q_start = robot.named_pose(NamedPose::Start).unwrap();
    assert!(
        (q - q_start).norm() < 1e-3,
        "the simulated body starts at `start`"
    );
    let tool = robot.forward_kinematics(None).unwrap();
    let tool_at = robot.forward_kinematics(Some(&q_start)).unwrap();
    assert!((tool.translation.vector - tool_at.translation.vector).norm() < 1e-3);

    let sensor = a_wall_just_above_the_tool(&b, &tool);

    let pid = a_pid_reading_the_sensor_on_b(&a);
    assert_eq!(
        entries(&client, "/A"),
        [
            "boards/",
            "controllers/",
            "creator",
            "robots/",
            "trajectories/"
        ]
    );
    assert_eq!(entries(&client, "/B/sensors"), ["ft"]);

    telemetry_carries_the_wrench_b_publishes(&client, &pid, &sensor);

    everything_goes_but_what_an_active_object_uses_first(&client, &a, &b, &pid);

    // A node killed mid-run (with an object bound) expires after its lease.
    b.create("sensor/virtual", "ft2", "").unwrap();
    assert_eq!(entries(&client, "/B/sensors"), ["ft2"]);
    node_b.kill();
    // Node A keeps renewing all along.
    std::thread::sleep(LEASE * 2);
    assert_eq!(entries(&client, "/"), ["A/"]);
    assert!(matches!(
        client.resolve("/B/sensors/ft2"),
        Err(RpcError::Remote(WireError::Call(CallError::UnknownName(_))))
    ));
    naming.snapshot().check_invariants().unwrap();

    // A clean shutdown unregisters at once.
    node_a.shutdown();
    assert!(entries(&client, "/").is_empty());
    naming_server.shutdown();
}

/// Node A: a simulated board and a PUMA 560 mapped onto it, both configured.
fn a_puma_on_a_simulated_board(client: &Client, a: &NodeProxy) -> RobotProxy {
    a.create("board/sim", "sim0", "").unwrap();
    let robot: RobotProxy = a.create_as("robot/puma560", "slave", "").unwrap();
    robot
        .map_joints("sim0", &(0..6).map(|j| (j, j)).collect::<Vec<_>>())
        .unwrap();
    client
        .object("/A/boards/sim0")
        .unwrap()
        .configure()
        .unwrap();
    robot.configure().unwrap();
    assert_eq!(robot.path(), "/A/robots/slave");
    robot
}

/// Node B: a virtual force sensor whose floor (free space above) is 1 cm above the tool (so
/// the probe pushes into it: about 5000 N/m × 0.01 m = 50 N along +z), published on the data
/// plane (any free port on loopback): node A reads it there.
fn a_wall_just_above_the_tool(b: &NodeProxy, tool: &Pose) -> SensorProxy {
    let p = tool.translation.vector;
    let wall_z = p.z + 0.01;
    let sensor_config = format!(
        "publish = \"127.0.0.1:0\"\n[[shapes]]\nkind = \"plane\"\npoint = [{}, {}, {wall_z}]\n\
         normal = [0.0, 0.0, 1.0]\n",
        p.x, p.y
    );
    let sensor: SensorProxy = b.create_as("sensor/virtual", "ft", &sensor_config).unwrap();
    sensor.configure().unwrap();
    let velocity = nalgebra::Vector3::zeros();
    let w = sensor.measure(tool, &velocity).unwrap();
    assert!(
        w.force.norm() > 1.0,
        "the probe at the tool touches the wall: {w:?}"
    );
    sensor
}

/// Node A: a trajectory and a controller bound to the robot, the trajectory and the remote
/// sensor by its naming path, active.
fn a_pid_reading_the_sensor_on_b(a: &NodeProxy) -> ControllerProxy {
    let trajectory: TrajectoryProxy = a
        .create_as(
            "trajectory/spline",
            "hold",
            "[[waypoints]]\nat_s = 1.0\npose = \"start\"\n",
        )
        .unwrap();
    trajectory.configure().unwrap();
    let pid: ControllerProxy = a.create_as("controller/joint-pid", "pid", "").unwrap();
    pid.set_robot("slave").unwrap();
    pid.set_trajectory("hold").unwrap();
    pid.set_sensor("/B/sensors/ft").unwrap();
    pid.configure().unwrap();
    pid.activate().unwrap();
    assert_eq!(pid.state().unwrap(), LifecycleState::Active);
    pid
}

/// Telemetry: batches with increasing seq, and the wrench B publishes on the data plane
/// visible in A's loop.
fn telemetry_carries_the_wrench_b_publishes(
    client: &Client,
    pid: &ControllerProxy,
    sensor: &SensorProxy,
) {
    let mut stream = client.subscribe("/A/controllers/pid", 1).unwrap();
    let mut last_seq = None;
    let mut samples = 0;
    let mut touched = None;
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline && (samples < 50 || touched.is_none()) {
        let Some(record) = stream.recv_timeout(Duration::from_secs(2)).unwrap() else {
            continue;
        };
        if let Some(prev) = last_seq {
            assert!(record.seq > prev, "seq {} after {prev}", record.seq);
        }
        last_seq = Some(record.seq);
        samples += 1;
        let f = record.wrench.force;
        if (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt() > 1.0 {
            touched = Some(record.wrench);
        }
    }
    assert!(
        samples >= 50,
        "only {samples} telemetry samples in 10 s; controller status {:?}",
        pid.status()
    );
    let touched = touched.expect("the remote sensor's wrench never reached the loop");
    let status = pid.status().unwrap();
    assert!(status.running);
    assert!(status.ticks > 0);
    assert_eq!(status.state, LifecycleState::Active);
    assert!(touched.force[2].abs() > 1.0, "{touched:?}");
    // The sensor on B saw the probe the controller on A fed it.
    let read = sensor.read().unwrap();
    assert!(read.force.norm() > 1.0, "{read:?}");
    drop(stream);
}

/// Destroying what an active object depends on is refused; then everything goes, and the
/// naming tree shows only the creators.
fn everything_goes_but_what_an_active_object_uses_first(
    client: &Client,
    a: &NodeProxy,
    b: &NodeProxy,
    pid: &ControllerProxy,
) {
    assert!(matches!(
        a.destroy("slave", false),
        Err(RpcError::Remote(WireError::Call(CallError::InUse { .. })))
    ));
    pid.deactivate().unwrap();
    for name in ["pid", "hold", "slave", "sim0"] {
        a.destroy(name, false).unwrap();
    }
    b.destroy("ft", false).unwrap();
    assert!(a.list().unwrap().is_empty());
    assert!(b.list().unwrap().is_empty());
    assert_eq!(entries(client, "/"), ["A/", "B/"]);
    assert_eq!(entries(client, "/A"), ["creator"]);
    assert_eq!(entries(client, "/B"), ["creator"]);
    assert!(matches!(
        client.resolve("/B/sensors/ft"),
        Err(RpcError::Remote(WireError::Call(CallError::UnknownName(_))))
    ));
}

/// The same system behind a shared secret: the naming service and both nodes require it, the
/// nodes use it with each other (a remote sensor read from A on B), a client without it or with
/// another one is refused, and a node may not listen off loopback without one.
const ADMIN_SECRET: &[u8] = b"3c1f7a9e0b2d4c6e8f1a3b5c7d9e0f2a";

#[test]
fn a_system_behind_a_shared_secret() {
    let secret = b"correct horse battery staple".to_vec();
    let naming = Arc::new(NamingService::new("naming", NamingLimits::default()));
    let mut naming_config = ServerConfig::new("naming");
    naming_config.secret = Some(secret.as_slice().into());
    let naming_server = Server::bind(loopback(), naming_config, naming.clone()).unwrap();
    let naming_addr = naming_server.local_addr();

    // A node without the secret cannot register.
    let no_secret = NodeConfig::new("intruder", NamingChoice::Remote(naming_addr));
    assert!(matches!(
        Node::start(no_secret),
        Err(NodeError::NamingRefused {
            cause: RpcError::Remote(WireError::Protocol(ProtocolError::AuthFailed)),
            ..
        })
    ));
    // Nor may a node listen on every interface without one.
    let mut open = NodeConfig::new("open", NamingChoice::Host);
    open.listen = "0.0.0.0:0".parse().unwrap();
    assert!(matches!(
        Node::start(open),
        Err(NodeError::Listen(NetError::SecretRequired(_)))
    ));

    let start = |name: &str| {
        let mut config = NodeConfig::new(name, NamingChoice::Remote(naming_addr));
        config.secret = Some(secret.as_slice().into());
        // Creating objects over the wire takes the admin secret.
        config.server.admin_secret = Some(ADMIN_SECRET.into());
        config.lease = LEASE;
        Node::start(config).unwrap()
    };
    let node_a = start("A");
    let node_b = start("B");

    // Clients: none, a wrong and the right secret.
    assert!(matches!(
        Client::connect(naming_addr, ClientConfig::new("anonymous")),
        Err(RpcError::Remote(WireError::Protocol(
            ProtocolError::AuthFailed
        )))
    ));
    let mut wrong = ClientConfig::new("guess");
    wrong.secret = Some(b"password".into());
    assert!(matches!(
        Client::connect(naming_addr, wrong),
        Err(RpcError::Remote(WireError::Protocol(
            ProtocolError::AuthFailed
        )))
    ));
    let mut right = ClientConfig::admin("operator");
    right.secret = Some(secret.as_slice().into());
    right.admin_secret = Some(ADMIN_SECRET.into());
    let client = Client::connect(naming_addr, right).unwrap();
    assert_eq!(entries(&client, "/"), ["A/", "B/"]);

    // A sensor on B, read by node A through its own authenticated link.
    let sensor: SensorProxy = client
        .node("B")
        .unwrap()
        .create_as(
            "sensor/virtual",
            "ft",
            "[[shapes]]\nkind = \"plane\"\npoint = [0.0, 0.0, 0.5]\nnormal = [0.0, 0.0, 1.0]\n",
        )
        .unwrap();
    sensor.configure().unwrap();
    let probe = PoseMsg::from(&penelope_hal::Pose::translation(0.0, 0.0, 0.49));
    let reply = node_a
        .remote()
        .call(
            "/B/sensors/ft",
            Method::Sensor(SensorMethod::Measure {
                pose: probe,
                velocity: [0.0; 3],
            }),
        )
        .unwrap();
    let Reply::Wrench(w) = reply else {
        panic!("a wrench, not {reply:?}")
    };
    assert!(w.force[2] > 1.0, "1 cm into the plane pushes back: {w:?}");

    node_a.shutdown();
    node_b.shutdown();
    assert!(entries(&client, "/").is_empty());
    naming_server.shutdown();
}
