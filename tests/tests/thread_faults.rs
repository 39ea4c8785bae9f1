//! Thread death is a fault: a control or communication thread of a running loop that panics
//! (injected, as a bug would) stops its robot safely (here a PUMA 560 on a simulated board:
//! zero torque, amplifiers off), the controller shows `error` with the cause, the node keeps
//! answering, and `rearm` brings the loop back from the measured state without a jump.

use penelope_hal::{LifecycleState, Transition};
use penelope_protocol::proto::{
    BoardMethod, CallError, ControllerMethod, JointAxis, Method, ObjectInfo, Reply, RobotMethod,
    WireError,
};
use penelope_runtime::objects::runtime::LoopThread;
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_testkit::wait::wait_until;

fn call(c: &Creator, name: &str, method: Method) -> Result<Reply, WireError> {
    c.call_object(name, method).map_err(WireError::from)
}

fn ok(c: &Creator, name: &str, method: Method) -> Reply {
    call(c, name, method).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn describe(c: &Creator, name: &str) -> ObjectInfo {
    match ok(c, name, Method::Describe) {
        Reply::Object(info) => info,
        other => panic!("describe answered {other:?}"),
    }
}

fn ticks(c: &Creator) -> u64 {
    match ok(c, "pid", Method::Controller(ControllerMethod::Status)) {
        Reply::Status(s) => s.ticks,
        other => panic!("status answered {other:?}"),
    }
}

fn amplifiers_on(c: &Creator) -> bool {
    match ok(c, "sim", Method::Board(BoardMethod::AmplifiersEnabled)) {
        Reply::Flag(f) => f,
        other => panic!("amplifiers answered {other:?}"),
    }
}

/// The largest joint-by-joint difference of two joint vectors, rad.
fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn joints(c: &Creator) -> Vec<f64> {
    match ok(c, "arm", Method::Robot(RobotMethod::JointPositions)) {
        Reply::Joints(q) => q.to_vec(),
        other => panic!("joint positions answered {other:?}"),
    }
}

/// A PUMA 560 on a simulated board held at its start pose by a joint PID, running.
fn running_arm() -> Creator {
    let mut config = CreatorConfig::new("faults");
    config.rt.priority = None;
    let c = Creator::new(config);
    for (kind, name, cfg) in [
        ("robot/puma560", "arm", ""),
        // Brakes, as a real arm has: with its amplifiers off after a fault it stands, not falls.
        ("board/sim", "sim", "brake = true"),
        ("trajectory/step", "hold", "pose = \"start\""),
        ("controller/joint-pid", "pid", ""),
    ] {
        c.create(kind, name, cfg).unwrap();
    }
    ok(
        &c,
        "arm",
        Method::Robot(RobotMethod::MapJoints {
            board: "sim".into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    for name in ["sim", "arm", "hold"] {
        ok(&c, name, Method::Transition(Transition::Configure));
    }
    for m in [
        ControllerMethod::SetRobot {
            robot: "arm".into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: "hold".into(),
        },
    ] {
        ok(&c, "pid", Method::Controller(m));
    }
    ok(&c, "pid", Method::Transition(Transition::Configure));
    ok(&c, "pid", Method::Transition(Transition::Activate));
    wait_until("the loop runs", || ticks(&c) > 200);
    assert!(amplifiers_on(&c));
    c
}

fn fails_safely(thread: LoopThread, cause: &str) {
    let c = running_arm();
    let before = joints(&c);
    c.inject_thread_panic("pid", thread).unwrap();
    wait_until("the controller shows error", || {
        describe(&c, "pid").state == LifecycleState::Error
    });
    let info = describe(&c, "pid");
    let fault = info
        .relations
        .iter()
        .find(|(k, _)| k == "fault")
        .map(|(_, v)| v.clone())
        .expect("the cause is shown");
    assert!(fault.contains(cause), "{fault}");
    // The robot is stopped: amplifiers off, no longer used by a loop, and where it was.
    assert!(!amplifiers_on(&c));
    assert_eq!(describe(&c, "arm").state, LifecycleState::Inactive);
    let after = joints(&c);
    let moved = largest_difference(&before, &after);
    assert!(moved < 0.01, "the arm moved {moved} rad while failing");
    // The node keeps answering, and a failed loop is not re-activated by accident.
    assert_eq!(c.list().len(), 4);
    assert!(matches!(
        call(&c, "pid", Method::Transition(Transition::Activate)),
        Err(WireError::Call(CallError::InvalidTransition { .. }))
    ));

    // Re-armed: running again, from the measured state, without a jump.
    ok(&c, "pid", Method::Controller(ControllerMethod::Rearm));
    assert_eq!(describe(&c, "pid").state, LifecycleState::Active);
    assert!(
        !describe(&c, "pid")
            .relations
            .iter()
            .any(|(k, _)| k == "fault")
    );
    wait_until("the re-armed loop runs", || ticks(&c) > 300);
    assert!(amplifiers_on(&c));
    let rearmed = joints(&c);
    let jump = largest_difference(&after, &rearmed);
    assert!(jump < 0.01, "re-arming moved the arm {jump} rad");
    // Deactivated on purpose, the slave is held by its board's servo where it was.
    ok(&c, "pid", Method::Transition(Transition::Deactivate));
    assert!(amplifiers_on(&c));
    let held = joints(&c);
    let drift = largest_difference(&rearmed, &held);
    assert!(drift < 0.01, "deactivating moved the arm {drift} rad");
}

#[test]
fn a_panicking_control_thread_stops_its_robot_and_rearm_brings_it_back() {
    fails_safely(
        LoopThread::Control,
        "the control thread panicked: injected fault",
    );
}

#[test]
fn a_panicking_communication_thread_stops_its_robot_and_rearm_brings_it_back() {
    fails_safely(
        LoopThread::Communication,
        "the communication thread panicked: injected fault",
    );
}
