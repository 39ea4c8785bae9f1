//! A joint law following a tool-space trajectory allocates nothing: the communication task's
//! inverse kinematics (nearest branch, velocity from the previous solution) and the control
//! task, built by the creator exactly as `activate` builds them and stepped on a simulated clock
//! over a spline of tool waypoints for 30,000 control ticks. Then the same with the robot's
//! joints split between two laws (`controller/joint-groups`: the PID on the arm following the
//! tool square, a position servo on the wrist following its own spline, new gains for the PID
//! arriving mid-run) for another 30,000.
//!
//! The counting allocator counts the allocations of this test's thread (where the loops are
//! stepped); this binary holds this one test only.

use penelope_hal::{JointVector, Timestamp, Transition};
use penelope_protocol::proto::{Method, Reply, RobotMethod};
use penelope_rt_core::controller::JointPidGains;
use penelope_rt_core::safety::SafetyState;
use penelope_runtime::objects::runtime::{GainsUpdate, RoutedGains};
use penelope_runtime::objects::{Creator, DetachedLoop};
use penelope_testkit::alloc::{CountingAllocator, allocations};
use penelope_tests::arm::{arm_controller, puma_on_sim_board};
use penelope_tests::papers_task::ok;

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

/// A creator with a PUMA 560 `arm` on a simulated board, configured, and the spline `square`:
/// a square of 4 cm in the tool's y-z plane, back and forth, every second a corner.
fn arm_and_square(node: &str) -> Creator {
    let c = puma_on_sim_board(node);
    let p = match ok(
        &c,
        "arm",
        Method::Robot(RobotMethod::ForwardKinematics { q: None }),
    ) {
        Reply::Pose(p) => p.position,
        other => panic!("fk answered {other:?}"),
    };
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
    ok(&c, "square", Method::Transition(Transition::Configure));
    c
}

#[test]
fn thirty_thousand_ticks_toward_tool_goals_allocate_nothing() {
    let c = arm_and_square("alloc");
    arm_controller(&c, "controller/joint-pid", "pid", "", "square");
    let d = c.detach_loop("pid").expect("the loop builds");
    run_counted(d, None);

    // The same PID on joints 0-2 only, a position servo on the wrist.
    let c = arm_and_square("alloc-groups");
    arm_controller(&c, "controller/joint-pid", "pid", "", "square");
    c.create(
        "trajectory/spline",
        "wrist-wave",
        "[[waypoints]]\nat_s = 5.0\nq = [0, 0, 0, 0.3, -0.3, 0.3]\n\
         [[waypoints]]\nat_s = 10.0\nq = [0, 0, 0, -0.3, 0.3, -0.3]\n",
    )
    .unwrap();
    ok(&c, "wrist-wave", Method::Transition(Transition::Configure));
    arm_controller(
        &c,
        "controller/joint-position",
        "servo",
        "max_velocity = 2.0",
        "wrist-wave",
    );
    c.create(
        "controller/joint-groups",
        "split",
        r#"groups = [{ controller = "pid", joints = [0, 1, 2] }, { controller = "servo", joints = [3, 4, 5] }]"#,
    )
    .unwrap();
    ok(&c, "split", Method::Transition(Transition::Configure));
    let d = c.detach_loop("split").expect("the group's loop builds");
    let stiffer = JointPidGains::pd(JointVector::repeat(800.0), JointVector::repeat(40.0));
    run_counted(
        d,
        Some(RoutedGains {
            member: Some(0),
            update: GainsUpdate::Pid(stiffer),
        }),
    );
}

/// Steps a detached loop 1,000 ticks, then counts allocations over 30,000 more (`gains` sent
/// to the loop in the middle); checks that it ran without a fault, published references, and
/// found every inverse kinematics solution.
fn run_counted(mut d: DetachedLoop, gains: Option<RoutedGains>) {
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
    for i in 1000..16_000 {
        step(i);
    }
    if let Some(g) = gains {
        d.gains.push(g).expect("room for new gains");
    }
    for i in 16_000..31_000 {
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
