//! Helpers shared by the in-process creator tests (`objects.rs`, `object_control.rs`,
//! `object_sensors.rs`, `robot_crtk_verbs.rs`, `tool_trajectories.rs`): sessions, calls,
//! object set-up and waiting. Each test binary uses a
//! subset, hence `dead_code` is allowed here.

#![allow(dead_code)]

use std::time::{Duration, Instant};

use penelope_hal::Transition;
use penelope_protocol::proto::{
    Call, ControllerMethod, CreatorCall, JointAxis, Method, Reply, RobotMethod, WireError,
};
use penelope_protocol::service::{Outbox, OutboxReceiver, Service, Session};
use penelope_runtime::objects::{Creator, CreatorConfig};

pub fn session(id: u64) -> (Session, OutboxReceiver) {
    let (outbox, rx) = Outbox::bounded(1024);
    (
        Session {
            id,
            peer: "127.0.0.1:40000".parse().unwrap(),
            client: "test".into(),
            identity: penelope_protocol::service::Identity::IN_PROCESS,
            outbox,
        },
        rx,
    )
}

pub fn creator() -> Creator {
    let mut config = CreatorConfig::new("lab");
    config.rt.priority = None;
    Creator::new(config)
}

pub fn call(c: &Creator, s: &Session, method: (&str, Method)) -> Result<Reply, WireError> {
    c.call(
        s,
        Call::Object {
            object: method.0.into(),
            method: method.1,
        },
    )
}

pub fn create(c: &Creator, s: &Session, kind: &str, name: &str, config: &str) {
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

pub fn lifecycle(c: &Creator, s: &Session, name: &str, t: Transition) -> Result<Reply, WireError> {
    call(c, s, (name, Method::Transition(t)))
}

pub fn map(c: &Creator, s: &Session, robot: &str, board: &str, pairs: &[(u8, u8)]) {
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
pub fn try_joints(r: Result<Reply, WireError>) -> Option<Vec<f64>> {
    match r {
        Ok(Reply::Joints(q)) => Some(q),
        _ => None,
    }
}

pub fn joints(r: Result<Reply, WireError>) -> Vec<f64> {
    match r {
        Ok(Reply::Joints(q)) => q,
        other => panic!("expected joints, got {other:?}"),
    }
}

pub fn ctl(c: &Creator, s: &Session, name: &str, m: ControllerMethod) -> Result<Reply, WireError> {
    call(c, s, (name, Method::Controller(m)))
}

/// A PUMA 560 named `robot` on two simulated boards (joints 0-2 on `b1` axes 0-2, joints 3-5
/// on `b2` axes 0-2), a joint PID `pid` following the trajectory `traj`.
pub fn puma_on_two_boards(c: &Creator, s: &Session, traj_kind: &str, traj_cfg: &str) {
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

pub fn max_error(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

pub fn wait_for(what: &str, timeout: Duration, mut ok: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !ok() {
        assert!(t0.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Calls `method` on `name` in process (no session), panicking with the reason on an error.
pub fn ok(c: &Creator, name: &str, method: Method) -> Reply {
    c.call_object(name, method)
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// A creator made with `config` holding a PUMA 560 `arm` on a simulated board `sim` (joint j
/// on axis j), both configured.
pub fn puma_on_sim_board(config: CreatorConfig) -> Creator {
    let c = Creator::new(config);
    c.create("robot/puma560", "arm", "").unwrap();
    c.create("board/sim", "sim", "").unwrap();
    ok(
        &c,
        "arm",
        Method::Robot(RobotMethod::MapJoints {
            board: "sim".into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    ok(&c, "sim", Method::Transition(Transition::Configure));
    ok(&c, "arm", Method::Transition(Transition::Configure));
    c
}

/// Creates controller `name` of `kind` (its keys `config`) driving `arm` along `trajectory`
/// (configured already), and configures it.
pub fn arm_controller(c: &Creator, kind: &str, name: &str, config: &str, trajectory: &str) {
    c.create(kind, name, config).unwrap();
    for m in [
        ControllerMethod::SetRobot {
            robot: "arm".into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: trajectory.into(),
        },
    ] {
        ok(c, name, Method::Controller(m));
    }
    ok(c, name, Method::Transition(Transition::Configure));
}
