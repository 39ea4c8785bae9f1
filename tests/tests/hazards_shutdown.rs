//! Node shutdown and a forced destroy end torque: a node's creator with two
//! torque-driven loops on the real clock, one on a PUMA 200 behind the emulated Galil DMC, one on
//! a simulated PUMA 560; `Creator::shutdown` (what `Node::shutdown` and Ctrl-C run after the
//! server stops) and a forced destroy of an object a running loop uses leave every board with
//! its amplifiers off: the DMC's motors off with a zero offset, the simulated board disabled
//! (zero torque).

use std::time::{Duration, Instant};

use penelope_drivers::galil::emulator::{Dmc, PtyEmulator, PtyOptions};
use penelope_hal::Transition;
use penelope_protocol::proto::{
    BoardMethod, ControllerMethod, JointAxis, Method, Reply, RobotMethod,
};
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_testkit::wait::wait_until;

fn ok(c: &Creator, name: &str, method: Method) -> Reply {
    c.call_object(name, method)
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn amplifiers_on(c: &Creator, board: &str) -> bool {
    match ok(c, board, Method::Board(BoardMethod::AmplifiersEnabled)) {
        Reply::Flag(on) => on,
        other => panic!("{board} answered {other:?}"),
    }
}

const AXES: usize = 6;

fn motors(emu: &PtyEmulator) -> Vec<(bool, f64)> {
    emu.inspect(|d: &Dmc| {
        (0..AXES)
            .filter_map(|i| d.axis(i))
            .map(|a| (a.motor_on, a.offset))
            .collect()
    })
}

/// A torque loop (`controller/joint-pid`) on `robot` (a `kind`) mapped onto `board`, active.
fn torque_loop(c: &Creator, robot: (&str, &str), board: &str, suffix: &str) {
    let (kind, robot) = robot;
    c.create(kind, robot, "").unwrap();
    ok(
        c,
        robot,
        Method::Robot(RobotMethod::MapJoints {
            board: board.into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    let hold = format!("hold-{suffix}");
    let pid = format!("pid-{suffix}");
    c.create("trajectory/step", &hold, "pose = \"start\"")
        .unwrap();
    // 10 ms and a generous reference watchdog: a serial line at 115200 baud carries about a
    // hundred exchanges a second, and a loaded machine is not what this test judges.
    c.create(
        "controller/joint-pid",
        &pid,
        "period_us = 10000\nwatchdog_ms = 1000\ngravity_compensation = false\n",
    )
    .unwrap();
    for name in [board, robot, hold.as_str()] {
        c.transition(name, Transition::Configure).unwrap();
    }
    for m in [
        ControllerMethod::SetRobot {
            robot: robot.into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: hold.clone(),
        },
    ] {
        ok(c, &pid, Method::Controller(m));
    }
    c.transition(&pid, Transition::Configure).unwrap();
    c.transition(&pid, Transition::Activate).unwrap();
}

/// A creator on the real clock with a torque loop on the emulated DMC and one on a simulated
/// board, both running with their amplifiers on.
fn two_torque_loops(emu: &PtyEmulator) -> Creator {
    let mut config = CreatorConfig::new("lab");
    config.rt.priority = None;
    let c = Creator::new(config);
    c.create(
        "board/galil",
        "dmc",
        &format!("device = \"{}\"\nwatchdog_ms = 1000", emu.path().display()),
    )
    .unwrap();
    c.create("board/sim", "sim", "").unwrap();
    torque_loop(&c, ("robot/puma200", "galil-arm"), "dmc", "galil");
    torque_loop(&c, ("robot/puma560", "sim-arm"), "sim", "sim");
    wait_until("both loops running with their amplifiers on", || {
        motors(emu).iter().all(|(on, _)| *on) && amplifiers_on(&c, "sim")
    });
    c
}

#[test]
fn node_shutdown_leaves_every_board_with_its_amplifiers_off() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let c = two_torque_loops(&emu);
    let started = Instant::now();
    c.shutdown();
    let shut = started.elapsed();
    // Every loop stopped, every board idle and off.
    assert!(!amplifiers_on(&c, "sim"), "the simulated board is still on");
    assert!(!amplifiers_on(&c, "dmc"), "the Galil board is still on");
    wait_until("the DMC's motors off", || {
        motors(&emu)
            .iter()
            .all(|(on, offset)| !on && *offset == 0.0)
    });
    let off = started.elapsed();
    println!(
        "shutdown: both loops stopped in {:.1} ms; the DMC's motors off {:.1} ms after it began",
        shut.as_secs_f64() * 1e3,
        off.as_secs_f64() * 1e3
    );
    // Four control periods per loop and the joins, generous for a busy machine.
    assert!(off < Duration::from_secs(5), "{off:?}");
}

#[test]
fn a_forced_destroy_under_running_loops_leaves_their_boards_off() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let c = two_torque_loops(&emu);
    // Refused unless forced: the loops use them.
    assert!(c.destroy("dmc", false).is_err());
    assert!(c.destroy("hold-sim", false).is_err());
    let started = Instant::now();
    // The Galil board itself, and the trajectory the simulated arm's loop follows.
    c.destroy("dmc", true).unwrap();
    wait_until("the DMC's motors off", || {
        motors(&emu)
            .iter()
            .all(|(on, offset)| !on && *offset == 0.0)
    });
    let galil_off = started.elapsed();
    c.destroy("hold-sim", true).unwrap();
    assert!(!amplifiers_on(&c, "sim"), "the simulated board is still on");
    println!(
        "forced destroy: the DMC's motors off {:.1} ms after the destroy began",
        galil_off.as_secs_f64() * 1e3
    );
    assert!(galil_off < Duration::from_secs(5), "{galil_off:?}");
    c.shutdown();
}
