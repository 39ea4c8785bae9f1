//! The creator in-process (no network): kinds, axis conflicts and typed errors. A PUMA 560 on
//! two simulated boards driven by its loops (and the destroy rules) is in `object_control.rs`,
//! the force sensors in `object_sensors.rs`; the helpers they share in `common/`.

use penelope_hal::{NamedPose, Transition};
use penelope_protocol::proto::{
    BoardMethod, Call, CallError, Class, ControllerMethod, CreatorCall, JointAxis, Method,
    NamingCall, Reply, RobotMethod, TrajectoryMethod, WireError,
};
use penelope_protocol::service::{Service, Session};
use penelope_runtime::objects::{Creator, CreatorConfig};

mod common;

use common::*;

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
        Err(WireError::Call(CallError::InUse { name, dependents })) => {
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
        Err(WireError::Call(CallError::InUse { .. }))
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
    creation_refusals(&c, &s);
    robot_query_refusals(&c, &s);
    robot_command_refusals(&c, &s);
    lifecycle_and_call_refusals(&c, &s);
}

/// Unknown kinds, bad names and configurations, a taken name, an unreachable board, a NaN
/// time and the creator's limit; leaves `arm` (a PUMA 560, unconfigured), `dmc` (a Galil that
/// failed to configure), `spl` (a spline) and `pid` (a joint PID), the limit of four.
fn creation_refusals(c: &Creator, s: &Session) {
    let creator_call = |cc: CreatorCall| c.call(s, Call::Creator(cc));
    let mk = |kind: &str, name: &str, config: &str| {
        creator_call(CreatorCall::Create {
            kind: kind.into(),
            name: name.into(),
            config: config.into(),
        })
    };
    assert!(matches!(
        mk("robot/r2d2", "x", ""),
        Err(WireError::Call(CallError::UnknownKind(_)))
    ));
    assert!(matches!(
        mk("robot/puma560", "a/b", ""),
        Err(WireError::Call(CallError::BadName { .. }))
    ));
    assert!(matches!(
        mk("robot/puma560", "x", "colour = \"red\""),
        Err(WireError::Call(CallError::BadConfig { .. }))
    ));
    assert!(matches!(
        mk("trajectory/ramp", "x", "duration_s = -2"),
        Err(WireError::Call(CallError::BadConfig { .. }))
    ));
    assert!(matches!(
        mk("controller/joint-pid", "x", "period_us = 5"),
        Err(WireError::Call(CallError::BadConfig { .. }))
    ));
    mk("robot/puma560", "arm", "").unwrap();
    assert!(matches!(
        mk("robot/puma560", "arm", ""),
        Err(WireError::Call(CallError::NameTaken(_)))
    ));
    mk(
        "board/galil",
        "dmc",
        "address = \"127.0.0.1:1\"\nconnect_timeout_ms = 200",
    )
    .unwrap();
    assert!(matches!(
        lifecycle(c, s, "dmc", Transition::Configure),
        Err(WireError::Call(CallError::Device(_)))
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
            c,
            s,
            (
                "spl",
                Method::Trajectory(TrajectoryMethod::Reference { t_s: 1.0 })
            )
        ),
        Ok(Reply::Reference(_))
    ));
    assert!(matches!(
        call(
            c,
            s,
            (
                "spl",
                Method::Trajectory(TrajectoryMethod::Reference { t_s: f64::NAN })
            )
        ),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    mk("controller/joint-pid", "pid", "").unwrap();
    assert!(matches!(
        mk("robot/puma200", "one-too-many", ""),
        Err(WireError::Call(CallError::LimitReached { limit: 4, .. }))
    ));
}

/// A robot's queries with bad arguments, before it is configured, of another class, or of
/// no object at all.
fn robot_query_refusals(c: &Creator, s: &Session) {
    let fk = |q: Vec<f64>| {
        call(
            c,
            s,
            (
                "arm",
                Method::Robot(RobotMethod::ForwardKinematics { q: Some(q) }),
            ),
        )
    };
    assert!(matches!(fk(vec![0.0; 6]), Ok(Reply::Pose(_))));
    assert!(matches!(
        fk(vec![0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    assert!(matches!(
        fk(vec![0.0; 5]),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    assert!(matches!(
        call(c, s, ("arm", Method::Robot(RobotMethod::JointPositions))),
        Err(WireError::Call(CallError::NotReady(_)))
    ));
    assert!(matches!(
        call(c, s, ("arm", Method::Board(BoardMethod::AxisCount))),
        Err(WireError::Call(CallError::WrongClass {
            expected: Class::Board,
            found: Class::Robot,
            ..
        }))
    ));
    assert!(matches!(
        call(c, s, ("ghost", Method::Describe)),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
}

/// A robot's motions and conversions with bad arguments or before it is configured.
fn robot_command_refusals(c: &Creator, s: &Session) {
    assert!(matches!(
        call(
            c,
            s,
            (
                "arm",
                Method::Robot(RobotMethod::GoTo {
                    pose: NamedPose::Work,
                    duration_s: 1.0
                })
            )
        ),
        Err(WireError::Call(CallError::NotReady(_)))
    ));
    assert!(matches!(
        call(
            c,
            s,
            (
                "arm",
                Method::Robot(RobotMethod::GoTo {
                    pose: NamedPose::Work,
                    duration_s: f64::INFINITY
                })
            )
        ),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    assert!(matches!(
        call(
            c,
            s,
            (
                "arm",
                Method::Robot(RobotMethod::JacobianInverse {
                    q: None,
                    damping: f64::NAN
                })
            )
        ),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    assert!(matches!(
        call(
            c,
            s,
            (
                "arm",
                Method::Robot(RobotMethod::CountsToRadians { counts: vec![1, 2] })
            )
        ),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    assert!(matches!(
        call(
            c,
            s,
            (
                "arm",
                Method::Robot(RobotMethod::MapJoints {
                    board: "dmc".into(),
                    joints: vec![JointAxis { joint: 9, axis: 0 }],
                })
            )
        ),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
}

/// Transitions the lifecycle refuses, controller calls before they can run, and calls of the
/// session (naming, subscriptions, ping).
fn lifecycle_and_call_refusals(c: &Creator, s: &Session) {
    assert!(matches!(
        lifecycle(c, s, "arm", Transition::Configure),
        Err(WireError::Call(CallError::NotReady(_)))
    ));
    assert!(matches!(
        lifecycle(c, s, "pid", Transition::Activate),
        Err(WireError::Call(CallError::InvalidTransition { .. }))
    ));
    assert!(matches!(
        lifecycle(c, s, "pid", Transition::Configure),
        Err(WireError::Call(CallError::NotReady(_)))
    ));
    assert!(matches!(
        lifecycle(c, s, "arm", Transition::Activate),
        Err(WireError::Call(CallError::Unsupported { .. }))
    ));
    assert!(matches!(
        ctl(
            c,
            s,
            "pid",
            ControllerMethod::SetGains {
                gains: "kp = \"x\"".into()
            }
        ),
        Err(WireError::Call(CallError::BadConfig { .. }))
    ));
    assert!(matches!(
        ctl(c, s, "pid", ControllerMethod::EStop),
        Err(WireError::Call(CallError::NotReady(_)))
    ));
    assert!(matches!(
        c.call(
            s,
            Call::Naming(NamingCall::List {
                context: "/".into()
            })
        ),
        Err(WireError::Call(CallError::NoNamingService))
    ));
    assert!(matches!(
        c.call(
            s,
            Call::Subscribe {
                object: "spl".into(),
                decimation: 1
            }
        ),
        Err(WireError::Call(CallError::WrongClass { .. }))
    ));
    assert!(matches!(
        c.call(s, Call::Unsubscribe { subscription: 99 }),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    assert!(
        matches!(c.call(s, Call::Ping { payload: vec![1, 2] }), Ok(Reply::Pong(p)) if p == [1, 2])
    );
}

#[test]
fn a_channel_says_its_mapping() {
    let c = creator();
    let (s, _rx) = session(1);
    create(
        &c,
        &s,
        "trajectory/teleop",
        "link",
        "master = \"frhc\"\nslave = \"puma\"\nscale = 2.0\nforce_gain = 0.25\ntorque_gain = 0.75\n\
         rotation_rpy_deg = [0.0, 0.0, 90.0]",
    );
    let Ok(Reply::Object(info)) = call(&c, &s, ("link", Method::Describe)) else {
        panic!("describe of a channel");
    };
    let mapping = info.relations.iter().find(|(k, _)| k == "mapping");
    assert_eq!(
        mapping.map(|(_, v)| v.as_str()),
        Some("scale 2 force_gain 0.25 torque_gain 0.75 rotation_rpy_deg 0 0 90"),
        "{:?}",
        info.relations
    );
}
