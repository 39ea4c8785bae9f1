//! Trajectories in operational space: a goal given as a tool position (and orientation) moves
//! the tool in a straight line, under a Cartesian law directly and under a joint law through
//! inverse kinematics in the communication task; a move that cannot take a tool goal says so.

use penelope_hal::{Timestamp, Transition};
use penelope_protocol::proto::{CallError, Method, Reply, RobotMethod, WireError};
use penelope_runtime::objects::{Creator, CreatorConfig};

mod common;
use common::{arm_controller, ok, puma_on_sim_board};

fn tool(c: &Creator, q: Option<Vec<f64>>) -> [f64; 3] {
    match ok(
        c,
        "arm",
        Method::Robot(RobotMethod::ForwardKinematics { q }),
    ) {
        Reply::Pose(p) => p.position,
        other => panic!("fk answered {other:?}"),
    }
}

/// The tool's distance from `goal` after the controller of `law` followed a 1 s ramp of the
/// tool 5 cm forward and 3 cm down (on a simulated clock, 2.5 s), and the largest distance of
/// the tool from the straight line between start and goal on the way.
fn follow(law: &str, law_config: &str) -> (f64, f64) {
    let mut config = CreatorConfig::new("tool");
    config.rt.priority = None;
    let c = puma_on_sim_board(config);
    let start = tool(&c, None);
    let goal = [start[0] + 0.05, start[1], start[2] - 0.03];
    c.create(
        "trajectory/ramp",
        "line",
        &format!(
            "position = [{}, {}, {}]\nduration_s = 1.0",
            goal[0], goal[1], goal[2]
        ),
    )
    .unwrap();
    ok(&c, "line", Method::Transition(Transition::Configure));
    arm_controller(&c, law, "ctl", law_config, "line");
    let mut d = c.detach_loop("ctl").unwrap();
    let mut off_line: f64 = 0.0;
    let mut last = None;
    for i in 1..=2500u64 {
        let now = Timestamp::from_nanos(i * 1_000_000);
        if i % 2 == 1 {
            d.comm.tick(now);
        }
        d.control.tick(now);
        while let Some(s) = d.telemetry.pop().map(|t| t.sample) {
            // Distance from the segment start..goal.
            let p = s.tool_position;
            let (a, b) = (
                nalgebra::Vector3::from(start),
                nalgebra::Vector3::from(goal),
            );
            let t = ((p - a).dot(&(b - a)) / (b - a).norm_squared()).clamp(0.0, 1.0);
            off_line = off_line.max((p - (a + (b - a) * t)).norm());
            last = Some(s);
        }
    }
    let end = last.unwrap().tool_position;
    let error = (end - nalgebra::Vector3::from(goal)).norm();
    assert_eq!(d.comm.ik_failures(), 0);
    (error, off_line)
}

#[test]
fn a_tool_goal_is_reached_in_a_straight_line_by_a_joint_law_and_a_cartesian_one() {
    // The impedance stiffer than its default (2 kN/m), so that joint friction leaves less than
    // 2 mm of the spring stretched at rest.
    for (law, config) in [
        ("controller/joint-pid", ""),
        (
            "controller/cartesian-impedance",
            "stiffness = [20000.0, 20000.0, 20000.0, 200.0, 200.0, 200.0]\n\
             damping = [600.0, 600.0, 600.0, 10.0, 10.0, 10.0]",
        ),
    ] {
        let (error, off_line) = follow(law, config);
        println!(
            "{law}: {:.2} mm from the goal, {:.2} mm off the line",
            error * 1e3,
            off_line * 1e3
        );
        assert!(error < 0.002, "{law}: {:.2} mm from the goal", error * 1e3);
        assert!(
            off_line < 0.005,
            "{law}: {:.2} mm off the line",
            off_line * 1e3
        );
    }
}

#[test]
fn a_trapezoidal_move_refuses_a_tool_goal_and_goals_do_not_mix() {
    let c = Creator::new(CreatorConfig::new("tool"));
    for (kind, config) in [
        ("trajectory/trapezoidal", "position = [0.5, 0.0, 0.5]"),
        (
            "trajectory/step",
            "position = [0.5, 0.0, 0.5]\npose = \"work\"",
        ),
        ("trajectory/step", "rpy_deg = [0.0, 90.0, 0.0]"),
    ] {
        assert!(
            matches!(
                c.create(kind, "t", config).map_err(WireError::from),
                Err(WireError::Call(CallError::BadConfig { .. }))
            ),
            "{kind}: {config}"
        );
    }
}
