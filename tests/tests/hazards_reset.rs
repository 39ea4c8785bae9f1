//! Reset never starts motion, for a teleoperation slave: the paper's task made of
//! objects on one node (an FRHC held by the scripted operator's hand, a PUMA 200 over a wall
//! with a wrist sensor, position-forward / force-back), stepped on a simulated clock; the slave
//! is e-stopped while the master moves on, then re-armed and activated again. And for a
//! trajectory mid-move on a simulated clock: a board fault and a link loss (the reference
//! stops), then the return and the reset: the arm moves less than 5 mrad in the second after.

use std::time::Duration;

use penelope_hal::{JointVector, Timestamp, Transition};
use penelope_protocol::proto::{BoardMethod, ControllerMethod, Method, Reply, RobotMethod};
use penelope_rt_core::control::ControlCommand;
use penelope_rt_core::safety::{FaultCause, SafetyState};
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_testkit::wait::wait_until;
use penelope_tests::fixtures::{hold_at, one_radian_move};
use penelope_tests::papers_task::{map_all, ok, papers_task, step_papers_task};

fn at_ms(rows: &[TelemetrySample], ms: u64) -> &TelemetrySample {
    rows.iter()
        .find(|s| s.time.as_nanos() >= ms * 1_000_000)
        .expect("a sample at that time")
}

#[test]
fn a_rearmed_teleoperation_slave_reanchors_where_it_is_and_follows_without_a_jump() {
    const ESTOP_MS: u64 = 2_500;
    const REARM_MS: u64 = 2_800;
    let c = papers_task();
    let (master, slave) = step_papers_task(&c, 4.0, f64::INFINITY, |i, now, slave| {
        if i == ESTOP_MS {
            slave.control.apply(now, ControlCommand::EStop);
        }
        if i == REARM_MS {
            slave.control.apply(now, ControlCommand::Rearm);
            slave.control.apply(now, ControlCommand::Activate);
        }
    });
    // Latched while the master moved on.
    assert_eq!(at_ms(&slave, ESTOP_MS + 10).state, SafetyState::EStop);
    let master_moved =
        (at_ms(&master, REARM_MS).tool_position - at_ms(&master, ESTOP_MS).tool_position).norm();
    println!(
        "the master moved {:.1} mm while the slave was e-stopped",
        master_moved * 1e3
    );
    assert!(
        master_moved > 0.005,
        "the test needs a master that moves: {master_moved} m"
    );

    // Re-armed: it runs again within a few periods (not waiting for a clutch or a link loss).
    let back = slave
        .iter()
        .find(|s| s.time.as_nanos() > REARM_MS * 1_000_000 && s.state == SafetyState::Running)
        .expect("the slave never followed again after its re-arm");
    let resumed_after = back.time.as_nanos() / 1_000_000 - REARM_MS;
    println!("re-armed slave following again {resumed_after} ms after the re-arm");
    assert!(resumed_after <= 20, "{resumed_after} ms");

    // No jump: in the 200 ms after the re-arm the slave moves no more than the master does
    // (scale 1), plus a little for its tracking; never by the offset the master built up.
    let window = |rows: &[TelemetrySample], from: u64, to: u64| {
        (at_ms(rows, to).tool_position - at_ms(rows, from).tool_position).norm()
    };
    let slave_moved = window(&slave, REARM_MS, REARM_MS + 200);
    let master_then = window(&master, REARM_MS, REARM_MS + 200);
    println!(
        "200 ms after the re-arm: slave moved {:.2} mm, master {:.2} mm (offset built while \
         stopped {:.1} mm)",
        slave_moved * 1e3,
        master_then * 1e3,
        master_moved * 1e3
    );
    assert!(
        slave_moved <= master_then + 0.003,
        "the slave jumped: {slave_moved} m against the master's {master_then} m"
    );
    // Following from where it is: over the next second its motion is the master's (scale 1).
    let slave_d = at_ms(&slave, REARM_MS + 1_000).tool_position - back.tool_position;
    let master_d = at_ms(&master, REARM_MS + 1_000).tool_position
        - at_ms(&master, back.time.as_nanos() / 1_000_000).tool_position;
    println!(
        "the second after: slave moved {:.1} mm, master {:.1} mm, difference {:.1} mm",
        slave_d.norm() * 1e3,
        master_d.norm() * 1e3,
        (slave_d - master_d).norm() * 1e3
    );
    assert!(
        (slave_d - master_d).norm() < 0.01 + 0.2 * master_d.norm(),
        "the slave does not follow the master's motion: {slave_d:?} vs {master_d:?}"
    );
    assert!(
        slave
            .iter()
            .filter(|s| s.time > back.time)
            .all(|s| s.state == SafetyState::Running),
        "the slave stopped following"
    );
}

fn ms(t: u64) -> Timestamp {
    Timestamp::from_nanos(t * 1_000_000)
}

/// What interrupts the move.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Interruption {
    /// The board's reads fail (a line fault) for a while, then work again.
    BoardFault,
    /// The reference stops for a second (its link or its producer lost), then comes back.
    LinkLoss,
}

/// A 1 rad move of joint 0 interrupted at a quarter by `what`; after its return and past the
/// move's end, the reset (re-arm, activate). Returns how far the arm moved in the second after
/// the return and in the second after the reset, rad; then checks that a new command moves it.
fn interrupted_then_reset(what: Interruption) -> (f64, f64) {
    let (mut ctl, mut comm) = one_radian_move();
    let mut t = 0;
    let mut comm_on = true;
    macro_rules! run_until {
        ($end:expr, $each:block) => {
            let end = $end;
            while t < end {
                t += 1;
                if comm_on && t % 4 == 0 {
                    comm.tick(ms(t));
                }
                ctl.tick(ms(t));
                $each
            }
        };
    }
    run_until!(3_000, {
        if ctl.board().true_position()[0] >= 0.25 {
            break;
        }
    });
    assert_eq!(ctl.safety().state(), SafetyState::Running);
    match what {
        Interruption::BoardFault => {
            // Longer than the loop tolerates, then the line answers again.
            ctl.board_mut().fail_next_reads(200);
            run_until!(t + 1_000, {});
            assert!(
                matches!(ctl.safety().fault_cause(), Some(FaultCause::BoardRead(_))),
                "{:?}",
                ctl.safety().fault_cause()
            );
        }
        Interruption::LinkLoss => {
            comm_on = false;
            run_until!(t + 1_000, {});
            assert_eq!(
                ctl.safety().fault_cause(),
                Some(FaultCause::ReferenceTimeout)
            );
            // The link comes back; the trajectory's time went on meanwhile.
            comm_on = true;
        }
    }
    let at_return = ctl.board().true_position();
    let mut after_return: f64 = 0.0;
    run_until!(t + 1_000, {
        after_return = after_return.max((ctl.board().true_position() - at_return).amax());
    });
    // Well past the move's end, then reset as the creator does: re-arm, activate.
    run_until!(t + 2_000, {});
    let at_rearm = ctl.board().true_position();
    ctl.apply(ms(t), ControlCommand::Rearm);
    ctl.apply(ms(t), ControlCommand::Activate);
    let mut after_reset: f64 = 0.0;
    run_until!(t + 1_000, {
        after_reset = after_reset.max((ctl.board().true_position() - at_rearm).amax());
    });
    println!(
        "{what:?} at a quarter of a 1 rad move: the arm moved {:.3} mrad in the second after \
         the return, {:.3} mrad in the second after the reset ({})",
        after_return * 1e3,
        after_reset * 1e3,
        ctl.safety().state()
    );
    assert_eq!(ctl.safety().state(), SafetyState::Holding);
    assert!(ctl.safety().awaiting_new_motion());

    // An explicit new command (the trajectory restarted from the measured state) moves it.
    let q = ctl.joint_state().position;
    comm.start(ms(t), &hold_at(q));
    run_until!(t + 2_000, {});
    assert_eq!(ctl.safety().state(), SafetyState::Running);
    let to_goal = (ctl.board().true_position()[0] - 1.0).abs();
    assert!(
        to_goal < 0.02,
        "the new command did not reach the goal: {to_goal} rad away"
    );
    (after_return, after_reset)
}

#[test]
fn a_reset_after_a_board_fault_mid_move_does_not_start_motion() {
    let (after_return, after_reset) = interrupted_then_reset(Interruption::BoardFault);
    assert!(
        after_return < 5e-3,
        "the board's return moved the arm: {after_return} rad"
    );
    assert!(
        after_reset < 5e-3,
        "the reset started motion: {after_reset} rad"
    );
}

#[test]
fn a_reset_after_a_link_loss_mid_move_does_not_start_motion() {
    let (after_return, after_reset) = interrupted_then_reset(Interruption::LinkLoss);
    assert!(
        after_return < 5e-3,
        "the link's return moved the arm: {after_return} rad"
    );
    assert!(
        after_reset < 5e-3,
        "the reset started motion: {after_reset} rad"
    );
}

/// The joints of robot `arm`, rad.
fn joints_of(c: &Creator, arm: &str) -> JointVector {
    match ok(c, arm, Method::Robot(RobotMethod::JointPositions)) {
        Reply::Joints(q) => JointVector::from_iterator(q.into_iter().chain(std::iter::repeat(0.0))),
        other => panic!("joint positions answered {other:?}"),
    }
}

#[test]
fn a_node_rearm_after_an_estop_mid_move_under_gravity_does_not_start_motion() {
    // A PUMA 560 under gravity on a simulated board with power-off brakes (they hold it while
    // the e-stop has its amplifiers off), moving from its start pose to its work pose in 2 s
    // under a joint PID with gravity compensation, on the real clock as a node runs it.
    let mut config = CreatorConfig::new("lab");
    config.rt.priority = None;
    let c = Creator::new(config);
    for (kind, name, cfg) in [
        ("robot/puma560", "arm", ""),
        ("board/sim", "sim", "brake = true"),
        (
            "trajectory/spline",
            "move",
            "[[waypoints]]\nat_s = 2.0\npose = \"work\"\n",
        ),
        ("controller/joint-pid", "pid", ""),
    ] {
        c.create(kind, name, cfg).unwrap();
    }
    map_all(&c, "arm", "sim");
    for name in ["sim", "arm", "move"] {
        ok(&c, name, Method::Transition(Transition::Configure));
    }
    for m in [
        ControllerMethod::SetRobot {
            robot: "arm".into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: "move".into(),
        },
    ] {
        ok(&c, "pid", Method::Controller(m));
    }
    ok(&c, "pid", Method::Transition(Transition::Configure));
    let start = joints_of(&c, "arm");
    ok(&c, "pid", Method::Transition(Transition::Activate));
    // E-stop once the arm is well under way.
    wait_until("the arm moves", || {
        c.call_object("arm", Method::Robot(RobotMethod::JointPositions))
            .is_ok()
            && (joints_of(&c, "arm") - start).amax() > 0.1
    });
    assert_eq!(c.estop_loop("pid"), Some(true));
    // Past the move's end (2 s from its start), then the reset.
    std::thread::sleep(Duration::from_secs(2));
    let at_rearm = joints_of(&c, "arm");
    ok(&c, "pid", Method::Controller(ControllerMethod::Rearm));
    let rearmed = std::time::Instant::now();
    let mut moved: f64 = 0.0;
    while rearmed.elapsed() < Duration::from_secs(1) {
        moved = moved.max((joints_of(&c, "arm") - at_rearm).amax());
        std::thread::sleep(Duration::from_millis(5));
    }
    println!(
        "node-level re-arm under gravity after an e-stop mid-move ({:.3} rad from the start): \
         the arm moved {:.3} mrad in the second after the re-arm",
        (at_rearm - start).amax(),
        moved * 1e3
    );
    assert!(moved < 5e-3, "the reset started motion: {moved} rad");
    // Re-armed for real: active, amplifiers on (the brakes released), holding against gravity.
    let amplifiers = ok(&c, "sim", Method::Board(BoardMethod::AmplifiersEnabled));
    assert_eq!(amplifiers, Reply::Flag(true));
    let status = match ok(&c, "pid", Method::Controller(ControllerMethod::Status)) {
        Reply::Status(s) => s,
        other => panic!("status answered {other:?}"),
    };
    let last = status.last.expect("the loop ticks");
    // Holding, or following the communication task's hold at the measured pose that replaced
    // the interrupted move: either way with torque against gravity, and nowhere else to go.
    assert!(
        [SafetyState::Holding, SafetyState::Running]
            .iter()
            .any(|s| s.to_string() == last.state),
        "{last:?}"
    );
    let torque = last.effort.iter().fold(0.0_f64, |m, e| m.max(e.abs()));
    assert!(torque > 1.0, "no torque against gravity: {last:?}");
    c.shutdown();
}
