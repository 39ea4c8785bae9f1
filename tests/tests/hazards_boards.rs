//! Fault injection on the simulated and FPGA boards: a control thread that hangs (does
//! not die) in torque mode. The board's own command-freshness watchdog, stepped by the plant
//! keeper beside the loop (not by the control thread), ends the torque.

use std::time::{Duration, Instant};

use penelope_drivers::model::puma560;
use penelope_drivers::sim::ToolContact;
use penelope_drivers::sim::board::{
    DEFAULT_COMMAND_TIMEOUT, SimBoard, SimBoardConfig, SimBoardError,
};
use penelope_drivers::sim::plant::PlantConfig;
use penelope_hal::{
    AxisCommand, AxisState, Board, JointReference, JointVector, NamedPose, Reference, RobotModel,
    Timestamp,
};
use penelope_rt_core::cell::{Stamped, latest};
use penelope_rt_core::control::{
    ControlCommand, ControlConfig, ControlLoop, ControlPorts, NoCommands,
};
use penelope_rt_core::safety::{SafetyConfig, SafetyState};
use penelope_runtime::objects::runtime::{JointBoard, JointBoardError, SimDrive, SimObserver};
use penelope_testkit::wait::wait_until;
use penelope_tests::fixtures::{ConstantTorque, Discard, HangableThread};

const COUNTS_PER_RADIAN: f64 = 1000.0;

/// A PUMA 560's simulated body with the default command timeout, at rest at its start pose.
fn body() -> Box<penelope_runtime::objects::runtime::SimBody> {
    Box::new(SimBoard::new(
        puma560(),
        PlantConfig::default(),
        SimBoardConfig {
            counts_per_radian: JointVector::repeat(COUNTS_PER_RADIAN),
            effort_full_scale: JointVector::repeat(100.0),
            dac_bits: 16,
            position_kp: JointVector::repeat(100.0),
            position_kd: JointVector::repeat(1.0),
            velocity_cutoff_hz: 0.0,
            command_timeout: Some(DEFAULT_COMMAND_TIMEOUT),
            brake: false,
        },
        ToolContact::Free,
        puma560().named_pose(NamedPose::Start),
        Timestamp::ZERO,
    ))
}

/// Runs a torque law on `board` in a thread of its own on the real clock (as a node's control
/// thread does, with the plant keeper started), makes the thread hang in torque mode, and
/// returns the wall time from the hang to zero torque.
fn hang_in_torque_mode(mut board: JointBoard, what: &str) -> Duration {
    let observer = match &mut board {
        JointBoard::Sim(d) | JointBoard::Fpga(d) => {
            d.start_keeper();
            d.observer()
        }
        JointBoard::Galil(_) => unreachable!("a simulated body"),
    };
    let model = puma560();
    let safety = SafetyConfig::slave(6, *model.limits());
    let config = ControlConfig::new(Duration::from_millis(1), safety)
        .with_counts_per_radian(COUNTS_PER_RADIAN);
    let (reference, reference_port) = latest::<Stamped<Reference>>();
    let ports = ControlPorts {
        reference: reference_port,
        telemetry: Discard,
        commands: NoCommands,
    };
    let ctl = ControlLoop::new(config, board, model, [ConstantTorque(2.0)], ports).unwrap();
    let thread = HangableThread::spawn(
        (ctl, reference),
        |(ctl, _), clock| {
            ctl.tick(clock());
            // A period between the first reading and the activation, as a node's thread has.
            std::thread::sleep(Duration::from_millis(1));
            ctl.apply(clock(), ControlCommand::Activate);
        },
        |(ctl, reference), now| {
            reference.write(Stamped {
                stamp: now,
                value: Reference::Joint(JointReference::default()),
            });
            ctl.tick(now).state == SafetyState::Running
        },
    );
    wait_until("torque on every axis", || {
        thread.is_running()
            && observer
                .with_body(|b| {
                    b.is_enabled()
                        && b.held_commands()
                            .iter()
                            .all(|c| matches!(c, AxisCommand::Effort(e) if *e > 1.0))
                })
                .unwrap_or(false)
    });
    thread.hang();
    let hung_at = Instant::now();
    wait_until("zero torque", || {
        observer
            .with_body(|b| b.command_stale_since().is_some())
            .unwrap_or(false)
    });
    let delay = hung_at.elapsed();
    let stale_at = the_drive_is_off_and_the_world_goes_on(&observer, what);

    // Let the thread go: its loop finds the board faulted, and says why.
    let now = thread.now();
    let (mut ctl, _) = thread.release();
    let mut out = [AxisState::default(); 6];
    assert_eq!(
        ctl.board_mut().read_axes(now, &mut out),
        Err(JointBoardError::Sim(SimBoardError::CommandStale))
    );
    // A read or two may be tolerated (`board_read_tolerance`); then the loop faults.
    let faulted = (1..=20).any(|k| {
        let now = Timestamp::from_nanos(now.as_nanos() + k * 1_000_000);
        ctl.tick(now).state == SafetyState::Fault
    });
    assert!(faulted, "{what}: the loop runs on");
    let (board, ..) = ctl.into_parts();
    let (JointBoard::Sim(d) | JointBoard::Fpga(d)) = board else {
        unreachable!("a simulated body")
    };
    // The keeper is stopped and the body handed back whole, still off (the loop's fault path
    // turned the amplifiers off, which acknowledges the watchdog).
    let body = d.into_body();
    assert!(!body.is_enabled(), "{what}: amplifiers on after the fault");
    assert!(body.plant().snapshot().time >= stale_at);
    delay
}

/// After the trip: amplifiers off, nothing held, no torque left on; and the world goes on
/// without the control thread (the arm falls with no torque held). Returns when the command
/// went stale.
fn the_drive_is_off_and_the_world_goes_on(observer: &SimObserver, what: &str) -> Timestamp {
    let (stale_at, last_effort, held, enabled) = observer
        .with_body(|b| {
            (
                b.command_stale_since().expect("tripped"),
                b.plant().snapshot().joints.effort,
                b.held_commands().to_vec(),
                b.is_enabled(),
            )
        })
        .expect("the drive is alive");
    assert!(!enabled, "{what}: amplifiers still on");
    assert!(
        held.iter().all(|c| *c == AxisCommand::Off),
        "{what}: {held:?}"
    );
    assert_eq!(last_effort, JointVector::zeros(), "{what}: torque left on");
    // The world goes on without the control thread: the arm falls with no torque held.
    let plant_then = observer.with_body(|b| b.plant().snapshot().time).unwrap();
    wait_until("the plant keeps moving", || {
        observer.with_body(|b| b.plant().snapshot().time).unwrap() > plant_then
    });
    stale_at
}

fn check(delay: Duration, what: &str) {
    println!(
        "{what}: a hung control thread in torque mode: zero torque, amplifiers off {:.1} ms after \
         its last tick (command timeout {} ms, wall clock)",
        delay.as_secs_f64() * 1e3,
        DEFAULT_COMMAND_TIMEOUT.as_millis()
    );
    // Not before the timeout (it was this watchdog, not another fault: the thread's last tick
    // may precede the hang by a period); generous above for a busy 2-core machine.
    assert!(
        delay >= DEFAULT_COMMAND_TIMEOUT / 2,
        "{what}: off before the timeout: {delay:?}"
    );
    assert!(
        delay <= DEFAULT_COMMAND_TIMEOUT + Duration::from_millis(500),
        "{what}: {delay:?}"
    );
}

#[test]
fn a_hung_control_thread_in_torque_mode_leaves_the_simulated_board_with_zero_torque() {
    let delay = hang_in_torque_mode(JointBoard::Sim(SimDrive::new(body())), "board/sim");
    check(delay, "board/sim");
}

#[test]
fn a_hung_control_thread_in_torque_mode_leaves_the_fpga_board_with_zero_torque() {
    let delay = hang_in_torque_mode(JointBoard::Fpga(SimDrive::new(body())), "board/fpga");
    check(delay, "board/fpga");
}
