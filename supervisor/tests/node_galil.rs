//! A node drives a PUMA 200 through a `board/galil` object on the Galil DMC emulator (a
//! pseudo-terminal, as a serial port): the board opens at configure, the robot reads its joints
//! from the encoders, a joint-position law sends targets to the board's own servo over the serial
//! link (goWork reaches the work pose), the amplifiers follow the lifecycle, and a cable pulled
//! mid-run faults the loop with a typed cause while the node keeps answering. An unreachable
//! device is a typed error at configure.

use std::thread;
use std::time::Duration;

use penelope_drivers::galil::emulator::{PtyEmulator, PtyOptions};
use penelope_hal::NamedPose;
use penelope_supervisor::client::{BoardProxy, Client, ControllerProxy, Lifecycle, RobotProxy};
use penelope_supervisor::net::conn::{ClientConfig, RpcError};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::proto::WireError;

#[test]
fn a_node_drives_a_puma200_through_the_emulated_galil() {
    let emulator = PtyEmulator::spawn(PtyOptions::default()).expect("a pseudo-terminal");
    let node = Node::start(NodeConfig::new("lab", NamingChoice::Host)).unwrap();
    let client = Client::connect(node.address(), ClientConfig::new("test")).unwrap();
    let lab = client.node("lab").unwrap();

    // A device that is not there is a typed error at configure, and the object stays usable.
    let missing: BoardProxy = lab
        .create_as(
            "board/galil",
            "nowhere",
            "device = \"/dev/penelope-no-such-tty\"",
        )
        .unwrap();
    assert!(matches!(
        missing.configure(),
        Err(RpcError::Remote(WireError::Device(_)))
    ));
    lab.destroy("nowhere", false).unwrap();

    let board: BoardProxy = lab
        .create_as(
            "board/galil",
            "dmc",
            &format!("device = \"{}\"", emulator.path().display()),
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
    thread::sleep(Duration::from_millis(800));
    let torque = pid.status().unwrap();
    assert!(torque.ticks > 20, "{torque:?}");
    assert!(torque.last.as_ref().is_some_and(|s| s.fault.is_none()));
    let held = robot.joint_positions().unwrap();
    assert!((held - start).amax() < 0.01, "{held:?} vs {start:?}");
    pid.deactivate().unwrap();
    assert!(!board.amplifiers_enabled().unwrap());

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
    thread::sleep(Duration::from_millis(300));
    let running = servo.status().unwrap();
    assert!(running.running);
    assert!(running.last.as_ref().is_some_and(|s| s.fault.is_none()));
    assert!(board.amplifiers_enabled().unwrap());
    let held = robot.joint_positions().unwrap();
    assert!((held - start).amax() < 0.01, "{held:?} vs {start:?}");
    // goWork through the running servo law: a smooth joint trajectory, targets over the line.
    robot.go_to(NamedPose::Work, 1.0).unwrap();
    thread::sleep(Duration::from_millis(2000));
    let work = robot.named_pose(NamedPose::Work).unwrap();
    let reached = robot.joint_positions().unwrap();
    println!("the servo reached {reached:?} for work {work:?}");
    assert!(
        (reached - work).amax() < 0.02,
        "{reached:?} vs work {work:?}: {:?}",
        servo.status()
    );

    // The cable is pulled: the loop faults with a typed cause, the node keeps answering.
    emulator.unplug();
    thread::sleep(Duration::from_millis(1500));
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
