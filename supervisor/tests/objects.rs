//! The creator in-process (no network): kinds, a PUMA 560 on two simulated boards driven by a
//! joint PID along a trajectory and by GoTo, telemetry through an outbox, a remote force sensor,
//! destroy rules, axis conflicts and typed errors.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use penelope_hal::{NamedPose, Transition};
use penelope_supervisor::objects::{Creator, CreatorConfig};
use penelope_supervisor::proto::{
    BoardMethod, Call, Class, ControllerMethod, CreatorCall, JointAxis, Method, NamingCall, Reply,
    RobotMethod, SensorMethod, ServerMsg, TrajectoryMethod, WireError, WrenchMsg,
};
use penelope_supervisor::service::{Outbox, OutboxReceiver, Remote, Service, Session};

fn session(id: u64) -> (Session, OutboxReceiver) {
    let (outbox, rx) = Outbox::bounded(1024);
    (
        Session {
            id,
            peer: "127.0.0.1:40000".parse().unwrap(),
            client: "test".into(),
            identity: penelope_supervisor::service::Identity::LOCAL_NODE,
            outbox,
        },
        rx,
    )
}

fn creator() -> Creator {
    let mut config = CreatorConfig::new("lab");
    config.rt.priority = None;
    Creator::new(config)
}

fn call(c: &Creator, s: &Session, method: (&str, Method)) -> Result<Reply, WireError> {
    c.call(
        s,
        Call::Object {
            object: method.0.into(),
            method: method.1,
        },
    )
}

fn create(c: &Creator, s: &Session, kind: &str, name: &str, config: &str) {
    c.call(
        s,
        Call::Creator(CreatorCall::Create {
            kind: kind.into(),
            name: name.into(),
            config: config.into(),
        }),
    )
    .unwrap_or_else(|e| panic!("create {kind} {name}: {e}"));
}

fn lifecycle(c: &Creator, s: &Session, name: &str, t: Transition) -> Result<Reply, WireError> {
    call(c, s, (name, Method::Transition(t)))
}

fn map(c: &Creator, s: &Session, robot: &str, board: &str, pairs: &[(u8, u8)]) {
    call(
        c,
        s,
        (
            robot,
            Method::Robot(RobotMethod::MapJoints {
                board: board.into(),
                joints: pairs
                    .iter()
                    .map(|(joint, axis)| JointAxis {
                        joint: *joint,
                        axis: *axis,
                    })
                    .collect(),
            }),
        ),
    )
    .unwrap();
}

/// The joint values of a reply, or `None` for an error (a loop that has not ticked yet).
fn try_joints(r: Result<Reply, WireError>) -> Option<Vec<f64>> {
    match r {
        Ok(Reply::Joints(q)) => Some(q),
        _ => None,
    }
}

fn joints(r: Result<Reply, WireError>) -> Vec<f64> {
    match r {
        Ok(Reply::Joints(q)) => q,
        other => panic!("expected joints, got {other:?}"),
    }
}

fn ctl(c: &Creator, s: &Session, name: &str, m: ControllerMethod) -> Result<Reply, WireError> {
    call(c, s, (name, Method::Controller(m)))
}

/// A PUMA 560 named `robot` on two simulated boards (joints 0-2 on `b1` axes 0-2, joints 3-5
/// on `b2` axes 0-2), a joint PID `pid` following the trajectory `traj`.
fn puma_on_two_boards(c: &Creator, s: &Session, traj_kind: &str, traj_cfg: &str) {
    create(c, s, "robot/puma560", "robot", "");
    create(c, s, "board/sim", "b1", "axes = 3");
    create(c, s, "board/sim", "b2", "axes = 3");
    map(c, s, "robot", "b1", &[(0, 0), (1, 1), (2, 2)]);
    map(c, s, "robot", "b2", &[(3, 0), (4, 1), (5, 2)]);
    for b in ["b1", "b2", "robot"] {
        lifecycle(c, s, b, Transition::Configure).unwrap();
    }
    create(c, s, traj_kind, "traj", traj_cfg);
    lifecycle(c, s, "traj", Transition::Configure).unwrap();
    create(c, s, "controller/joint-pid", "pid", "");
    ctl(
        c,
        s,
        "pid",
        ControllerMethod::SetRobot {
            robot: "robot".into(),
        },
    )
    .unwrap();
    ctl(
        c,
        s,
        "pid",
        ControllerMethod::SetTrajectory {
            trajectory: "traj".into(),
        },
    )
    .unwrap();
    lifecycle(c, s, "pid", Transition::Configure).unwrap();
}

fn max_error(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn wait_for(what: &str, timeout: Duration, mut ok: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !ok() {
        assert!(t0.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn kinds_are_listed_with_their_keys() {
    let c = creator();
    let (s, _rx) = session(1);
    let Ok(Reply::Kinds(kinds)) = c.call(&s, Call::Creator(CreatorCall::Kinds)) else {
        panic!("kinds")
    };
    for k in [
        "robot/puma560",
        "robot/puma200",
        "robot/frhc",
        "board/sim",
        "board/galil",
        "sensor/virtual",
        "controller/joint-pid",
        "controller/cartesian-impedance",
        "trajectory/step",
        "trajectory/ramp",
        "trajectory/trapezoidal",
        "trajectory/spline",
    ] {
        let info = kinds.iter().find(|i| i.kind == k).expect(k);
        assert!(!info.config.is_empty(), "{k} documents its keys");
    }
    assert!(matches!(
        c.call(&s, Call::NodeInfo),
        Ok(Reply::Node(n)) if n.node == "lab" && n.objects == 0
    ));
}

#[test]
fn a_puma_on_two_boards_follows_its_trajectory_streams_telemetry_and_goes_to_work() {
    // SCHED_FIFO where the process may use it (else normal priority, said in `describe`).
    let c = Creator::new(CreatorConfig::new("lab"));
    let (s, rx) = session(1);
    create(&c, &s, "robot/puma560", "probe-model", "");
    let start = joints(call(
        &c,
        &s,
        (
            "probe-model",
            Method::Robot(RobotMethod::NamedPose {
                pose: NamedPose::Start,
            }),
        ),
    ));
    let goal: Vec<f64> = start
        .iter()
        .zip([0.2, -0.1, 0.1, 0.2, 0.1, 0.2])
        .map(|(q, d)| q + d)
        .collect();
    let goal_text = format!(
        "goal = [{}]\nduration_s = 0.6",
        goal.iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    puma_on_two_boards(&c, &s, "trajectory/ramp", &goal_text);

    // Before activation: the measured state is the simulated body's start pose.
    let q0 = joints(call(
        &c,
        &s,
        ("robot", Method::Robot(RobotMethod::JointPositions)),
    ));
    assert!(max_error(&q0, &start) < 1e-6);

    let Ok(Reply::Subscribed { subscription }) = c.call(
        &s,
        Call::Subscribe {
            object: "pid".into(),
            decimation: 10,
        },
    ) else {
        panic!("subscribe")
    };
    let info = lifecycle(&c, &s, "pid", Transition::Activate).unwrap();
    assert!(matches!(info, Reply::Object(o) if o.state == penelope_hal::LifecycleState::Active));
    for used in ["robot", "b1", "b2", "traj"] {
        assert_eq!(
            c.info(used).unwrap().state,
            penelope_hal::LifecycleState::Active,
            "{used} shows active while the loop runs"
        );
    }

    // The ramp ends after 0.6 s; the robot settles at the goal.
    wait_for("the goal", Duration::from_secs(5), || {
        try_joints(call(
            &c,
            &s,
            ("robot", Method::Robot(RobotMethod::JointPositions)),
        ))
        .is_some_and(|q| max_error(&q, &goal) < 0.02)
    });
    let Ok(Reply::Status(status)) = ctl(&c, &s, "pid", ControllerMethod::Status) else {
        panic!("status")
    };
    assert!(status.running && status.ticks > 100);
    let last = status.last.unwrap();
    assert!(last.state == "running", "state {}", last.state);
    assert!(max_error(&last.q, &goal) < 0.03);

    // Telemetry batches arrived, samples decimated and in order.
    let mut seqs = Vec::new();
    while let Ok(m) = rx.rx.try_recv() {
        if let ServerMsg::Telemetry(b) = m {
            assert_eq!(b.subscription, subscription);
            seqs.extend(b.samples.iter().map(|r| r.seq));
        }
    }
    assert!(seqs.len() > 20, "{} samples", seqs.len());
    assert!(seqs.windows(2).all(|w| w[1] > w[0]), "increasing seq");
    assert!(seqs.iter().all(|q| q % 10 == 0), "decimated by 10");

    // GoTo work, through the active controller.
    let work = joints(call(
        &c,
        &s,
        (
            "robot",
            Method::Robot(RobotMethod::NamedPose {
                pose: NamedPose::Work,
            }),
        ),
    ));
    call(
        &c,
        &s,
        (
            "robot",
            Method::Robot(RobotMethod::GoTo {
                pose: NamedPose::Work,
                duration_s: 2.0,
            }),
        ),
    )
    .unwrap();
    wait_for("the work pose", Duration::from_secs(10), || {
        try_joints(call(
            &c,
            &s,
            ("robot", Method::Robot(RobotMethod::JointPositions)),
        ))
        .is_some_and(|q| max_error(&q, &work) < 0.02)
    });
    assert!(matches!(
        call(
            &c,
            &s,
            ("b1", Method::Board(BoardMethod::AmplifiersEnabled))
        ),
        Ok(Reply::Flag(true))
    ));

    // Destroy is refused while active, then forced: the loop stops, amplifiers off.
    match c.call(
        &s,
        Call::Creator(CreatorCall::Destroy {
            name: "b2".into(),
            force: false,
        }),
    ) {
        Err(WireError::InUse { dependents, .. }) => assert_eq!(dependents, vec!["pid".to_string()]),
        other => panic!("expected InUse, got {other:?}"),
    }
    c.call(
        &s,
        Call::Creator(CreatorCall::Destroy {
            name: "b2".into(),
            force: true,
        }),
    )
    .unwrap();
    assert!(c.info("b2").is_none());
    let Ok(Reply::Status(status)) = ctl(&c, &s, "pid", ControllerMethod::Status) else {
        panic!("status")
    };
    assert!(!status.running);
    assert_eq!(status.state, penelope_hal::LifecycleState::Inactive);
    assert_eq!(
        c.info("robot").unwrap().state,
        penelope_hal::LifecycleState::Inactive
    );
    assert!(matches!(
        call(
            &c,
            &s,
            ("b1", Method::Board(BoardMethod::AmplifiersEnabled))
        ),
        Ok(Reply::Flag(false))
    ));
    // The body kept its pose across the stop.
    let q = joints(call(
        &c,
        &s,
        ("robot", Method::Robot(RobotMethod::JointPositions)),
    ));
    assert!(max_error(&q, &work) < 0.05);
    c.closed(&s);
    assert_eq!(c.subscription_count(), 0);
}

struct FakeRemote {
    calls: AtomicU64,
    fail: AtomicBool,
}

impl Remote for FakeRemote {
    fn call(&self, path: &str, method: Method) -> Result<Reply, WireError> {
        assert_eq!(path, "/other/sensors/ft");
        self.calls.fetch_add(1, Ordering::Relaxed);
        if self.fail.load(Ordering::Relaxed) {
            return Err(WireError::Remote("node `other` is unreachable".into()));
        }
        match method {
            Method::Sensor(SensorMethod::Measure { pose, .. }) => {
                assert!(pose.to_pose().is_ok());
                Ok(Reply::Wrench(WrenchMsg {
                    force: [1.0, 2.0, 3.0],
                    torque: [0.0, 0.0, 0.5],
                }))
            }
            other => Err(WireError::BadArgument(format!("{other:?}"))),
        }
    }
}

#[test]
fn a_remote_sensor_wrench_reaches_telemetry_and_goes_stale_when_the_remote_fails() {
    let c = creator();
    let (s, _rx) = session(1);
    puma_on_two_boards(&c, &s, "trajectory/step", "pose = \"start\"");
    let remote = Arc::new(FakeRemote {
        calls: AtomicU64::new(0),
        fail: AtomicBool::new(false),
    });
    ctl(
        &c,
        &s,
        "pid",
        ControllerMethod::SetSensor {
            sensor: "/other/sensors/ft".into(),
        },
    )
    .unwrap();
    // Without a remote the activation is refused, typed.
    assert!(matches!(
        lifecycle(&c, &s, "pid", Transition::Activate),
        Err(WireError::NotReady(_))
    ));
    c.set_remote(remote.clone());
    lifecycle(&c, &s, "pid", Transition::Activate).unwrap();
    let status = |c: &Creator| match ctl(c, &s, "pid", ControllerMethod::Status) {
        Ok(Reply::Status(st)) => st,
        other => panic!("{other:?}"),
    };
    wait_for("the remote wrench", Duration::from_secs(5), || {
        status(&c)
            .last
            .is_some_and(|l| l.wrench.force == [1.0, 2.0, 3.0])
    });
    assert!(matches!(
        call(&c, &s, ("robot", Method::Robot(RobotMethod::ToolWrench))),
        Ok(Reply::Wrench(w)) if w.force == [1.0, 2.0, 3.0]
    ));
    remote.fail.store(true, Ordering::Relaxed);
    wait_for("the stale wrench", Duration::from_secs(5), || {
        status(&c)
            .last
            .is_some_and(|l| l.wrench.force == [0.0, 0.0, 0.0])
    });
    // The loop keeps running (the sensor is optional for a joint PID).
    assert_eq!(status(&c).last.unwrap().state, "running");
    assert!(remote.calls.load(Ordering::Relaxed) > 10);
    c.shutdown();
    assert!(!status(&c).running);
}

#[test]
fn a_local_virtual_sensor_measures_its_environment() {
    let c = creator();
    let (s, _rx) = session(1);
    create(
        &c,
        &s,
        "sensor/virtual",
        "ft",
        "[[shapes]]\nkind = \"plane\"\npoint = [0, 0, 0.5]\nnormal = [0, 0, 1]\nstiffness = 1000\ndamping = 0",
    );
    assert!(matches!(
        call(&c, &s, ("ft", Method::Sensor(SensorMethod::Read))),
        Err(WireError::NotReady(_))
    ));
    lifecycle(&c, &s, "ft", Transition::Configure).unwrap();
    let pose = |z: f64| penelope_supervisor::proto::PoseMsg {
        position: [0.0, 0.0, z],
        n: [1.0, 0.0, 0.0],
        o: [0.0, 1.0, 0.0],
        a: [0.0, 0.0, 1.0],
    };
    let Ok(Reply::Wrench(w)) = call(
        &c,
        &s,
        (
            "ft",
            Method::Sensor(SensorMethod::Measure {
                pose: pose(0.49),
                velocity: [0.0; 3],
            }),
        ),
    ) else {
        panic!("measure")
    };
    assert!(
        (w.force[2] - 10.0).abs() < 1e-9,
        "1 cm into a 1000 N/m wall: {w:?}"
    );
    call(&c, &s, ("ft", Method::Sensor(SensorMethod::Bias))).unwrap();
    assert!(matches!(
        call(&c, &s, ("ft", Method::Sensor(SensorMethod::Read))),
        Ok(Reply::Wrench(w)) if w.force[2].abs() < 1e-12
    ));
    assert!(matches!(
        call(
            &c,
            &s,
            (
                "ft",
                Method::Sensor(SensorMethod::SetProbe {
                    pose: pose(f64::NAN),
                    velocity: [0.0; 3]
                })
            )
        ),
        Err(WireError::BadArgument(_))
    ));
}

#[test]
fn two_robots_may_map_one_board_but_only_one_loop_drives_an_axis() {
    let c = creator();
    let (s, _rx) = session(1);
    puma_on_two_boards(&c, &s, "trajectory/step", "pose = \"start\"");
    create(&c, &s, "robot/puma200", "second", "");
    map(&c, &s, "second", "b1", &[(0, 0), (1, 1), (2, 2)]);
    create(&c, &s, "board/sim", "b3", "axes = 3");
    lifecycle(&c, &s, "b3", Transition::Configure).unwrap();
    map(&c, &s, "second", "b3", &[(3, 0), (4, 1), (5, 2)]);
    lifecycle(&c, &s, "second", Transition::Configure).unwrap();
    create(&c, &s, "controller/joint-pid", "pid2", "");
    ctl(
        &c,
        &s,
        "pid2",
        ControllerMethod::SetRobot {
            robot: "second".into(),
        },
    )
    .unwrap();
    ctl(
        &c,
        &s,
        "pid2",
        ControllerMethod::SetTrajectory {
            trajectory: "traj".into(),
        },
    )
    .unwrap();
    lifecycle(&c, &s, "pid2", Transition::Configure).unwrap();

    lifecycle(&c, &s, "pid", Transition::Activate).unwrap();
    match lifecycle(&c, &s, "pid2", Transition::Activate) {
        Err(WireError::InUse { name, dependents }) => {
            assert_eq!(name, "b1");
            assert_eq!(dependents, vec!["pid".to_string()]);
        }
        other => panic!("expected InUse, got {other:?}"),
    }
    // A second controller on the same robot is refused too.
    create(&c, &s, "controller/joint-pid", "pid3", "");
    ctl(
        &c,
        &s,
        "pid3",
        ControllerMethod::SetRobot {
            robot: "robot".into(),
        },
    )
    .unwrap();
    ctl(
        &c,
        &s,
        "pid3",
        ControllerMethod::SetTrajectory {
            trajectory: "traj".into(),
        },
    )
    .unwrap();
    lifecycle(&c, &s, "pid3", Transition::Configure).unwrap();
    assert!(matches!(
        lifecycle(&c, &s, "pid3", Transition::Activate),
        Err(WireError::InUse { .. })
    ));
    // Once the first stops, the second may run.
    lifecycle(&c, &s, "pid", Transition::Deactivate).unwrap();
    lifecycle(&c, &s, "pid2", Transition::Activate).unwrap();
    lifecycle(&c, &s, "pid2", Transition::Deactivate).unwrap();
}

#[test]
fn every_bad_input_gets_a_typed_error() {
    let mut config = CreatorConfig::new("lab");
    config.max_objects = 4;
    config.rt.priority = None;
    let c = Creator::new(config);
    let (s, _rx) = session(1);
    let creator_call = |cc: CreatorCall| c.call(&s, Call::Creator(cc));
    let mk = |kind: &str, name: &str, config: &str| {
        creator_call(CreatorCall::Create {
            kind: kind.into(),
            name: name.into(),
            config: config.into(),
        })
    };
    assert!(matches!(
        mk("robot/r2d2", "x", ""),
        Err(WireError::UnknownKind(_))
    ));
    assert!(matches!(
        mk("robot/puma560", "a/b", ""),
        Err(WireError::BadName { .. })
    ));
    assert!(matches!(
        mk("robot/puma560", "x", "colour = \"red\""),
        Err(WireError::BadConfig { .. })
    ));
    assert!(matches!(
        mk("trajectory/ramp", "x", "duration_s = -2"),
        Err(WireError::BadConfig { .. })
    ));
    assert!(matches!(
        mk("controller/joint-pid", "x", "period_us = 5"),
        Err(WireError::BadConfig { .. })
    ));
    mk("robot/puma560", "arm", "").unwrap();
    assert!(matches!(
        mk("robot/puma560", "arm", ""),
        Err(WireError::NameTaken(_))
    ));
    mk(
        "board/galil",
        "dmc",
        "address = \"127.0.0.1:1\"\nconnect_timeout_ms = 200",
    )
    .unwrap();
    assert!(matches!(
        lifecycle(&c, &s, "dmc", Transition::Configure),
        Err(WireError::Device(_))
    ));
    assert_eq!(
        c.info("dmc").unwrap().state,
        penelope_hal::LifecycleState::Unconfigured
    );
    mk(
        "trajectory/spline",
        "spl",
        "[[waypoints]]\nat_s = 1.0\nq = [0.1, 0.2]",
    )
    .unwrap();
    assert!(matches!(
        call(
            &c,
            &s,
            (
                "spl",
                Method::Trajectory(TrajectoryMethod::Reference { t_s: 1.0 })
            )
        ),
        Ok(Reply::Reference(_))
    ));
    assert!(matches!(
        call(
            &c,
            &s,
            (
                "spl",
                Method::Trajectory(TrajectoryMethod::Reference { t_s: f64::NAN })
            )
        ),
        Err(WireError::BadArgument(_))
    ));
    mk("controller/joint-pid", "pid", "").unwrap();
    assert!(matches!(
        mk("robot/puma200", "one-too-many", ""),
        Err(WireError::LimitReached { limit: 4, .. })
    ));

    // Methods.
    let fk = |q: Vec<f64>| {
        call(
            &c,
            &s,
            (
                "arm",
                Method::Robot(RobotMethod::ForwardKinematics { q: Some(q) }),
            ),
        )
    };
    assert!(matches!(fk(vec![0.0; 6]), Ok(Reply::Pose(_))));
    assert!(matches!(
        fk(vec![0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]),
        Err(WireError::BadArgument(_))
    ));
    assert!(matches!(fk(vec![0.0; 5]), Err(WireError::BadArgument(_))));
    assert!(matches!(
        call(&c, &s, ("arm", Method::Robot(RobotMethod::JointPositions))),
        Err(WireError::NotReady(_))
    ));
    assert!(matches!(
        call(&c, &s, ("arm", Method::Board(BoardMethod::AxisCount))),
        Err(WireError::WrongClass {
            expected: Class::Board,
            found: Class::Robot,
            ..
        })
    ));
    assert!(matches!(
        call(&c, &s, ("ghost", Method::Describe)),
        Err(WireError::UnknownName(_))
    ));
    assert!(matches!(
        call(
            &c,
            &s,
            (
                "arm",
                Method::Robot(RobotMethod::GoTo {
                    pose: NamedPose::Work,
                    duration_s: 1.0
                })
            )
        ),
        Err(WireError::NotReady(_))
    ));
    assert!(matches!(
        call(
            &c,
            &s,
            (
                "arm",
                Method::Robot(RobotMethod::GoTo {
                    pose: NamedPose::Work,
                    duration_s: f64::INFINITY
                })
            )
        ),
        Err(WireError::BadArgument(_))
    ));
    assert!(matches!(
        call(
            &c,
            &s,
            (
                "arm",
                Method::Robot(RobotMethod::JacobianInverse {
                    q: None,
                    damping: f64::NAN
                })
            )
        ),
        Err(WireError::BadArgument(_))
    ));
    assert!(matches!(
        call(
            &c,
            &s,
            (
                "arm",
                Method::Robot(RobotMethod::CountsToRadians { counts: vec![1, 2] })
            )
        ),
        Err(WireError::BadArgument(_))
    ));
    assert!(matches!(
        call(
            &c,
            &s,
            (
                "arm",
                Method::Robot(RobotMethod::MapJoints {
                    board: "dmc".into(),
                    joints: vec![JointAxis { joint: 9, axis: 0 }],
                })
            )
        ),
        Err(WireError::BadArgument(_))
    ));
    // Lifecycle refusals.
    assert!(matches!(
        lifecycle(&c, &s, "arm", Transition::Configure),
        Err(WireError::NotReady(_))
    ));
    assert!(matches!(
        lifecycle(&c, &s, "pid", Transition::Activate),
        Err(WireError::InvalidTransition { .. })
    ));
    assert!(matches!(
        lifecycle(&c, &s, "pid", Transition::Configure),
        Err(WireError::NotReady(_))
    ));
    assert!(matches!(
        lifecycle(&c, &s, "arm", Transition::Activate),
        Err(WireError::Unsupported { .. })
    ));
    assert!(matches!(
        ctl(
            &c,
            &s,
            "pid",
            ControllerMethod::SetGains {
                gains: "kp = \"x\"".into()
            }
        ),
        Err(WireError::BadConfig { .. })
    ));
    assert!(matches!(
        ctl(&c, &s, "pid", ControllerMethod::EStop),
        Err(WireError::NotReady(_))
    ));
    assert!(matches!(
        c.call(
            &s,
            Call::Naming(NamingCall::List {
                context: "/".into()
            })
        ),
        Err(WireError::NoNamingService)
    ));
    assert!(matches!(
        c.call(
            &s,
            Call::Subscribe {
                object: "spl".into(),
                decimation: 1
            }
        ),
        Err(WireError::WrongClass { .. })
    ));
    assert!(matches!(
        c.call(&s, Call::Unsubscribe { subscription: 99 }),
        Err(WireError::UnknownName(_))
    ));
    assert!(
        matches!(c.call(&s, Call::Ping { payload: vec![1, 2] }), Ok(Reply::Pong(p)) if p == [1, 2])
    );
}
