//! A node drives a PUMA 200 through a `board/galil` object on the Galil DMC emulator (a
//! pseudo-terminal, as a serial port): the board opens at configure, the robot reads its joints
//! from the encoders, a joint-position law sends targets to the board's own servo over the serial
//! link (goWork reaches the work pose), the amplifiers follow the lifecycle, and a cable pulled
//! mid-run faults the loop with a typed cause while the node keeps answering. An unreachable
//! device is a typed error at configure.
//!
//! With the emulator's axes driving the PUMA 200's rigid-body plant (gravity included), a joint
//! PID with gravity compensation on the node, started away from its target, converges on the
//! arm itself (torque signs from the model: the waist and elbow gears are negative), and a cable
//! pulled then leaves the motors off within the board's watchdog time.

use std::thread;
use std::time::{Duration, Instant};

use penelope_drivers::galil::DEFAULT_WATCHDOG;
use penelope_drivers::galil::emulator::{ArmConfig, DmcConfig, PtyEmulator, PtyOptions};
use penelope_hal::{JointVector, NamedPose};
use penelope_protocol::client::{
    BoardProxy, Client, ControllerProxy, Lifecycle, NodeProxy, RobotProxy,
};
use penelope_protocol::net::conn::{ClientConfig, RpcError};
use penelope_protocol::proto::{CallError, WireError};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};

/// Polls `done` every 10 ms until it holds; fails with `what` after `limit` (a bound on a
/// machine that stalls, not the expected time).
fn wait_for(what: &str, limit: Duration, mut done: impl FnMut() -> bool) {
    let end = Instant::now() + limit;
    while !done() {
        assert!(Instant::now() < end, "{what}: not within {limit:?}");
        thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn a_node_drives_a_puma200_through_the_emulated_galil() {
    let emulator = PtyEmulator::spawn(PtyOptions::default()).expect("a pseudo-terminal");
    let node = Node::start(NodeConfig::new("lab", NamingChoice::Host)).unwrap();
    let client = Client::connect(node.address(), ClientConfig::admin("test")).unwrap();
    let lab = client.node("lab").unwrap();

    a_missing_device_is_a_typed_error_and_leaves_the_object_usable(&lab);

    let (board, robot, start) = a_puma200_on_the_emulated_dmc(&lab, &emulator);

    lab.create(
        "trajectory/spline",
        "hold",
        "[[waypoints]]\nat_s = 0.5\npose = \"start\"\n",
    )
    .unwrap();
    client
        .object("/lab/trajectories/hold")
        .unwrap()
        .configure()
        .unwrap();
    a_torque_loop_holds_the_arm_then_the_dmc_servo_does(&lab, &board, &robot, start);

    let servo = the_board_servo_takes_the_arm_to_work(&lab, &board, &robot, start);

    // The cable is pulled: the loop faults with a typed cause, the node keeps answering.
    emulator.unplug();
    wait_for("a fault after the unplug", Duration::from_secs(30), || {
        servo
            .status()
            .is_ok_and(|s| s.last.as_ref().is_some_and(|t| t.fault.is_some()))
    });
    let faulted = servo.status().unwrap();
    println!("after the unplug: {faulted:?}");
    assert!(
        faulted.last.as_ref().is_some_and(|s| s.fault.is_some()),
        "{faulted:?}"
    );
    assert!(lab.info().is_ok());

    servo.deactivate().unwrap();
    lab.destroy("dmc", true).unwrap();
    node.shutdown();
}

/// A device that is not there is a typed error at configure, and the object stays usable
/// (destroyed again here).
fn a_missing_device_is_a_typed_error_and_leaves_the_object_usable(lab: &NodeProxy) {
    let missing: BoardProxy = lab
        .create_as(
            "board/galil",
            "nowhere",
            "device = \"/dev/penelope-no-such-tty\"",
        )
        .unwrap();
    assert!(matches!(
        missing.configure(),
        Err(RpcError::Remote(WireError::Call(CallError::Device(_))))
    ));
    lab.destroy("nowhere", false).unwrap();
}

/// The board on the emulator's line and a PUMA 200 mapped onto its six axes, configured; the
/// joints read through the robot's scaling from its `start`. Returns them and `start`.
fn a_puma200_on_the_emulated_dmc(
    lab: &NodeProxy,
    emulator: &PtyEmulator,
) -> (BoardProxy, RobotProxy, JointVector) {
    // The board's watchdog at its longest: this test drives the arm; the watchdog's own test
    // is the next one, and a loaded test machine that stalls the node's loop for 30 ms is not
    // what this one judges.
    let board: BoardProxy = lab
        .create_as(
            "board/galil",
            "dmc",
            &format!(
                "device = \"{}\"\nwatchdog_ms = 1000",
                emulator.path().display()
            ),
        )
        .unwrap();
    board.configure().unwrap();
    assert_eq!(board.axis_count().unwrap(), 6);
    assert_eq!(board.read_encoders().unwrap().len(), 6);
    assert!(!board.amplifiers_enabled().unwrap());

    let robot: RobotProxy = lab.create_as("robot/puma200", "slave", "").unwrap();
    robot
        .map_joints("dmc", &(0..6).map(|j| (j, j)).collect::<Vec<_>>())
        .unwrap();
    robot.configure().unwrap();
    // The joints are the encoders through the robot's scaling, from the pose where the
    // encoders read zero (the robot's `start`, where the arm is parked at power-up).
    let counts = board.read_encoders().unwrap();
    let start = robot.named_pose(NamedPose::Start).unwrap();
    let from_counts = start + robot.counts_to_radians(&counts).unwrap();
    let q = robot.joint_positions().unwrap();
    assert!((q - from_counts).norm() < 1e-9, "{q:?} vs {from_counts:?}");
    (board, robot, start)
}

/// A torque loop holds the arm where it is; deactivated, the DMC's own servo holds it,
/// amplifiers on.
fn a_torque_loop_holds_the_arm_then_the_dmc_servo_does(
    lab: &NodeProxy,
    board: &BoardProxy,
    robot: &RobotProxy,
    start: JointVector,
) {
    // A torque loop first: it holds the arm where it is (the emulated axes are bare motors with
    // no gravity to compensate). Then the same board in position mode must servo again.
    let pid: ControllerProxy = lab
        .create_as(
            "controller/joint-pid",
            "pid",
            "period_us = 10000\nwatchdog_ms = 1000\ngravity_compensation = false\n",
        )
        .unwrap();
    pid.set_robot("slave").unwrap();
    pid.set_trajectory("hold").unwrap();
    pid.configure().unwrap();
    pid.activate().unwrap();
    wait_for("20 torque ticks", Duration::from_secs(30), || {
        pid.status().is_ok_and(|s| s.ticks > 20)
    });
    let torque = pid.status().unwrap();
    assert!(torque.ticks > 20, "{torque:?}");
    assert!(torque.last.as_ref().is_some_and(|s| s.fault.is_none()));
    let held = robot.joint_positions().unwrap();
    assert!((held - start).amax() < 0.01, "{held:?} vs {start:?}");
    // Deactivated, a slave stays where it is: held by the DMC's own servo, amplifiers on.
    pid.deactivate().unwrap();
    assert!(board.amplifiers_enabled().unwrap());
    thread::sleep(Duration::from_millis(300));
    let still = robot.joint_positions().unwrap();
    assert!((still - start).amax() < 0.01, "{still:?} vs {start:?}");
}

/// Joint positions as targets for the board's own servo hold the arm, then take it to `work`;
/// returns the servo controller, running.
fn the_board_servo_takes_the_arm_to_work(
    lab: &NodeProxy,
    board: &BoardProxy,
    robot: &RobotProxy,
    start: JointVector,
) -> ControllerProxy {
    // Joint positions as targets for the board's own servo (the DMC closes the loop): a torque
    // loop over a 115200-baud line (about 100 exchanges per second) cannot hold a PUMA.
    let servo: ControllerProxy = lab
        .create_as(
            "controller/joint-position",
            "servo",
            "period_us = 10000\nwatchdog_ms = 1000\nmax_velocity = 1.0\n",
        )
        .unwrap();
    servo.set_robot("slave").unwrap();
    servo.set_trajectory("hold").unwrap();
    servo.configure().unwrap();
    servo.activate().unwrap();
    wait_for("10 servo ticks", Duration::from_secs(30), || {
        servo.status().is_ok_and(|s| s.ticks > 10)
    });
    let running = servo.status().unwrap();
    assert!(running.running);
    assert!(running.last.as_ref().is_some_and(|s| s.fault.is_none()));
    assert!(board.amplifiers_enabled().unwrap());
    let held = robot.joint_positions().unwrap();
    assert!((held - start).amax() < 0.01, "{held:?} vs {start:?}");
    // goWork through the running servo law: a smooth joint trajectory, targets over the line.
    robot.go_to(NamedPose::Work, 1.0).unwrap();
    let work = robot.named_pose(NamedPose::Work).unwrap();
    let near = || {
        robot
            .joint_positions()
            .is_ok_and(|q| (q - work).amax() < 0.02)
    };
    let end = Instant::now() + Duration::from_secs(30);
    while !near() && Instant::now() < end {
        thread::sleep(Duration::from_millis(10));
    }
    let reached = robot.joint_positions().unwrap();
    println!("the servo reached {reached:?} for work {work:?}");
    assert!(
        (reached - work).amax() < 0.02,
        "{reached:?} vs work {work:?}: {:?}",
        servo.status()
    );
    servo
}

#[test]
fn a_gravity_compensated_joint_pid_on_the_node_converges_on_the_emulated_puma200() {
    let model = penelope_drivers::model::puma200();
    let start = model.named_pose(NamedPose::Start);
    // 0.1 V per N·m at the node (its default), so 10 N·m per volt at the emulated amplifiers.
    // Friction off: a PD with exact gravity compensation then has no stiction band, so it
    // converges on the goal itself (the waist's Coulomb friction through its 60:1 gear would
    // leave up to 0.03 rad).
    let arm_config = ArmConfig {
        friction: false,
        ..ArmConfig::new(model.clone(), start, 10.0)
    };
    let emulator = PtyEmulator::spawn(PtyOptions {
        dmc: DmcConfig {
            arm: Some(arm_config),
            ..DmcConfig::default()
        },
        ..PtyOptions::default()
    })
    .expect("a pseudo-terminal");
    let node = Node::start(NodeConfig::new("lab", NamingChoice::Host)).unwrap();
    let client = Client::connect(node.address(), ClientConfig::admin("test")).unwrap();
    let lab = client.node("lab").unwrap();
    let board: BoardProxy = lab
        .create_as(
            "board/galil",
            "dmc",
            &format!("device = \"{}\"", emulator.path().display()),
        )
        .unwrap();
    board.configure().unwrap();
    let robot: RobotProxy = lab.create_as("robot/puma200", "slave", "").unwrap();
    robot
        .map_joints("dmc", &(0..6).map(|j| (j, j)).collect::<Vec<_>>())
        .unwrap();
    robot.configure().unwrap();

    // A target 0.05 rad away from where the arm is, on every joint.
    let mut goal = start;
    for j in 0..6 {
        goal[j] += if j % 2 == 0 { 0.05 } else { -0.05 };
    }
    let list: Vec<String> = (0..6).map(|j| format!("{:.6}", goal[j])).collect();
    lab.create(
        "trajectory/step",
        "away",
        &format!("goal = [{}]\n", list.join(", ")),
    )
    .unwrap();
    client
        .object("/lab/trajectories/away")
        .unwrap()
        .configure()
        .unwrap();
    let pid: ControllerProxy = lab
        .create_as(
            "controller/joint-pid",
            "pid",
            "period_us = 5000\nwatchdog_ms = 1000\ngravity_compensation = true\n",
        )
        .unwrap();
    pid.set_robot("slave").unwrap();
    pid.set_trajectory("away").unwrap();
    pid.configure().unwrap();
    pid.activate().unwrap();

    the_arm_settles_on_the_goal(&emulator, &pid, goal);

    the_dmc_watchdog_turns_the_motors_off(&emulator);
    assert!(lab.info().is_ok());
    pid.deactivate().unwrap();
    lab.destroy("dmc", true).unwrap();
    node.shutdown();
}

/// The arm itself (the emulator's plant), not the encoders' report of it, settles on the goal
/// and stays there, the PID without fault.
fn the_arm_settles_on_the_goal(emulator: &PtyEmulator, pid: &ControllerProxy, goal: JointVector) {
    let arm = || emulator.inspect(|d| d.arm_joints()).unwrap();
    let end = Instant::now() + Duration::from_secs(20);
    let mut settled_since: Option<Instant> = None;
    loop {
        let error = (arm() - goal).amax();
        if error < 2e-3 {
            let since = *settled_since.get_or_insert_with(Instant::now);
            if since.elapsed() > Duration::from_millis(500) {
                break;
            }
        } else {
            settled_since = None;
        }
        assert!(
            Instant::now() < end,
            "no convergence: arm {:?} vs goal {goal:?}: {:?}",
            arm(),
            pid.status()
        );
        thread::sleep(Duration::from_millis(10));
    }
    let status = pid.status().unwrap();
    assert!(
        status.last.as_ref().is_some_and(|s| s.fault.is_none()),
        "{status:?}"
    );
    println!(
        "joint PID + gravity on the emulated PUMA 200: {:.1e} rad from the goal (started 0.05 \
         away), per joint {:?}",
        (arm() - goal).amax(),
        (arm() - goal).as_slice()
    );
}

/// The cable is pulled while the PID holds the arm against gravity: the DMC's own watchdog
/// turns the motors off (the brakes then hold the arm) within its bound.
fn the_dmc_watchdog_turns_the_motors_off(emulator: &PtyEmulator) {
    emulator.unplug();
    let end = Instant::now() + Duration::from_secs(10);
    while emulator.inspect(|d| (0..6).any(|i| d.axis(i).unwrap().motor_on)) {
        assert!(Instant::now() < end, "the motors stayed on");
        thread::sleep(Duration::from_millis(2));
    }
    let silence = emulator.inspect(|d| {
        (0..6)
            .filter_map(|i| d.axis(i).unwrap().host_silent_at_off)
            .max()
            .unwrap()
    });
    println!(
        "motors off {:.2} ms after the host's last command (watchdog {} ms)",
        silence.as_secs_f64() * 1e3,
        DEFAULT_WATCHDOG.as_millis()
    );
    assert!(silence <= DEFAULT_WATCHDOG, "{silence:?}");
}
