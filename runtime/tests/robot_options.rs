//! A robot's options on a node: the board its joints are on (on a `board/fpga`, the FRHC's FPGA
//! board computes its forward kinematics, Jacobian frames and `J^T F`, for its methods and its
//! loops) and `role` (a master's loop displays zero force when its reference goes stale, with
//! its force caps; a slave holds its pose).

use penelope_hal::{JointVector, Timestamp, Transition};
use penelope_protocol::proto::{
    CallError, ControllerMethod, JointAxis, Method, ObjectInfo, Reply, RobotMethod, WireError,
};
use penelope_rt_core::safety::SafetyState;
use penelope_runtime::objects::{Creator, CreatorConfig};

fn creator() -> Creator {
    let mut config = CreatorConfig::new("options");
    config.rt.priority = None;
    Creator::new(config)
}

fn create(c: &Creator, kind: &str, name: &str, config: &str) -> Result<ObjectInfo, WireError> {
    c.create(kind, name, config).map_err(WireError::from)
}

fn ok(c: &Creator, name: &str, method: Method) -> Reply {
    c.call_object(name, method)
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// An FRHC named `name` on its own board of `board_kind` (`board/sim` or `board/fpga`),
/// configured.
fn frhc(c: &Creator, name: &str, board_kind: &str, config: &str) {
    create(c, "robot/frhc", name, config).unwrap();
    let board = format!("{name}-io");
    create(c, board_kind, &board, "").unwrap();
    ok(
        c,
        name,
        Method::Robot(RobotMethod::MapJoints {
            board: board.clone(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    ok(c, &board, Method::Transition(Transition::Configure));
    ok(c, name, Method::Transition(Transition::Configure));
}

fn tool_position(c: &Creator, robot: &str, q: &[f64]) -> [f64; 3] {
    match ok(
        c,
        robot,
        Method::Robot(RobotMethod::ForwardKinematics {
            q: Some(q.to_vec()),
        }),
    ) {
        Reply::Pose(p) => p.position,
        other => panic!("fk answered {other:?}"),
    }
}

#[test]
fn the_fpga_kinematics_answer_the_robots_methods_within_the_fixed_point_error() {
    let c = creator();
    frhc(&c, "float", "board/sim", "");
    frhc(&c, "fpga", "board/fpga", "");
    let mut largest: f64 = 0.0;
    let mut differs = false;
    for q in [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.3, -0.2, 0.4, 0.1, -0.3, 0.2],
        [-0.5, 0.4, -0.3, 0.6, 0.2, -0.4],
    ] {
        let (a, b) = (
            tool_position(&c, "float", &q),
            tool_position(&c, "fpga", &q),
        );
        for i in 0..3 {
            largest = largest.max((a[i] - b[i]).abs());
            differs |= a[i] != b[i];
        }
    }
    // The fixed-point model is not the float model (so this compares two computations)...
    assert!(differs, "the FPGA model answered exactly the float model");
    // ...and agrees with it to the FPGA path's documented accuracy.
    assert!(
        largest < 1e-4,
        "FPGA and float tool positions differ by {largest} m"
    );

    // Only the FRHC goes on an FPGA board.
    create(&c, "robot/puma560", "arm", "").unwrap();
    let refused = c.call_object(
        "arm",
        Method::Robot(RobotMethod::MapJoints {
            board: "fpga-io".into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    let refused = refused.map_err(WireError::from);
    assert!(
        matches!(&refused, Err(WireError::Call(CallError::BadConfig { message, .. })) if message.contains("FRHC")),
        "{refused:?}"
    );
    // The board chooses the kinematics: the robot has no such key.
    for bad in [
        "kinematics = \"fpga\"",
        "role = \"boss\"",
        "max_force_n = 0",
    ] {
        assert!(
            matches!(
                create(&c, "robot/frhc", "bad", bad),
                Err(WireError::Call(CallError::BadConfig { .. }))
            ),
            "{bad}"
        );
    }
}

/// The efforts a controller on the FRHC commands once its reference has gone stale (the
/// communication task never runs), after 300 control ticks.
fn efforts_without_reference(robot_config: &str) -> (JointVector, SafetyState) {
    let c = creator();
    frhc(&c, "hand", "board/sim", robot_config);
    create(&c, "trajectory/step", "hold", "pose = \"start\"").unwrap();
    create(&c, "controller/joint-pid", "pid", "watchdog_ms = 20").unwrap();
    for m in [
        ControllerMethod::SetRobot {
            robot: "hand".into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: "hold".into(),
        },
    ] {
        ok(&c, "pid", Method::Controller(m));
    }
    ok(&c, "hold", Method::Transition(Transition::Configure));
    ok(&c, "pid", Method::Transition(Transition::Configure));
    let mut detached = c.detach_loop("pid").unwrap();
    let mut last = None;
    for i in 1..=300u64 {
        detached.control.tick(Timestamp::from_nanos(i * 1_000_000));
        while let Some(s) = detached.telemetry.pop().map(|t| t.sample) {
            last = Some(s);
        }
    }
    let last = last.expect("the loop ticked");
    (last.effort, last.state)
}

#[test]
fn a_master_displays_zero_force_on_a_stale_reference_and_a_slave_holds() {
    // The FRHC is a master by default.
    let (effort, state) = efforts_without_reference("");
    assert!(
        matches!(state, SafetyState::Holding | SafetyState::Fault),
        "{state:?}"
    );
    assert!(
        effort.iter().all(|e| *e == 0.0),
        "a master pushed the operator's hand: {effort:?}"
    );
    // Made a slave, the same robot holds its pose against gravity.
    let (effort, state) = efforts_without_reference("role = \"slave\"");
    assert_eq!(state, SafetyState::Holding);
    assert!(
        effort.iter().any(|e| e.abs() > 1e-3),
        "a slave did not hold: {effort:?}"
    );
}
