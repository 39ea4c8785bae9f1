//! The CRTK verbs' real-time side allocates nothing: a joint PID's loop built by the creator
//! exactly as `activate` builds it, stepped on a simulated clock for 101,500 control ticks while
//! a servo target arrives every tick (the motion port's cell), a move is pushed every 10,000
//! ticks (the GoTo ring) and cancelled by the next targets, and a stream that stops lets the
//! loop hold and then run on.
//!
//! The counting allocator counts the allocations of this test's thread (where the loops are
//! stepped and the targets written); this binary holds this one test only.

use penelope_hal::{JointVector, NamedPose, Timestamp, Transition};
use penelope_protocol::proto::{Method, Reply, RobotMethod};
use penelope_rt_core::safety::SafetyState;
use penelope_runtime::objects::runtime::{GoToCommand, ServoTarget};
use penelope_testkit::alloc::{CountingAllocator, allocations};
use penelope_tests::arm::{arm_controller, puma_on_sim_board};
use penelope_tests::papers_task::ok;
use std::time::Duration;

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn servo_targets_and_moves_over_100k_ticks_allocate_nothing() {
    let c = puma_on_sim_board("servo");
    c.create("trajectory/step", "hold", "pose = \"start\"")
        .unwrap();
    ok(&c, "hold", Method::Transition(Transition::Configure));
    arm_controller(&c, "controller/joint-pid", "pid", "", "hold");
    let start = match ok(
        &c,
        "arm",
        Method::Robot(RobotMethod::NamedPose {
            pose: NamedPose::Start,
        }),
    ) {
        Reply::Joints(q) => {
            let mut v = JointVector::zeros();
            v.as_mut_slice()[..q.len()].copy_from_slice(&q);
            v
        }
        other => panic!("named pose answered {other:?}"),
    };

    let mut d = c.detach_loop("pid").expect("the loop builds");
    let period_ns = 1_000_000u64;
    let mut holds = 0u64;
    let mut was_holding = false;
    let mut step = |i: u64, d: &mut penelope_runtime::objects::DetachedLoop| {
        let now = Timestamp::from_nanos((i + 1) * period_ns);
        // Every 10,000 ticks a 1 s move, then 2 s later a servo stream for 5 s (which cancels
        // the move if it is still under way) around where the move went, then silence.
        let phase = i % 10_000;
        let offset = 0.02 * (f64::from(u32::try_from(i / 10_000).unwrap_or(0) % 3) - 1.0);
        if phase == 0 {
            let _ = d.goto.push(GoToCommand {
                goal: start.add_scalar(offset),
                duration: Duration::from_secs(1),
            });
            d.motion.move_requested();
        }
        if (2_000..7_000).contains(&phase) {
            let t = (phase - 2_000) as f64 * 1e-3;
            d.motion.servo(ServoTarget {
                q: start.add_scalar(offset + 0.01 * (std::f64::consts::PI * t).sin()),
            });
        }
        if i.is_multiple_of(2) {
            d.comm.tick(now);
        }
        d.control.tick(now);
        while let Some(r) = d.telemetry.pop() {
            let holding = r.sample.state == SafetyState::Holding;
            // (The loop holds once at its start, before its first reference: not counted.)
            if holding && !was_holding && i >= 1000 {
                holds += 1;
            }
            was_holding = holding;
        }
    };
    // Warm-up: the first ticks start the trajectory.
    for i in 0..1000 {
        step(i, &mut d);
    }
    let before = allocations();
    for i in 1000..102_500 {
        step(i, &mut d);
    }
    let after = allocations();
    assert_eq!(
        after - before,
        0,
        "the loop allocated or freed {} times",
        after - before
    );
    let last = *d.control.control_loop().last_sample();
    assert_eq!(last.seq, 102_500);
    assert_eq!(last.state, SafetyState::Running, "fault: {:?}", last.fault);
    // Each stopped stream held the loop once (the watchdog), then it ran on.
    println!("{holds} holds for 10 stopped streams");
    assert_eq!(holds, 10);
    assert!(!d.motion.status().is_busy());
    assert_eq!(d.motion.status().servo_dropped(), 0);
}
