//! Fault injection on the real-time side: each test drives a fault and asserts the
//! safe state reached and a time bound, printing the measured figure.
//!
//! - a control thread that hangs (does not die) in torque mode on the emulated Galil DMC: the
//!   board's I/O thread sees no fresh command and turns the amplifiers off;
//! - a board that measures a NaN velocity under a torque-driven PD hold: the hold cannot be
//!   formed, so zero torque with the amplifiers off, in the same tick;
//! - an e-stop in the middle of a move, re-armed after the move's end: the reset does not start
//!   motion: the arm holds where it is until a new command (on a simulated clock);
//! - a torque-driven slave deactivated mid-motion: the control thread's last act, one period
//!   after its last tick, hands the arm to the board's servo (before any thread is joined);
//! - the wave-variable law's link cut between two nodes: each end declares the link lost
//!   within two communication periods, the slave holds, the master displays no force.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use penelope_drivers::galil::board::BoardFault;
use penelope_drivers::galil::board::watchdog::TRIPPED;
use penelope_drivers::galil::emulator::{Dmc, PtyEmulator, PtyOptions};
use penelope_drivers::galil::{
    DEFAULT_COMMAND_TIMEOUT, GalilBoard, GalilBoardConfig, GalilBoardError,
};
use penelope_hal::Transition;
use penelope_hal::{
    AxisCommand, AxisState, Board, ErrorKind, JointReference, JointVector, Reference, Timestamp,
};
use penelope_protocol::proto::{
    Call, ControllerMethod, JointAxis, Method, Reply, RobotMethod, TelemetryRecord,
};
use penelope_rt_core::cell::{Stamped, latest};
use penelope_rt_core::control::{
    ControlCommand, ControlConfig, ControlLoop, ControlPorts, NoCommands,
};
use penelope_rt_core::exec::{Flow, Tick};
use penelope_rt_core::safety::SafetyEvent;
use penelope_rt_core::safety::{FaultCause, HoldMode, SafetyConfig, SafetyState};
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::runtime::{self, JointBoard, LoopFault};
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::system::SystemFile;
use penelope_testbed::DecoupledChain;
use penelope_testkit::net::free_udp_port;
use penelope_testkit::wait::wait_until;
use penelope_tests::fixtures::{ConstantTorque, Discard, HangableThread, hold_at, one_radian_move};

const GALIL_AXES: usize = 6;

fn galil_axes(d: &Dmc) -> Vec<penelope_drivers::galil::emulator::AxisSnapshot> {
    (0..GALIL_AXES).filter_map(|i| d.axis(i)).collect()
}

#[test]
fn a_hung_control_thread_in_torque_mode_leaves_the_galil_motors_off_within_the_command_timeout() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let mut config = GalilBoardConfig::new(emu.path().to_string_lossy(), GALIL_AXES, &[0.5; 8]);
    config.client.timeout = Duration::from_millis(200);
    let timeout = config.command_timeout.expect("on by default");
    assert_eq!(timeout, DEFAULT_COMMAND_TIMEOUT);
    let board = GalilBoard::open(config).unwrap();
    wait_until("the first exchange", || board.cycles() > 0);

    let model = DecoupledChain::six_joint();
    let safety = SafetyConfig::slave(GALIL_AXES, model.limits);
    let config =
        ControlConfig::new(Duration::from_millis(1), safety).with_counts_per_radian(1000.0);
    let (reference, reference_port) = latest::<Stamped<Reference>>();
    let ports = ControlPorts {
        reference: reference_port,
        telemetry: Discard,
        commands: NoCommands,
    };
    let ctl = ControlLoop::new(config, board, model, [ConstantTorque(0.4)], ports).unwrap();

    // The control thread: ticks every millisecond until told to hang, then blocks (alive, not
    // ticking) until the test lets it go.
    let thread = HangableThread::spawn(
        (ctl, reference),
        |(ctl, _), clock| {
            ctl.tick(clock());
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
            && emu.inspect(|d| {
                galil_axes(d)
                    .iter()
                    .all(|a| a.motor_on && a.offset.abs() > 0.1)
            })
    });
    // Hang, in torque mode.
    thread.hang();
    let hung_at = emu.inspect(Dmc::now);

    wait_until("motors off", || {
        emu.inspect(|d| galil_axes(d).iter().all(|a| !a.motor_on && a.offset == 0.0))
    });
    let off_at = emu.inspect(|d| {
        galil_axes(d)
            .iter()
            .filter_map(|a| a.off_at)
            .max()
            .expect("went off")
    });
    let delay = off_at.saturating_sub(hung_at);
    println!(
        "hung control thread: motors off {:.1} ms after its last tick (command timeout {} ms)",
        delay.as_secs_f64() * 1e3,
        timeout.as_millis()
    );
    // The I/O thread checks once per exchange and then needs two exchanges (`OF`, `MO`): a
    // generous bound for a busy machine; not much before the timeout (it was this check, not
    // another fault: the thread's last tick may precede `hung_at` by a period).
    assert!(delay >= timeout / 2, "off before the timeout: {delay:?}");
    assert!(delay <= timeout + Duration::from_millis(500), "{delay:?}");
    // The heartbeat is no longer fed: the board's own watchdog trips too.
    wait_until("the board's watchdog trips", || {
        emu.inspect(|d| d.variable(TRIPPED)) == Some(1.0)
    });

    // Let the thread go: its loop finds the board faulted, and says why.
    let now = thread.now();
    let (mut ctl, _) = thread.release();
    let mut out = [AxisState::default(); GALIL_AXES];
    assert_eq!(
        ctl.board_mut().read_axes(now, &mut out),
        Err(GalilBoardError::Fault(BoardFault::CommandStale))
    );
}

/// A board that reports what it is told and measures what the test says, refusing NaN efforts
/// as real boards do.
#[derive(Debug, Default)]
struct RecordingBoard {
    measured: [AxisState; 6],
    commands: [AxisCommand; 6],
    enabled: bool,
    refused: u32,
}

#[derive(Debug)]
struct Refused;

impl penelope_hal::Error for Refused {
    fn kind(&self) -> ErrorKind {
        ErrorKind::NonFinite
    }
}

impl Board for RecordingBoard {
    type Error = Refused;
    fn axis_count(&self) -> usize {
        6
    }
    fn read_axes(&mut self, _now: Timestamp, out: &mut [AxisState]) -> Result<(), Refused> {
        out[..6].copy_from_slice(&self.measured);
        Ok(())
    }
    fn write_axes(&mut self, _now: Timestamp, commands: &[AxisCommand]) -> Result<(), Refused> {
        if commands
            .iter()
            .any(|c| matches!(c, AxisCommand::Effort(t) if !t.is_finite()))
        {
            self.refused += 1;
            return Err(Refused);
        }
        self.commands.copy_from_slice(&commands[..6]);
        Ok(())
    }
    fn set_enabled(&mut self, enabled: bool) -> Result<(), Refused> {
        self.enabled = enabled;
        Ok(())
    }
}

#[test]
fn a_nan_velocity_under_a_torque_hold_ends_with_zero_torque_and_the_amplifiers_off() {
    let model = DecoupledChain::six_joint();
    let mut safety = SafetyConfig::slave(6, model.limits);
    safety.hold = HoldMode::Pd {
        kp: JointVector::repeat(200.0),
        kd: JointVector::repeat(5.0),
    };
    let config =
        ControlConfig::new(Duration::from_millis(1), safety).with_counts_per_radian(1000.0);
    let (mut reference, reference_port) = latest::<Stamped<Reference>>();
    let ports = ControlPorts {
        reference: reference_port,
        telemetry: Discard,
        commands: NoCommands,
    };
    let board = RecordingBoard::default();
    let mut ctl = ControlLoop::new(config, board, model, [ConstantTorque(1.5)], ports).unwrap();
    let ms = |k: u64| Timestamp::from_nanos(k * 1_000_000);
    ctl.tick(ms(1));
    ctl.apply(ms(1), ControlCommand::Activate);
    for k in 2..20 {
        reference.write(Stamped {
            stamp: ms(k),
            value: Reference::Joint(JointReference::default()),
        });
        assert_eq!(ctl.tick(ms(k)).state, SafetyState::Running);
    }
    let board = ctl.board();
    assert!(board.enabled);
    assert!(
        board
            .commands
            .iter()
            .all(|c| *c == AxisCommand::Effort(1.5))
    );

    // The board measures a NaN velocity on joint 2: the loop faults and its PD hold, formed
    // from that state, would be NaN too.
    ctl.board_mut().measured[2].velocity = f64::NAN;
    let out = ctl.tick(ms(20));
    assert_eq!(out.state, SafetyState::Fault);
    assert_eq!(ctl.safety().fault_cause(), Some(FaultCause::NonFiniteState));
    // In that same tick: no torque left on, amplifiers off, nothing refused.
    let board = ctl.board();
    println!(
        "NaN velocity: commands {:?}, amplifiers on: {}, refused writes: {}",
        board.commands, board.enabled, board.refused
    );
    assert!(board.commands.iter().all(|c| *c == AxisCommand::Off));
    assert!(!board.enabled);
    assert_eq!(board.refused, 0);
    // And so it stays while the fault is latched.
    for k in 21..40 {
        ctl.tick(ms(k));
    }
    let board = ctl.board();
    assert!(board.commands.iter().all(|c| *c == AxisCommand::Off));
    assert!(!board.enabled);
    assert_eq!(board.refused, 0);
}

fn ms(t: u64) -> Timestamp {
    Timestamp::from_nanos(t * 1_000_000)
}

#[test]
fn a_rearm_after_an_estop_mid_move_does_not_start_motion() {
    let (mut ctl, mut comm) = one_radian_move();
    // The communication task every 4 ms, the loop every 1 ms, on a simulated clock.
    let mut t = 0;
    macro_rules! run_until {
        ($end:expr, $each:block) => {
            let end = $end;
            while t < end {
                t += 1;
                if t % 4 == 0 {
                    comm.tick(ms(t));
                }
                ctl.tick(ms(t));
                $each
            }
        };
    }
    // E-stop at a quarter of the move.
    run_until!(3_000, {
        if ctl.board().true_position()[0] >= 0.25 {
            break;
        }
    });
    assert_eq!(ctl.safety().state(), SafetyState::Running);
    let stopped_at = ctl.board().true_position()[0];
    ctl.apply(ms(t), ControlCommand::EStop);
    // Well past the move's end, then reset as the creator does: re-arm, activate.
    run_until!(t + 3_000, {});
    let at_rearm = ctl.board().true_position();
    ctl.apply(ms(t), ControlCommand::Rearm);
    ctl.apply(ms(t), ControlCommand::Activate);
    let mut moved: f64 = 0.0;
    run_until!(t + 1_000, {
        moved = moved.max((ctl.board().true_position() - at_rearm).amax());
    });
    println!(
        "re-armed after an e-stop at {stopped_at:.3} rad of a 1 rad move (arm at {:.3} rad): \
         it moved {:.3} mrad in the next second ({})",
        at_rearm[0],
        moved * 1e3,
        ctl.safety().state()
    );
    assert!(moved < 5e-3, "the reset started motion: {moved} rad");
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
        "the new command reached the goal: {to_goal} rad away"
    );
}

/// A PUMA 560 on a simulated board held at its start pose by a joint PID (torques), on the
/// simulated clock, configured but not active.
fn puma_with_a_pid() -> Creator {
    let mut config = CreatorConfig::new("hazards");
    config.rt.priority = None;
    config.clock = ClockMode::Simulated;
    let c = Creator::new(config);
    for (kind, name, cfg) in [
        ("robot/puma560", "arm", ""),
        ("board/sim", "sim", ""),
        ("trajectory/step", "hold", "pose = \"start\""),
        ("controller/joint-pid", "pid", ""),
    ] {
        c.create(kind, name, cfg).unwrap();
    }
    let call = |name: &str, method: Method| {
        c.call_object(name, method)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    };
    call(
        "arm",
        Method::Robot(RobotMethod::MapJoints {
            board: "sim".into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    for name in ["sim", "arm", "hold"] {
        call(name, Method::Transition(Transition::Configure));
    }
    call(
        "pid",
        Method::Controller(ControllerMethod::SetRobot {
            robot: "arm".into(),
        }),
    );
    call(
        "pid",
        Method::Controller(ControllerMethod::SetTrajectory {
            trajectory: "hold".into(),
        }),
    );
    call("pid", Method::Transition(Transition::Configure));
    c
}

#[test]
fn deactivating_a_torque_driven_slave_ends_its_torque_one_period_after_its_last_tick() {
    let c = puma_with_a_pid();
    // The loop's own per-tick bodies, stepped here as the control and communication threads
    // would run them (a 1 ms control period, a 4 ms communication period).
    let detached = c.detach_loop("pid").unwrap();
    let mut comm = detached.comm;
    let mut telemetry = detached.telemetry;
    let stop = Arc::new(AtomicBool::new(false));
    let (back, handed_back) = mpsc::sync_channel(1);
    let mut control = runtime::control_body(
        detached.control,
        stop.clone(),
        back,
        Arc::new(LoopFault::default()),
    );
    let period = Duration::from_millis(1);
    let tick = |k: u64| Tick {
        index: k,
        deadline: ms(k),
        woke: ms(k),
        period,
        overruns: 0,
        previous_exec: Duration::ZERO,
        early: false,
    };
    let mut k = 0;
    while k < 300 {
        if k % 4 == 0 {
            comm.tick(ms(k));
        }
        assert_eq!(control(tick(k)), Flow::Continue);
        k += 1;
    }
    // Mid-run, the law's torques on.
    let mut last = None;
    while let Some(r) = telemetry.pop() {
        last = Some(r);
    }
    let last = last.expect("the loop reported");
    assert_eq!(last.sample.state, SafetyState::Running);
    assert!(last.sample.effort.amax() > 0.1, "{:?}", last.sample.effort);
    let last_tick = last.truth.expect("the plant's truth").time;

    // Stopped as a slave's deactivation stops it: the next control tick is its last act.
    stop.store(true, Ordering::Release);
    assert_eq!(control(tick(k)), Flow::Stop);
    let task = handed_back.try_recv().expect("the task is handed back");
    let JointBoard::Sim(drive) = task.into_loop().into_board() else {
        panic!("a simulated board");
    };
    let board = drive.into_body();
    let safe_at = board.plant().snapshot().time;
    let delay = safe_at.saturating_since(last_tick);
    println!(
        "deactivated mid-motion: the board's servo holds {:.3} ms after the loop's last tick \
         (period {} ms); commands {:?}",
        delay.as_secs_f64() * 1e3,
        period.as_millis(),
        board.held_commands()
    );
    assert!(
        board
            .held_commands()
            .iter()
            .all(|c| matches!(c, penelope_hal::AxisCommand::Position(_))),
        "{:?}",
        board.held_commands()
    );
    assert!(delay <= period, "{delay:?}");
}

/// The demo's two-node system (`config/demo-two-nodes.toml`) with the wave law's halves active
/// instead of the default ones, and `channel` added to the channel's keys.
fn two_wave_nodes(channel: &str) -> (Node, Node) {
    let text = include_str!("../../config/demo-two-nodes.toml")
        .replace("127.0.0.1:7410", &format!("127.0.0.1:{}", free_udp_port()))
        .replace("127.0.0.1:7420", &format!("127.0.0.1:{}", free_udp_port()))
        .replace(
            "[trajectories.link]\n",
            &format!("[trajectories.link]\n{channel}\n"),
        )
        .replace(
            "[controllers.display]\n",
            "[controllers.display]\nactive = false\n",
        )
        .replace(
            "[controllers.follow]\n",
            "[controllers.follow]\nactive = false\n",
        );
    // The two wave halves: their `active = false` lines become `true`.
    let mut lines: Vec<String> = Vec::new();
    let mut in_wave = false;
    for line in text.lines() {
        if line.starts_with('[') {
            in_wave = line == "[controllers.wave]" || line == "[controllers.wave-follow]";
        }
        if in_wave && line.trim_start().starts_with("active = false") {
            lines.push("active = true".into());
        } else {
            lines.push(line.into());
        }
    }
    let file = SystemFile::parse(&lines.join("\n")).expect("a valid system file");
    let secret = b"the hazards test secret, strong enough".as_slice();
    let node = |name: &str| {
        let mut config = NodeConfig::new(name, NamingChoice::None);
        config.creator.rt.priority = None;
        config.creator.clock = ClockMode::Simulated;
        config.secret = Some(secret.to_vec().into());
        Node::start(config).unwrap()
    };
    let (a, b) = (node("master"), node("slave"));
    file.apply(&a).expect("the master's half");
    file.apply(&b).expect("the slave's half");
    (a, b)
}

fn newest(node: &Node, controller: &str) -> TelemetryRecord {
    match node.call(Call::Object {
        object: controller.into(),
        method: Method::Controller(ControllerMethod::Status),
    }) {
        Ok(Reply::Status(s)) => {
            let last = s.last.expect("ticked");
            assert!(last.fault.is_none(), "{controller}: {:?}", last.fault);
            *last
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_wave_link_cut_is_declared_lost_within_two_periods_the_slave_holds_the_master_displays_nothing()
{
    // Both directions silent from 13.0 to 13.5 s (communication every 2 ms).
    let (a, b) = two_wave_nodes("faults = { outages = [{ from_s = 13.0, to_s = 13.5 }] }");
    let ticks_a = a.creator().record_ticks("wave", 1 << 15).unwrap();
    let ticks_b = b.creator().record_ticks("wave-follow", 1 << 15).unwrap();
    let step = |n: u32| {
        for _ in 0..n {
            a.creator().advance(Duration::from_millis(1)).unwrap();
            b.creator().advance(Duration::from_millis(1)).unwrap();
        }
    };
    step(13_000);
    step(100);
    let held = newest(&b, "wave-follow").tool_position;
    let mut drift: f64 = 0.0;
    for _ in 0..380 {
        step(1);
        let p = newest(&b, "wave-follow").tool_position;
        let d =
            ((p[0] - held[0]).powi(2) + (p[1] - held[1]).powi(2) + (p[2] - held[2]).powi(2)).sqrt();
        drift = drift.max(d);
    }
    step(1_000);
    let comm_period = 2;
    for (name, stream) in [("master", &ticks_a), ("slave", &ticks_b)] {
        let mut ticks = Vec::new();
        stream.drain_into(&mut ticks);
        let at = |event: SafetyEvent| -> Vec<u64> {
            ticks
                .iter()
                .filter(|t| t.sample.events.contains(event))
                .map(|t| t.sample.time.as_nanos() / 1_000_000)
                .collect()
        };
        let (lost, back) = (at(SafetyEvent::LinkLost), at(SafetyEvent::LinkRestored));
        println!("wave {name}: link-lost at {lost:?} ms, link-restored at {back:?} ms");
        assert_eq!(lost.len(), 1, "{name}: {lost:?}");
        // The last samples before the cut left at 12.998 s and are heard at most one period
        // later: lost two periods after that, plus one control tick.
        let bound = 12_998 + 3 * comm_period + 1;
        assert!(lost[0] <= bound, "{name}: lost at {} ms", lost[0]);
        assert_eq!(back.len(), 1, "{name}: {back:?}");
        if name == "master" {
            // Late in the cut the master displays no force at all.
            let late: Vec<_> = ticks
                .iter()
                .filter(|t| {
                    let ms = t.sample.time.as_nanos() / 1_000_000;
                    (13_100..13_480).contains(&ms)
                })
                .collect();
            assert!(!late.is_empty());
            let largest = late
                .iter()
                .map(|t| t.sample.commanded_wrench.force.norm())
                .fold(0.0, f64::max);
            println!("wave master: largest displayed force late in the cut {largest} N");
            assert_eq!(largest, 0.0);
        }
    }
    println!("wave slave: drifted {:.4} mm while held", drift * 1000.0);
    assert!(
        drift < 5e-4,
        "the slave moved {} mm while held",
        drift * 1000.0
    );
    a.shutdown();
    b.shutdown();
}
