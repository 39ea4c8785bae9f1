//! `controller/joint-groups`: a joint PID on a PUMA 560's arm and a position servo on its wrist,
//! each following its own trajectory, in one loop on a simulated board and a simulated clock
//! (the paper's "a set of joints can be controlled with a joint-based algorithm and the
//! remaining joints with a different algorithm").

use std::time::Duration;

use penelope_hal::{LifecycleState, Transition};
use penelope_protocol::proto::{
    Call, CallError, ControllerMethod, Method, Reply, RobotMethod, WireError,
};
use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::system::{SystemFile, SystemFileError};

/// The arm's goal (its trajectory gives goals for every joint; the group takes joints 0-2).
const ARM_GOAL: [f64; 6] = [0.3, 0.5, -2.6, 0.9, 0.9, 0.9];
/// The wrist's goal (joints 3-5 taken).
const WRIST_GOAL: [f64; 6] = [-0.9, -0.9, -0.9, 0.4, -0.3, 0.5];

fn system(groups: &str) -> String {
    let q = |v: [f64; 6]| format!("{v:?}");
    format!(
        r#"
[boards.io]
kind = "sim"

[robots.puma]
kind = "puma560"
start = "start"
joints = [{{ board = "io", joints = [0, 1, 2, 3, 4, 5] }}]

[trajectories.arm-move]
kind = "trapezoidal"
goal = {arm}
max_velocity = 0.5
max_acceleration = 2.0

[trajectories.wrist-move]
kind = "spline"
waypoints = [{{ at_s = 1.0, q = {wrist} }}]

[controllers.arm]
kind = "joint-pid"
robot = "puma"
trajectory = "arm-move"
ki = 200.0
integral_limit = 20.0

[controllers.wrist]
kind = "joint-position"
robot = "puma"
trajectory = "wrist-move"
max_velocity = 3.0

[controllers.split]
kind = "joint-groups"
groups = {groups}
"#,
        arm = q(ARM_GOAL),
        wrist = q(WRIST_GOAL),
    )
}

const SPLIT: &str =
    r#"[{ controller = "arm", joints = [0, 1, 2] }, { controller = "wrist", joints = [3, 4, 5] }]"#;

fn node() -> Node {
    let mut config = NodeConfig::new("lab", NamingChoice::None);
    config.creator.rt.priority = None;
    config.creator.clock = ClockMode::Simulated;
    Node::start(config).unwrap()
}

fn call(node: &Node, object: &str, method: Method) -> Result<Reply, WireError> {
    node.call(Call::Object {
        object: object.into(),
        method,
    })
}

fn joints(node: &Node) -> Vec<f64> {
    match call(node, "puma", Method::Robot(RobotMethod::JointPositions)) {
        Ok(Reply::Joints(q)) => q.to_vec(),
        other => panic!("{other:?}"),
    }
}

fn state(node: &Node, name: &str) -> LifecycleState {
    node.creator().info(name).unwrap().state
}

#[test]
fn a_pid_on_the_arm_and_a_servo_on_the_wrist_reach_their_own_goals() {
    let node = node();
    SystemFile::parse(&system(SPLIT))
        .unwrap()
        .apply(&node)
        .expect("the system comes up");
    // The group runs; its members run inside it, not on their own.
    for name in ["split", "arm", "wrist", "puma"] {
        assert_eq!(state(&node, name), LifecycleState::Active, "{name}");
    }
    let relations = node.creator().info("split").unwrap().relations;
    for member in ["arm [0 1 2]", "wrist [3 4 5]"] {
        assert!(
            relations.contains(&("member".to_string(), member.to_string())),
            "{relations:?}"
        );
    }
    assert!(relations.contains(&("robot".to_string(), "puma".to_string())));
    node.creator().advance(Duration::from_secs(4)).unwrap();
    let q = joints(&node);
    for j in 0..3 {
        assert!(
            (q[j] - ARM_GOAL[j]).abs() < 5e-3,
            "arm joint {j}: {} vs its goal {}",
            q[j],
            ARM_GOAL[j]
        );
    }
    for j in 3..6 {
        assert!(
            (q[j] - WRIST_GOAL[j]).abs() < 5e-3,
            "wrist joint {j}: {} vs its goal {}",
            q[j],
            WRIST_GOAL[j]
        );
    }

    // A member's new gains reach the running group: no stiffness and no gravity compensation
    // on the arm, and its shoulder and elbow sag while the wrist's servo still holds.
    let limp = "kp = 0.0\nkd = 2.0\nki = 0.0\ngravity_compensation = false";
    call(
        &node,
        "arm",
        Method::Controller(ControllerMethod::SetGains { gains: limp.into() }),
    )
    .unwrap();
    node.creator().advance(Duration::from_millis(500)).unwrap();
    let sagged = joints(&node);
    let sag = (1..3)
        .map(|j| (sagged[j] - ARM_GOAL[j]).abs())
        .fold(0.0, f64::max);
    assert!(sag > 0.05, "the arm should sag without gains: {sagged:?}");
    for j in 3..6 {
        assert!(
            (sagged[j] - WRIST_GOAL[j]).abs() < 5e-3,
            "the wrist is held by its servo, joint {j}: {}",
            sagged[j]
        );
    }
    // The group itself has no gains of its own.
    assert!(matches!(
        call(
            &node,
            "split",
            Method::Controller(ControllerMethod::SetGains {
                gains: "kp = 1.0".into()
            })
        ),
        Err(WireError::Call(CallError::Unsupported { .. }))
    ));

    // Deactivated, the group hands everything back; a member can then run alone.
    call(&node, "split", Method::Transition(Transition::Deactivate)).unwrap();
    for name in ["split", "arm", "wrist", "puma"] {
        assert_eq!(state(&node, name), LifecycleState::Inactive, "{name}");
    }
    call(&node, "arm", Method::Transition(Transition::Activate)).unwrap();
    assert_eq!(state(&node, "arm"), LifecycleState::Active);
    node.shutdown();
}

#[test]
fn overlapping_or_missing_joints_are_refused_naming_the_joint() {
    let node = node();
    let overlap = r#"[{ controller = "arm", joints = [0, 1, 2, 3] }, { controller = "wrist", joints = [3, 4, 5] }]"#;
    match SystemFile::parse(&system(overlap)).unwrap().apply(&node) {
        Err(SystemFileError::Step { key, error, .. }) => {
            assert_eq!(key, "controllers.split");
            assert!(
                matches!(&error, WireError::Call(CallError::BadConfig { message, .. })
                    if message.contains("joint 3 is in groups 0 and 1")),
                "{error}"
            );
        }
        other => panic!("{other:?}"),
    }
    let missing = r#"[{ controller = "arm", joints = [0, 1, 2] }, { controller = "wrist", joints = [3, 4] }]"#;
    match SystemFile::parse(&system(missing)).unwrap().apply(&node) {
        Err(SystemFileError::Step {
            key, step, error, ..
        }) => {
            assert_eq!(
                (key.as_str(), step.as_str()),
                ("controllers.split", "activate")
            );
            assert!(
                matches!(&error, WireError::Call(CallError::BadConfig { message, .. })
                    if message.contains("no group drives joint 5")),
                "{error}"
            );
        }
        other => panic!("{other:?}"),
    }
    let stranger = r#"[{ controller = "arm", joints = [0, 1, 2] }, { controller = "nobody", joints = [3, 4, 5] }]"#;
    match SystemFile::parse(&system(stranger)).unwrap().apply(&node) {
        Err(SystemFileError::Step { error, .. }) => {
            assert!(
                matches!(error, WireError::Call(CallError::UnknownName(ref n)) if n == "nobody"),
                "{error:?}"
            );
        }
        other => panic!("{other:?}"),
    }
    // Nothing half-made is left behind.
    assert!(node.creator().list().is_empty());
    node.shutdown();
}
