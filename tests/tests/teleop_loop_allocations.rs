//! The teleoperation loops a node builds allocate nothing: both control tasks (the FRHC pushed
//! by the scripted hand under force display, the PUMA 200 under slave tracking against a wall,
//! with its sensor cell) and both communication tasks (the two ends of the channel), built by
//! the creator exactly as `activate` builds them and stepped here on a simulated clock for
//! 100,000 control ticks each.
//!
//! The counting allocator counts every allocation of the process, so this binary holds this one
//! test only.

use penelope_hal::{Frame, Timestamp, Transition, Wrench};
use penelope_rt_core::cell::Stamped;
use penelope_rt_core::safety::SafetyState;
use penelope_supervisor::objects::{Creator, CreatorConfig};
use penelope_supervisor::proto::{ControllerMethod, JointAxis, Method, RobotMethod};
use penelope_tests::{CountingAllocator, allocations};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

fn call(c: &Creator, object: &str, method: Method) {
    c.call_object(object, method)
        .unwrap_or_else(|e| panic!("{object}: {e}"));
}

#[test]
fn a_hundred_thousand_teleoperation_ticks_allocate_nothing() {
    let mut config = CreatorConfig::new("alloc");
    config.rt.priority = None;
    let c = Creator::new(config);
    let wall = "[[shapes]]\nkind = \"plane\"\npoint = [0, 0, 0.1]";
    for (kind, name, cfg) in [
        ("robot/frhc", "frhc", ""),
        ("board/sim", "frhc-io", ""),
        ("sensor/operator-hand", "hand", "robot = \"frhc\""),
        ("robot/puma200", "puma", ""),
        ("board/sim", "puma-io", wall),
        ("sensor/virtual", "wrist", wall),
        (
            "trajectory/teleop",
            "link",
            "master = \"frhc\"\nslave = \"puma\"",
        ),
        ("controller/force-display", "display", ""),
        ("controller/slave-tracking", "follow", ""),
    ] {
        c.create(kind, name, cfg)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    for (robot, board) in [("frhc", "frhc-io"), ("puma", "puma-io")] {
        call(
            &c,
            robot,
            Method::Robot(RobotMethod::MapJoints {
                board: board.into(),
                joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
            }),
        );
    }
    for (controller, robot, sensor) in
        [("display", "frhc", None), ("follow", "puma", Some("wrist"))]
    {
        let mut methods = vec![
            ControllerMethod::SetRobot {
                robot: robot.into(),
            },
            ControllerMethod::SetTrajectory {
                trajectory: "link".into(),
            },
        ];
        if let Some(sensor) = sensor {
            methods.push(ControllerMethod::SetSensor {
                sensor: sensor.into(),
            });
        }
        for m in methods {
            call(&c, controller, Method::Controller(m));
        }
    }
    for name in [
        "frhc-io", "puma-io", "wrist", "hand", "frhc", "puma", "link", "display", "follow",
    ] {
        call(&c, name, Method::Transition(Transition::Configure));
    }
    let mut master = c.detach_loop("display").expect("the master's loop builds");
    let mut slave = c.detach_loop("follow").expect("the slave's loop builds");
    let mut wrench = slave.wrench.take().expect("a sensor is bound");
    let mut step = |i: u64| {
        let now = Timestamp::from_nanos((i + 1) * 1_000_000);
        if i.is_multiple_of(2) {
            master.comm.tick(now);
            slave.comm.tick(now);
            // What the sensor feed does each period, without its thread.
            wrench.write(Stamped {
                stamp: now,
                value: Wrench::zero(Frame::Base),
            });
        }
        master.control.tick(now);
        slave.control.tick(now);
        while master.telemetry.pop().is_some() {}
        while slave.telemetry.pop().is_some() {}
    };
    // Warm-up: the first ticks start the channels and anchor the mapping.
    for i in 0..1000 {
        step(i);
    }
    let before = allocations();
    for i in 1000..101_000 {
        step(i);
    }
    let after = allocations();
    assert_eq!(
        after - before,
        0,
        "the teleoperation loops allocated or freed {} times",
        after - before
    );

    for (name, d) in [("master", &master), ("slave", &slave)] {
        let last = *d.control.control_loop().last_sample();
        assert_eq!(last.seq, 101_000, "{name}");
        assert_eq!(
            last.state,
            SafetyState::Running,
            "{name} fault: {:?}",
            last.fault
        );
        assert!(d.comm.published() > 50_000, "{name}");
    }
}
