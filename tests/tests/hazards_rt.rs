//! Fault injection on the real-time side (issue 30): each test drives a fault and asserts the
//! safe state reached and a time bound, printing the measured figure.
//!
//! - a control thread that hangs (does not die) in torque mode on the emulated Galil DMC: the
//!   board's I/O thread sees no fresh command and turns the amplifiers off;
//! - a board that measures a NaN velocity under a torque-driven PD hold: the hold cannot be
//!   formed, so zero torque with the amplifiers off, in the same tick;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use penelope_drivers::galil::board::BoardFault;
use penelope_drivers::galil::board::watchdog::TRIPPED;
use penelope_drivers::galil::emulator::{Dmc, PtyEmulator, PtyOptions};
use penelope_drivers::galil::{
    DEFAULT_COMMAND_TIMEOUT, GalilBoard, GalilBoardConfig, GalilBoardError,
};
use penelope_hal::{
    AxisCommand, AxisState, Board, ControlInput, Controller, ControllerError, ErrorKind,
    JointCommand, JointReference, JointState, JointVector, Reference, RobotModel, Timestamp,
};
use penelope_rt_core::cell::{Stamped, latest};
use penelope_rt_core::control::{
    ControlCommand, ControlConfig, ControlLoop, ControlPorts, NoCommands,
};
use penelope_rt_core::safety::{FaultCause, HoldMode, SafetyConfig, SafetyState};
use penelope_rt_core::telemetry::{TelemetrySample, TelemetrySink};
use penelope_testbed::DecoupledChain;

/// A law that asks for the same torque on every joint, whatever the state.
struct ConstantTorque(f64);

impl Controller for ConstantTorque {
    fn kind(&self) -> &'static str {
        "constant-torque"
    }
    fn activate(&mut self, _now: Timestamp, _measured: &JointState, _model: &dyn RobotModel) {}
    fn update(&mut self, _input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        Ok(JointCommand::Effort(JointVector::repeat(self.0)))
    }
}

/// A telemetry port that keeps nothing.
struct Discard;

impl TelemetrySink for Discard {
    fn push(&mut self, _sample: &TelemetrySample) -> bool {
        true
    }
}

/// Waits (20 s at most: a bound against a hang, not a timing claim) until `done` holds.
fn wait_until(what: &str, mut done: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(20);
    while !done() {
        assert!(Instant::now() < deadline, "never happened: {what}");
        std::thread::sleep(Duration::from_millis(1));
    }
}

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
    let (mut reference, reference_port) = latest::<Stamped<Reference>>();
    let ports = ControlPorts {
        reference: reference_port,
        telemetry: Discard,
        commands: NoCommands,
    };
    let mut ctl = ControlLoop::new(config, board, model, [ConstantTorque(0.4)], ports).unwrap();

    // The control thread: ticks every millisecond until told to hang, then blocks (alive, not
    // ticking) until the test lets it go.
    let hang = Arc::new(AtomicBool::new(false));
    let running = Arc::new(AtomicBool::new(false));
    let (release, hung) = mpsc::channel::<()>();
    let start = Instant::now();
    let thread = {
        let (hang, running) = (hang.clone(), running.clone());
        std::thread::spawn(move || {
            let now = || Timestamp::from_nanos(start.elapsed().as_nanos() as u64);
            ctl.tick(now());
            ctl.apply(now(), ControlCommand::Activate);
            while !hang.load(Ordering::Acquire) {
                reference.write(Stamped {
                    stamp: now(),
                    value: Reference::Joint(JointReference::default()),
                });
                let out = ctl.tick(now());
                running.store(out.state == SafetyState::Running, Ordering::Release);
                std::thread::sleep(Duration::from_millis(1));
            }
            let _ = hung.recv();
            ctl
        })
    };
    wait_until("torque on every axis", || {
        running.load(Ordering::Acquire)
            && emu.inspect(|d| {
                galil_axes(d)
                    .iter()
                    .all(|a| a.motor_on && a.offset.abs() > 0.1)
            })
    });
    // Hang, in torque mode.
    hang.store(true, Ordering::Release);
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
    drop(release);
    let mut ctl = thread.join().unwrap();
    let mut out = [AxisState::default(); GALIL_AXES];
    let now = Timestamp::from_nanos(start.elapsed().as_nanos() as u64);
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
