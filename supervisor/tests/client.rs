//! The client library against a real creator and naming service over loopback: every proxy
//! method on a PUMA 560 driven by a simulated board, checked against the local model, the
//! controller's lifecycle and telemetry, and the error paths.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::{Matrix3, Vector3};
use penelope_drivers::model::{self, SerialRobotModel};
use penelope_hal::{
    Dynamics, Frame, JacobianFrame, JointVector, Kinematics, LifecycleState, NamedPose, Pose,
    Reference, RobotModel, Wrench,
};
use penelope_protocol::client::{
    BoardProxy, Client, ControllerProxy, Lifecycle, RobotProxy, SensorProxy, TrajectoryProxy,
    TypedProxy,
};
use penelope_protocol::net::conn::{ClientConfig, RpcError};
use penelope_protocol::net::server::{Server, ServerConfig};
use penelope_protocol::proto::{
    CallError, Class, Method, NameEntry, ObjectRef, Reply, RobotMethod, WireError, object_path,
};
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_supervisor::naming::{NamingLimits, NamingService};

const NODE: &str = "lab";

/// Control period and plant sub-step, µs: unoptimised builds get slower loops so that a tick
/// still fits in its period.
const PERIOD_US: u32 = if cfg!(debug_assertions) {
    10_000
} else {
    2_000
};
const SUBSTEP_US: u32 = if cfg!(debug_assertions) { 1_000 } else { 200 };

/// A naming service and one node (a creator behind its server), on loopback.
struct Lab {
    naming: Option<Server>,
    node: Option<Server>,
    creator: Arc<Creator>,
    client: Client,
}

impl Lab {
    fn start() -> Lab {
        Lab::start_with(ServerConfig::new("naming"))
    }

    fn start_with(naming_config: ServerConfig) -> Lab {
        let any: SocketAddr = "127.0.0.1:0".parse().unwrap();
        let naming = Server::bind(
            any,
            naming_config,
            Arc::new(NamingService::new("naming", NamingLimits::default())),
        )
        .unwrap();
        // Normal scheduling: a test must not take a core away from the rest of the machine.
        let mut config = CreatorConfig::new(NODE);
        config.rt.priority = None;
        let creator = Arc::new(Creator::new(config));
        let node = Server::bind(any, ServerConfig::new(NODE), creator.clone()).unwrap();
        let client = Client::connect(naming.local_addr(), ClientConfig::admin(NODE)).unwrap();
        client
            .naming()
            .bind(
                &object_path(NODE, Class::Creator, ""),
                ObjectRef {
                    node: NODE.into(),
                    address: node.local_addr().to_string(),
                    name: "creator".into(),
                    class: Class::Creator,
                    kind: "creator".into(),
                },
                false,
            )
            .unwrap();
        Lab {
            naming: Some(naming),
            node: Some(node),
            creator,
            client,
        }
    }

    /// Creates an object and binds it as a node would.
    fn create<P: TypedProxy>(&self, kind: &str, name: &str, config: &str) -> P {
        let node = self.client.node(NODE).unwrap();
        let proxy: P = node.create_as(kind, name, config).unwrap();
        let info = node
            .list()
            .unwrap()
            .into_iter()
            .find(|o| o.name == name)
            .unwrap();
        self.client
            .naming()
            .bind(&node.path_of(&info), node.reference_of(&info), false)
            .unwrap();
        proxy
    }

    /// The robot `slave` on the board `sim0`, both configured.
    fn puma(&self) -> RobotProxy {
        let board: BoardProxy = self.create(
            "board/sim",
            "sim0",
            &format!("axes = 6\nsubstep_us = {SUBSTEP_US}"),
        );
        let robot: RobotProxy = self.create("robot/puma560", "slave", "");
        let map: Vec<(usize, usize)> = (0..6).map(|j| (j, j)).collect();
        robot.map_joints("sim0", &map).unwrap();
        assert_eq!(board.configure().unwrap().state, LifecycleState::Inactive);
        assert_eq!(robot.configure().unwrap().state, LifecycleState::Inactive);
        robot
    }
}

impl Drop for Lab {
    fn drop(&mut self) {
        if let Some(s) = self.node.take() {
            s.shutdown();
        }
        self.creator.shutdown();
        if let Some(s) = self.naming.take() {
            s.shutdown();
        }
    }
}

fn remote(e: RpcError) -> WireError {
    match e {
        RpcError::Remote(w) => w,
        other => panic!("expected a typed remote error, got {other:?}"),
    }
}

fn close(a: &JointVector, b: &JointVector, n: usize, tol: f64) -> bool {
    (0..n).all(|j| (a[j] - b[j]).abs() <= tol)
}

fn pose_close(a: &Pose, b: &Pose, tol: f64) -> bool {
    let (ra, rb): (Matrix3<f64>, Matrix3<f64>) = (
        a.rotation.to_rotation_matrix().into_inner(),
        b.rotation.to_rotation_matrix().into_inner(),
    );
    (a.translation.vector - b.translation.vector).amax() <= tol && (ra - rb).amax() <= tol
}

#[test]
fn a_remote_puma_computes_what_the_local_model_does() {
    let lab = Lab::start();
    let robot = lab.puma();
    let local: SerialRobotModel = model::puma560();
    let n = local.joint_count();
    assert_eq!(robot.joint_count().unwrap(), n);

    // Named poses, and the simulated body starts at `start`.
    for p in NamedPose::ALL {
        assert!(close(
            &robot.named_pose(p).unwrap(),
            &local.named_pose(p),
            n,
            1e-12
        ));
    }
    let q0 = robot.joint_positions().unwrap();
    assert!(
        close(&q0, &local.named_pose(NamedPose::Start), n, 1e-6),
        "{q0}"
    );
    assert!(
        robot
            .joint_velocities()
            .unwrap()
            .iter()
            .all(|x| x.is_finite())
    );
    assert!(
        robot
            .joint_accelerations()
            .unwrap()
            .iter()
            .all(|x| x.is_finite())
    );

    let q = JointVector::from_row_slice(&[0.3, -0.7, 0.4, 0.2, -0.5, 1.1]);
    let fk = kinematics_as_the_model(&robot, &local, &q, &q0);

    statics_and_dynamics_as_the_model(&robot, &local, &q);

    encoder_scaling_as_the_model(&robot, &local, &q);

    // What it is.
    let info = robot.describe().unwrap();
    assert_eq!(
        (info.kind.as_str(), info.class),
        ("robot/puma560", Class::Robot)
    );
    assert_eq!(robot.state().unwrap(), LifecycleState::Inactive);
    assert_eq!(robot.path(), "/lab/robots/slave");

    // The board.
    let board: BoardProxy = lab.client.board("/lab/boards/sim0").unwrap();
    assert_eq!(board.axis_count().unwrap(), 6);
    assert_eq!(board.read_encoders().unwrap().len(), 6);
    assert!(!board.amplifiers_enabled().unwrap());

    // The same robot by its NODE/NAME shorthand, and a raw call by path.
    let again = lab.client.robot("lab/slave").unwrap();
    assert!(pose_close(
        &again.forward_kinematics(Some(&q)).unwrap(),
        &fk,
        0.0
    ));
    let reply = lab
        .client
        .call(
            "/lab/robots/slave",
            Method::Robot(RobotMethod::JointPositions),
        )
        .unwrap();
    assert!(matches!(reply, Reply::Joints(v) if v.len() == n));
}

/// Forward kinematics (given and measured joints), the operational state, the Jacobian and its
/// damped inverse, and inverse kinematics, as the local model computes them; returns the pose
/// of `q`.
fn kinematics_as_the_model(
    robot: &RobotProxy,
    local: &SerialRobotModel,
    q: &JointVector,
    q0: &JointVector,
) -> Pose {
    let n = local.joint_count();
    let fk = robot.forward_kinematics(Some(q)).unwrap();
    assert!(pose_close(&fk, &local.forward(q), 1e-12));
    let fk_measured = robot.forward_kinematics(None).unwrap();
    assert!(pose_close(&fk_measured, &local.forward(q0), 1e-12));
    let op = robot.operational_state().unwrap();
    assert!(pose_close(&op.pose, &fk_measured, 1e-12));
    assert_eq!(op.twist.frame, Frame::Base);

    // Jacobian and its damped inverse.
    let j = robot.jacobian(Some(q)).unwrap();
    assert!((j - local.jacobian(q, JacobianFrame::Base)).amax() < 1e-12);
    let ji = robot.jacobian_inverse(Some(q), 0.01).unwrap();
    assert!((ji - local.jacobian_damped_inverse(q, 0.01)).amax() < 1e-12);

    // Inverse kinematics finds q among its branches.
    let sols = robot.inverse_kinematics(&fk).unwrap();
    assert!(!sols.is_empty());
    assert!(
        sols.iter().any(|s| close(s, q, n, 1e-6)),
        "{q} not among {sols:?}"
    );
    fk
}

/// Statics (a base-frame and a tool-frame wrench) and dynamics, as the local model computes
/// them.
fn statics_and_dynamics_as_the_model(
    robot: &RobotProxy,
    local: &SerialRobotModel,
    q: &JointVector,
) {
    let n = local.joint_count();
    let base = Wrench {
        force: Vector3::new(1.0, -2.0, 3.0),
        torque: Vector3::new(0.1, 0.2, -0.3),
        frame: Frame::Base,
    };
    let tau = robot.wrench_to_torques(&base, Some(q)).unwrap();
    assert!(close(
        &tau,
        &local.wrench_to_torques(q, &base).unwrap(),
        n,
        1e-12
    ));
    let tool = Wrench {
        frame: Frame::Tool,
        ..base
    };
    let tau = robot.wrench_to_torques(&tool, Some(q)).unwrap();
    assert!(close(
        &tau,
        &local.wrench_to_torques(q, &tool).unwrap(),
        n,
        1e-9
    ));

    // Dynamics.
    assert!(close(
        &robot.gravity(Some(q)).unwrap(),
        &local.gravity(q),
        n,
        1e-12
    ));
    let m = robot.inertia(Some(q)).unwrap();
    assert!((m - local.inertia(q)).amax() < 1e-12);
}

/// Encoder scaling, both ways, as the local model's counts per radian give it.
fn encoder_scaling_as_the_model(robot: &RobotProxy, local: &SerialRobotModel, q: &JointVector) {
    let n = local.joint_count();
    let counts = robot.radians_to_counts(q).unwrap();
    assert_eq!(counts.len(), n);
    for (jj, c) in counts.iter().enumerate() {
        assert_eq!(*c, (q[jj] * local.counts_per_radian(jj)).round() as i64);
    }
    let back = robot.counts_to_radians(&counts).unwrap();
    assert!(close(&back, q, n, 1e-3));
}

#[test]
fn bad_paths_classes_and_arguments_are_typed_errors() {
    let lab = Lab::start();
    let robot = lab.puma();
    let client = &lab.client;

    bad_paths_and_classes(client);

    nan_and_nonsense_refused_before_sending_and_by_the_node(client, &robot);

    the_nodes_own_refusals(client, &robot);
    // Displays a user understands.
    let e = client.robot("/lab/boards/sim0").unwrap_err();
    assert_eq!(e.to_string(), "`/lab/boards/sim0` is a board, not a robot");
}

/// Unknown paths and names, a malformed spec, an unknown node, and a proxy of the wrong class.
fn bad_paths_and_classes(client: &Client) {
    assert!(matches!(
        remote(client.robot("/lab/robots/nobody").unwrap_err()),
        WireError::Call(CallError::UnknownName(_))
    ));
    assert!(matches!(
        remote(client.robot("lab/nobody").unwrap_err()),
        WireError::Call(CallError::UnknownName(_))
    ));
    assert!(matches!(
        remote(client.robot("nobody").unwrap_err()),
        WireError::Call(CallError::BadName { .. })
    ));
    assert!(matches!(
        remote(client.node("elsewhere").unwrap_err()),
        WireError::Call(CallError::UnknownName(_))
    ));
    match remote(client.sensor("/lab/robots/slave").unwrap_err()) {
        WireError::Call(CallError::WrongClass {
            expected, found, ..
        }) => assert_eq!((expected, found), (Class::Sensor, Class::Robot)),
        other => panic!("{other:?}"),
    }
}

/// NaN and nonsense are refused before sending, and by the node when sent anyway.
fn nan_and_nonsense_refused_before_sending_and_by_the_node(client: &Client, robot: &RobotProxy) {
    // NaN and nonsense are refused before sending...
    let mut q = JointVector::zeros();
    q[2] = f64::NAN;
    for e in [
        robot.forward_kinematics(Some(&q)).unwrap_err(),
        robot.gravity(Some(&q)).unwrap_err(),
        robot.go_to(NamedPose::Work, f64::NAN).unwrap_err(),
        robot.go_to(NamedPose::Work, -1.0).unwrap_err(),
        robot.jacobian_inverse(None, f64::NAN).unwrap_err(),
        robot
            .wrench_to_torques(
                &Wrench {
                    force: Vector3::new(f64::NAN, 0.0, 0.0),
                    ..Wrench::zero(Frame::Base)
                },
                None,
            )
            .unwrap_err(),
        robot.map_joints("sim0", &[(300, 0)]).unwrap_err(),
    ] {
        assert!(matches!(
            remote(e),
            WireError::Call(CallError::BadArgument(_))
        ));
    }
    let mut pose = Pose::identity();
    pose.translation.vector.x = f64::NAN;
    assert!(matches!(
        remote(robot.inverse_kinematics(&pose).unwrap_err()),
        WireError::Call(CallError::BadArgument(_))
    ));
    // ... and by the node when sent anyway.
    let e = client
        .call(
            "/lab/robots/slave",
            Method::Robot(RobotMethod::Gravity {
                q: Some(vec![0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]),
            }),
        )
        .unwrap_err();
    assert!(matches!(
        remote(e),
        WireError::Call(CallError::BadArgument(_))
    ));
    let e = client
        .call(
            "/lab/robots/slave",
            Method::Robot(RobotMethod::Gravity {
                q: Some(vec![0.0; 3]),
            }),
        )
        .unwrap_err();
    assert!(matches!(
        remote(e),
        WireError::Call(CallError::BadArgument(_))
    ));
}

/// What the node itself refuses: motion before activation, a repeated transition, unknown kinds,
/// taken names, bad configurations, and a proxy of the wrong class before anything is created.
fn the_nodes_own_refusals(client: &Client, robot: &RobotProxy) {
    assert!(matches!(
        remote(robot.go_to(NamedPose::Work, 1.0).unwrap_err()),
        WireError::Call(CallError::NotReady(_))
    ));
    assert!(matches!(
        remote(robot.configure().unwrap_err()),
        WireError::Call(CallError::InvalidTransition { .. })
    ));
    let node = client.node(NODE).unwrap();
    assert!(matches!(
        remote(node.create("robot/abb", "x", "").unwrap_err()),
        WireError::Call(CallError::UnknownKind(_))
    ));
    assert!(matches!(
        remote(node.create("robot/puma560", "slave", "").unwrap_err()),
        WireError::Call(CallError::NameTaken(_))
    ));
    assert!(matches!(
        remote(node.create("board/sim", "b2", "axes = 99").unwrap_err()),
        WireError::Call(CallError::BadConfig { .. })
    ));
    // A proxy of the wrong class is refused before anything is created.
    assert!(matches!(
        remote(
            node.create_as::<SensorProxy>("robot/puma560", "twin", "")
                .unwrap_err()
        ),
        WireError::Call(CallError::WrongClass { .. })
    ));
    assert!(node.list().unwrap().iter().all(|o| o.name != "twin"));
}

#[test]
fn a_controller_runs_streams_telemetry_and_everything_is_destroyed() {
    let lab = Lab::start();
    let robot = lab.puma();
    let local = model::puma560();
    let start = local.named_pose(NamedPose::Start);

    let goal: Vec<String> = start.iter().take(6).map(|x| format!("{x:?}")).collect();
    let hold: TrajectoryProxy = lab.create(
        "trajectory/step",
        "hold",
        &format!("goal = [{}]", goal.join(", ")),
    );
    hold.configure().unwrap();
    match hold.reference(0.5).unwrap() {
        Reference::Joint(r) => assert!(close(&r.position, &start, 6, 1e-12)),
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        remote(hold.reference(f64::NAN).unwrap_err()),
        WireError::Call(CallError::BadArgument(_))
    ));
    let _ = hold.duration().unwrap();

    let pid: ControllerProxy = lab.create(
        "controller/joint-pid",
        "pid",
        &format!("period_us = {PERIOD_US}\ncomm_period_us = {PERIOD_US}"),
    );
    assert!(matches!(
        remote(pid.configure().unwrap_err()),
        WireError::Call(CallError::NotReady(_))
    ));
    pid.set_robot("slave").unwrap();
    pid.set_trajectory("hold").unwrap();
    pid.configure().unwrap();
    assert_eq!(pid.activate().unwrap().state, LifecycleState::Active);

    // Telemetry: samples in order from the running loop.
    let mut stream = lab.client.subscribe("/lab/controllers/pid", 1).unwrap();
    stream.set_timeout(Duration::from_secs(5));
    let samples: Vec<_> = stream.by_ref().take(20).collect::<Result<_, _>>().unwrap();
    assert_eq!(samples.len(), 20);
    assert!(samples.windows(2).all(|w| w[1].seq > w[0].seq));
    assert!(samples.iter().all(|s| s.q.len() == 6));
    drop(stream);

    let status = pid.status().unwrap();
    assert!(status.running && status.ticks > 0, "{status:?}");
    robot.go_to(NamedPose::Start, 0.2).unwrap();
    pid.set_gains("kd = 20.0").unwrap();
    assert!(matches!(
        remote(pid.set_gains("no_such_gain = 1").unwrap_err()),
        WireError::Call(CallError::BadConfig { .. })
    ));

    // An active controller holds its robot.
    let node = lab.client.node(NODE).unwrap();
    match remote(node.destroy("slave", false).unwrap_err()) {
        WireError::Call(CallError::InUse { dependents, .. }) => {
            assert_eq!(dependents, vec!["pid".to_string()])
        }
        other => panic!("{other:?}"),
    }
    pid.estop().unwrap();
    assert_eq!(pid.deactivate().unwrap().state, LifecycleState::Inactive);
    assert!(!pid.status().unwrap().running);

    for name in ["pid", "hold", "slave", "sim0"] {
        let info = node
            .list()
            .unwrap()
            .into_iter()
            .find(|o| o.name == name)
            .unwrap();
        let path = node.path_of(&info);
        node.destroy(name, false).unwrap();
        lab.client.naming().unbind(&path).unwrap();
    }
    assert!(node.list().unwrap().is_empty());
    let left: Vec<_> = lab.client.naming().tree("/").unwrap();
    assert!(
        left.iter()
            .all(|(p, _, _)| p == "/lab" || p == "/lab/creator"),
        "{left:?}"
    );
}

#[test]
fn a_virtual_sensor_measures_the_probe_and_the_naming_proxy_lists() {
    let lab = Lab::start();
    let wall: SensorProxy = lab.create(
        "sensor/virtual",
        "wall",
        "[[shapes]]\nkind = \"plane\"\npoint = [0.0, 0.0, 0.5]\nnormal = [0.0, 0.0, -1.0]\nstiffness = 1000.0\ndamping = 0.0\n",
    );
    wall.configure().unwrap();
    let free = Pose::translation(0.0, 0.0, 0.4);
    let pressed = Pose::translation(0.0, 0.0, 0.51);
    let still = Vector3::zeros();
    assert!(wall.measure(&free, &still).unwrap().force.norm() < 1e-9);
    let w = wall.measure(&pressed, &still).unwrap();
    assert!((w.force.norm() - 10.0).abs() < 1e-6, "{w:?}");
    wall.set_probe(&pressed, &still).unwrap();
    let r = wall.read().unwrap();
    assert!((r.force - w.force).norm() < 1e-9);
    wall.bias().unwrap();
    assert!(wall.read().unwrap().force.norm() < 1e-9);
    assert!(matches!(
        remote(
            wall.measure(&pressed, &Vector3::new(f64::NAN, 0.0, 0.0))
                .unwrap_err()
        ),
        WireError::Call(CallError::BadArgument(_))
    ));

    let naming = lab.client.naming();
    let names = naming.list("/lab").unwrap();
    assert!(
        names
            .iter()
            .any(|e| matches!(e, NameEntry::Context { name } if name == "sensors"))
    );
    let tree = naming.tree("/").unwrap();
    let paths: Vec<&str> = tree.iter().map(|(p, _, _)| p.as_str()).collect();
    assert!(paths.contains(&"/lab/sensors/wall"), "{paths:?}");
    assert!(
        tree.iter()
            .any(|(p, d, _)| p == "/lab/sensors/wall" && *d == 2)
    );
    let r = naming.resolve("/lab/sensors/wall").unwrap();
    assert_eq!((r.class, r.name.as_str()), (Class::Sensor, "wall"));
    // A node binds only inside its own context (the lab's client is an admin: it creates).
    let as_node = Client::connect(lab.client.naming_address(), ClientConfig::node(NODE)).unwrap();
    assert!(matches!(
        remote(
            as_node
                .naming()
                .bind("/elsewhere/alias", r.clone(), false)
                .unwrap_err()
        ),
        WireError::Call(CallError::Forbidden(_))
    ));
    naming.bind("/lab/aliases/wall", r.clone(), false).unwrap();
    assert!(matches!(
        remote(naming.bind("/lab/aliases/wall", r, false).unwrap_err()),
        WireError::Call(CallError::NameTaken(_))
    ));
    let alias = lab.client.sensor("/lab/aliases/wall").unwrap();
    let deeper = Pose::translation(0.0, 0.0, 0.52);
    assert!(alias.measure(&deeper, &still).unwrap().force.norm() > 1.0);
    naming.unbind("/lab/aliases/wall").unwrap();
    assert!(matches!(
        remote(naming.resolve("/lab/aliases/wall").unwrap_err()),
        WireError::Call(CallError::UnknownName(_))
    ));
    assert_eq!(lab.client.nodes().unwrap().len(), 1);
    assert!(!lab.client.node(NODE).unwrap().kinds().unwrap().is_empty());
}

#[test]
fn a_connection_the_node_closed_is_reopened_once() {
    let mut config = ServerConfig::new("naming");
    config.idle_timeout = Duration::from_millis(200);
    let lab = Lab::start_with(config);
    assert!(lab.client.naming().list("/").is_ok());
    // The naming service drops the idle connection; the next call reconnects transparently.
    std::thread::sleep(Duration::from_millis(600));
    if let Err(e) = lab.client.naming().list("/") {
        panic!("{e:?}");
    }
    assert!(lab.client.naming().resolve("/lab/creator").is_ok());
}
