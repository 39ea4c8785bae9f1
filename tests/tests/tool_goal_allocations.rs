//! A joint law following a tool-space trajectory allocates nothing: the communication task's
//! inverse kinematics (nearest branch, velocity from the previous solution) and the control
//! task, built by the creator exactly as `activate` builds them and stepped on a simulated clock
//! over a spline of tool waypoints for 30,000 control ticks.
//!
//! The counting allocator counts every allocation of the process, so this binary holds this one
//! test only.

use penelope_hal::{Timestamp, Transition};
use penelope_rt_core::safety::SafetyState;
use penelope_supervisor::objects::{Creator, CreatorConfig};
use penelope_supervisor::proto::{ControllerMethod, JointAxis, Method, Reply, RobotMethod};
use penelope_tests::{CountingAllocator, allocations};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

fn call(c: &Creator, object: &str, method: Method) -> Reply {
    c.call_object(object, method)
        .unwrap_or_else(|e| panic!("{object}: {e}"))
}

#[test]
fn thirty_thousand_ticks_toward_tool_goals_allocate_nothing() {
    let mut config = CreatorConfig::new("alloc");
    config.rt.priority = None;
    let c = Creator::new(config);
    c.create("robot/puma560", "arm", "").unwrap();
    c.create("board/sim", "sim", "").unwrap();
    call(
        &c,
        "arm",
        Method::Robot(RobotMethod::MapJoints {
            board: "sim".into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    call(&c, "sim", Method::Transition(Transition::Configure));
    call(&c, "arm", Method::Transition(Transition::Configure));
    let p = match call(
        &c,
        "arm",
        Method::Robot(RobotMethod::ForwardKinematics { q: None }),
    ) {
        Reply::Pose(p) => p.position,
        other => panic!("fk answered {other:?}"),
    };
    // A square of 4 cm in the tool's y-z plane, back and forth, every second a corner.
    let mut waypoints = String::new();
    for (i, (dy, dz)) in [(0.04, 0.0), (0.04, -0.04), (0.0, -0.04), (0.0, 0.0)]
        .iter()
        .cycle()
        .take(12)
        .enumerate()
    {
        waypoints.push_str(&format!(
            "[[waypoints]]\nat_s = {}\nposition = [{}, {}, {}]\n",
            i + 1,
            p[0],
            p[1] + dy,
            p[2] + dz
        ));
    }
    c.create("trajectory/spline", "square", &waypoints).unwrap();
    c.create("controller/joint-pid", "pid", "").unwrap();
    for m in [
        ControllerMethod::SetRobot {
            robot: "arm".into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: "square".into(),
        },
    ] {
        call(&c, "pid", Method::Controller(m));
    }
    call(&c, "square", Method::Transition(Transition::Configure));
    call(&c, "pid", Method::Transition(Transition::Configure));
    let mut d = c.detach_loop("pid").expect("the loop builds");
    let mut step = |i: u64| {
        let now = Timestamp::from_nanos((i + 1) * 1_000_000);
        if i.is_multiple_of(2) {
            d.comm.tick(now);
        }
        d.control.tick(now);
        while d.telemetry.pop().is_some() {}
    };
    for i in 0..1000 {
        step(i);
    }
    let before = allocations();
    for i in 1000..31_000 {
        step(i);
    }
    let after = allocations();
    assert_eq!(
        after - before,
        0,
        "allocated or freed {} times",
        after - before
    );
    let last = *d.control.control_loop().last_sample();
    assert_eq!(last.state, SafetyState::Running, "fault: {:?}", last.fault);
    assert_eq!(d.comm.ik_failures(), 0);
    assert!(d.comm.published() > 14_000);
}
