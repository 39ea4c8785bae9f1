//! `robot/urdf`: a robot from a URDF file on a node. The PUMA 560's URDF on a simulated board
//! answers forward kinematics, the Jacobian and gravity as `robot/puma560` does; the SCARA
//! (3 joints, a prismatic quill) is driven to a joint goal by a joint PID with gravity
//! compensation on its own simulated plant; bad configurations and bad URDFs are refused with
//! messages naming the key or the element.

use penelope_hal::{Timestamp, Transition};
use penelope_protocol::proto::{
    CallError, ControllerMethod, JointAxis, Method, Reply, RobotMethod, WireError,
};
use penelope_runtime::objects::{Creator, CreatorConfig};

fn urdf(file: &str) -> String {
    format!("{}/../drivers/robots/{file}", env!("CARGO_MANIFEST_DIR"))
}

fn creator() -> Creator {
    let mut config = CreatorConfig::new("urdf");
    config.rt.priority = None;
    config.robot_files = vec![
        format!("{}/../drivers/robots", env!("CARGO_MANIFEST_DIR")).into(),
        std::env::temp_dir(),
    ];
    Creator::new(config)
}

fn ok(c: &Creator, name: &str, method: Method) -> Reply {
    c.call_object(name, method)
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Creates `name` of `kind` on its own simulated board of `axes` axes, configured.
fn on_sim_board(c: &Creator, kind: &str, name: &str, config: &str, axes: u8) {
    c.create(kind, name, config).unwrap();
    let board = format!("{name}-io");
    c.create("board/sim", &board, &format!("axes = {axes}"))
        .unwrap();
    ok(
        c,
        name,
        Method::Robot(RobotMethod::MapJoints {
            board: board.clone(),
            joints: (0..axes).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    ok(c, &board, Method::Transition(Transition::Configure));
    ok(c, name, Method::Transition(Transition::Configure));
}

fn numbers(reply: Reply) -> Vec<f64> {
    match reply {
        Reply::Pose(p) => p.position.to_vec(),
        Reply::Joints(j) => j.to_vec(),
        Reply::Matrix(m) => m.data.clone(),
        other => panic!("unexpected reply {other:?}"),
    }
}

fn bad_config(e: impl Into<WireError>) -> String {
    match e.into() {
        WireError::Call(CallError::BadConfig { message, .. }) => message,
        other => panic!("expected BadConfig, got {other:?}"),
    }
}

#[test]
fn robot_urdf_is_listed_with_its_keys() {
    let kinds = penelope_runtime::objects::catalog::all_kinds();
    let info = kinds.iter().find(|k| k.kind == "robot/urdf").unwrap();
    for key in ["file =", "tip =", "base =", "poses =", "start =", "role ="] {
        assert!(
            info.config.contains(key),
            "{key} missing from {}",
            info.config
        );
    }
}

#[test]
fn the_puma_urdf_on_a_sim_board_answers_like_robot_puma560() {
    let c = creator();
    let file = urdf("puma560.urdf");
    // puma560's start pose (the toolbox's nominal qn), given to the URDF robot by `poses`.
    let start = "[0.0, 0.7853981633974483, -3.141592653589793, 0.0, 0.7853981633974483, 0.0]";
    let config = format!("file = {file:?}\nposes = {{ start = {start} }}");
    on_sim_board(&c, "robot/urdf", "u", &config, 6);
    on_sim_board(&c, "robot/puma560", "d", "", 6);
    let q = vec![0.1, 0.7, -2.0, 0.4, 0.5, 0.6];
    let methods = [
        // At the measured joints: both bodies started at the same pose.
        RobotMethod::ForwardKinematics { q: None },
        RobotMethod::ForwardKinematics { q: Some(q.clone()) },
        RobotMethod::Jacobian { q: Some(q.clone()) },
        RobotMethod::Gravity { q: Some(q.clone()) },
        RobotMethod::Gravity { q: None },
    ];
    for m in methods {
        let a = numbers(ok(&c, "u", Method::Robot(m.clone())));
        let b = numbers(ok(&c, "d", Method::Robot(m.clone())));
        assert_eq!(a.len(), b.len(), "{m:?}");
        let e = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(e < 1e-9, "{m:?} differs by {e:e}");
    }
    let zero = RobotMethod::ForwardKinematics {
        q: Some(vec![0.0; 6]),
    };
    match ok(&c, "u", Method::Robot(zero)) {
        // Zero configuration: arm straight up, forearm forward (d3 sideways, a3 + d4 up).
        Reply::Pose(p) => {
            let want = [0.4318 + 0.0203, -0.15005, 0.67183 + 0.4318];
            for (got, want) in p.position.iter().zip(want) {
                assert!((got - want).abs() < 1e-12, "{:?}", p.position);
            }
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_scara_from_urdf_follows_a_joint_goal_on_its_simulated_plant() {
    let c = creator();
    let config = format!("file = {:?}\ntip = \"tool\"", urdf("scara.urdf"));
    on_sim_board(&c, "robot/urdf", "scara", &config, 3);
    let goal = [0.5, -0.4, 0.1];
    c.create(
        "trajectory/ramp",
        "to-goal",
        &format!(
            "goal = [{}, {}, {}]\nduration_s = 1.5",
            goal[0], goal[1], goal[2]
        ),
    )
    .unwrap();
    c.create("controller/joint-pid", "pid", "").unwrap();
    for m in [
        ControllerMethod::SetRobot {
            robot: "scara".into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: "to-goal".into(),
        },
    ] {
        ok(&c, "pid", Method::Controller(m));
    }
    ok(&c, "to-goal", Method::Transition(Transition::Configure));
    ok(&c, "pid", Method::Transition(Transition::Configure));
    let mut d = c.detach_loop("pid").unwrap();
    let mut last = None;
    for i in 1..=3000u64 {
        let now = Timestamp::from_nanos(i * 1_000_000);
        if i % 2 == 1 {
            d.comm.tick(now);
        }
        d.control.tick(now);
        while let Some(s) = d.telemetry.pop().map(|t| t.sample) {
            last = Some(s);
        }
    }
    let sample = last.expect("telemetry");
    assert_eq!(sample.fault, None, "{sample:?}");
    for (j, g) in goal.iter().enumerate() {
        let q = sample.q[j];
        assert!((q - g).abs() < 5e-3, "joint {j} at {q}, goal {g}");
    }
}

#[test]
fn bad_robot_urdf_configurations_are_refused_by_name() {
    let c = creator();
    let msg = bad_config(c.create("robot/urdf", "a", "").unwrap_err());
    assert!(msg.contains("`file`"), "{msg}");
    let msg = bad_config(
        c.create("robot/urdf", "b", "file = \"/nonexistent/arm.urdf\"")
            .unwrap_err(),
    );
    assert!(msg.contains("/nonexistent/arm.urdf"), "{msg}");
    let scara = urdf("scara.urdf");
    let msg = bad_config(
        c.create("robot/urdf", "c", &format!("file = {scara:?}"))
            .unwrap_err(),
    );
    assert!(msg.contains("camera, tool"), "{msg}");
    let msg = bad_config(
        c.create(
            "robot/urdf",
            "d",
            &format!("file = {scara:?}\ntip = \"wrist\""),
        )
        .unwrap_err(),
    );
    assert!(msg.contains("tip link `wrist`"), "{msg}");
    let msg = bad_config(
        c.create("robot/puma560", "e", "tip = \"tool0\"")
            .unwrap_err(),
    );
    assert!(msg.contains("robot/urdf only"), "{msg}");
    let msg = bad_config(
        c.create(
            "robot/urdf",
            "g",
            &format!("file = {scara:?}\ntip = \"tool\"\nposes = {{ start = [0.1, 0.2] }}"),
        )
        .unwrap_err(),
    );
    assert!(msg.contains("pose `start` needs 3 finite values"), "{msg}");

    let dir = std::env::temp_dir().join(format!("penelope-urdf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let floating = dir.join("floating.urdf");
    std::fs::write(
        &floating,
        r#"<robot name="f"><link name="world"/><link name="body"/>
           <joint name="free" type="floating"><parent link="world"/><child link="body"/></joint>
           </robot>"#,
    )
    .unwrap();
    let msg = bad_config(
        c.create(
            "robot/urdf",
            "f",
            &format!("file = {:?}", floating.display().to_string()),
        )
        .unwrap_err(),
    );
    assert!(
        msg.contains("joint `free`") && msg.contains("floating"),
        "{msg}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
