//! The per-tick bodies a node runs for an active controller allocate nothing: the control task
//! (board and plant, safety, joint PID, telemetry into the ring and cells, sensor cell) and the
//! communication task (trajectory, reference cell), built by the creator exactly as `activate`
//! builds them, stepped here on a simulated clock without threads.
//!
//! The counting allocator counts the allocations of this test's thread (where the loops are
//! stepped); this binary holds this one test only.

use penelope_hal::{Frame, Timestamp, Transition, Wrench};
use penelope_protocol::proto::{
    Call, ControllerMethod, CreatorCall, JointAxis, Method, RobotMethod,
};
use penelope_protocol::service::{Outbox, Service, Session};
use penelope_rt_core::cell::Stamped;
use penelope_rt_core::safety::SafetyState;
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_testkit::alloc::{CountingAllocator, allocations};
use penelope_tests::call_object;

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn fifty_thousand_node_loop_ticks_allocate_nothing() {
    let mut config = CreatorConfig::new("alloc");
    config.rt.priority = None;
    let c = Creator::new(config);
    a_pid_on_a_puma_with_a_virtual_sensor(&c);

    let mut detached = c.detach_loop("pid").expect("the loop builds");
    let mut wrench = detached.wrench.take().expect("a sensor is bound");
    let period_ns = 1_000_000u64;
    let mut step = |i: u64, d: &mut penelope_runtime::objects::DetachedLoop| {
        let now = Timestamp::from_nanos((i + 1) * period_ns);
        if i.is_multiple_of(2) {
            d.comm.tick(now);
            // What the sensor feed does each period, without its thread.
            wrench.write(Stamped {
                stamp: now,
                value: Wrench::zero(Frame::Base),
            });
        }
        d.control.tick(now);
        while d.telemetry.pop().is_some() {}
        let _ = d.probe.latest();
    };
    // Warm-up: the first ticks start the trajectory.
    for i in 0..1000 {
        step(i, &mut detached);
    }
    let before = allocations();
    for i in 1000..50_000 {
        step(i, &mut detached);
    }
    let after = allocations();
    assert_eq!(
        after - before,
        0,
        "the node loop allocated or freed {} times",
        after - before
    );
    let last = *detached.control.control_loop().last_sample();
    assert_eq!(last.seq, 50_000);
    assert_eq!(last.state, SafetyState::Running, "fault: {:?}", last.fault);
    assert!(detached.comm.published() > 20_000);
}

/// On `c`: a PUMA 560 on a simulated board, a trapezoidal move to `work`, a virtual force
/// sensor, and a joint PID bound to them, all configured.
fn a_pid_on_a_puma_with_a_virtual_sensor(c: &Creator) {
    let (outbox, _rx) = Outbox::bounded(16);
    let s = Session {
        id: 1,
        peer: "127.0.0.1:1".parse().unwrap(),
        client: "test".into(),
        identity: penelope_protocol::service::Identity::IN_PROCESS,
        outbox,
    };
    for (kind, name, cfg) in [
        ("robot/puma560", "arm", ""),
        (
            "board/sim",
            "sim",
            "[[shapes]]\nkind = \"plane\"\npoint = [0, 0, -5]",
        ),
        (
            "trajectory/trapezoidal",
            "move",
            "pose = \"work\"\nmax_velocity = 0.5",
        ),
        ("controller/joint-pid", "pid", ""),
    ] {
        c.call(
            &s,
            Call::Creator(CreatorCall::Create {
                kind: kind.into(),
                name: name.into(),
                config: cfg.into(),
            }),
        )
        .unwrap();
    }
    call_object(
        c,
        "arm",
        Method::Robot(RobotMethod::MapJoints {
            board: "sim".into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    for name in ["sim", "arm", "move"] {
        call_object(c, name, Method::Transition(Transition::Configure));
    }
    call_object(
        c,
        "pid",
        Method::Controller(ControllerMethod::SetRobot {
            robot: "arm".into(),
        }),
    );
    call_object(
        c,
        "pid",
        Method::Controller(ControllerMethod::SetTrajectory {
            trajectory: "move".into(),
        }),
    );
    call_object(
        c,
        "pid",
        Method::Controller(ControllerMethod::SetSensor {
            sensor: "arm-ft".into(),
        }),
    );
    c.call(
        &s,
        Call::Creator(CreatorCall::Create {
            kind: "sensor/virtual".into(),
            name: "arm-ft".into(),
            config: String::new(),
        }),
    )
    .unwrap();
    call_object(c, "arm-ft", Method::Transition(Transition::Configure));
    call_object(c, "pid", Method::Transition(Transition::Configure));
}
