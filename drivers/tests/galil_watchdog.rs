//! Amplifiers off on every fault, end to end on the emulated DMC (a pseudo-terminal):
//!
//! - a cable pulled in torque mode: the board's own watchdog program turns the motors off within
//!   the watchdog time, measured on the emulator's clock (last command received to motor off);
//! - a host process killed without a goodbye: the same, from a child process killed with
//!   SIGKILL;
//! - a line fault while the line still answers: the host zeroes `OF` and sends `MO` itself;
//! - release: dropping the board turns the amplifiers off and halts the watchdog;
//! - torque directions: an axis whose joint counts backwards gets the opposite volts.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use penelope_drivers::galil::board::watchdog::{TRIPPED, WATCHDOG_THREAD};
use penelope_drivers::galil::board::{BoardFault, DEFAULT_WATCHDOG};
use penelope_drivers::galil::emulator::{AxisSnapshot, Dmc, PtyEmulator, PtyOptions};
use penelope_drivers::galil::{
    GalilBoard, GalilBoardConfig, GalilBoardError, GalilError, Link, SerialLink, SerialSettings,
};
use penelope_hal::board::{AxisCommand, AxisState, Board};
use penelope_hal::time::Timestamp;
use penelope_rt_core::control::AxisBinding;

const AXES: usize = 6;
const SCALE: f64 = 0.5;

fn config(path: &str) -> GalilBoardConfig {
    let mut c = GalilBoardConfig::new(path, AXES, &[SCALE; 8]);
    c.client.timeout = Duration::from_millis(200);
    // These tests write one command and wait: the hung-host check is tested on its own.
    c.command_timeout = None;
    c
}

fn now(start: Instant) -> Timestamp {
    Timestamp::from_nanos(start.elapsed().as_nanos() as u64)
}

/// Waits (10 s at most) until the emulated controller satisfies `cond`.
fn wait_dmc(emu: &PtyEmulator, what: &str, cond: impl Fn(&Dmc) -> bool) {
    let end = Instant::now() + Duration::from_secs(10);
    while !emu.inspect(&cond) {
        assert!(Instant::now() < end, "timed out waiting for: {what}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn axes(d: &Dmc) -> Vec<AxisSnapshot> {
    (0..AXES).filter_map(|i| d.axis(i)).collect()
}

fn torque_on(d: &Dmc) -> bool {
    axes(d).iter().all(|a| a.motor_on && a.offset.abs() > 0.1)
}

fn all_off(d: &Dmc) -> bool {
    axes(d).iter().all(|a| !a.motor_on)
}

/// The longest silence of the host, on the emulator's clock, at the instant an axis went off
/// (from the host's last command to the motor off).
fn off_delay(d: &Dmc) -> Duration {
    axes(d)
        .iter()
        .map(|a| {
            a.host_silent_at_off
                .expect("went off after the host talked")
        })
        .max()
        .unwrap_or_default()
}

/// Torque on every axis through the board's cells.
fn drive_torque(board: &mut GalilBoard, start: Instant) {
    board.set_enabled(true).unwrap();
    board
        .write_axes(now(start), &[AxisCommand::Effort(2.0); AXES])
        .unwrap();
}

/// The watchdog bound, on the emulator's clock: off no later than the watchdog time after the
/// host's last word, and not much earlier (it was the watchdog, not something else).
fn assert_watchdog_bound(delay: Duration) {
    println!(
        "motor off {:.2} ms after the host's last command (watchdog {} ms)",
        delay.as_secs_f64() * 1e3,
        DEFAULT_WATCHDOG.as_millis()
    );
    assert!(delay <= DEFAULT_WATCHDOG, "{delay:?}");
    assert!(delay >= DEFAULT_WATCHDOG / 2, "{delay:?}");
}

#[test]
fn a_pulled_cable_in_torque_mode_leaves_the_motors_off_within_the_watchdog_time() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let start = Instant::now();
    let mut board = GalilBoard::open(config(&emu.path().to_string_lossy())).unwrap();
    drive_torque(&mut board, start);
    wait_dmc(&emu, "torque on every axis", torque_on);
    assert!(emu.inspect(|d| d.thread_running(usize::from(WATCHDOG_THREAD))));

    emu.unplug();
    wait_dmc(&emu, "motors off", all_off);
    let delay = emu.inspect(off_delay);
    assert_watchdog_bound(delay);
    assert_eq!(emu.inspect(|d| d.variable(TRIPPED)), Some(1.0));
    assert!(emu.inspect(|d| axes(d).iter().all(|a| a.offset == 0.0)));

    // The host sees a typed fault, never a panic.
    let end = Instant::now() + Duration::from_secs(10);
    let mut out = [AxisState::default(); AXES];
    loop {
        match board.read_axes(now(start), &mut out) {
            Err(GalilBoardError::Fault(_) | GalilBoardError::Stale) => break,
            _ => assert!(Instant::now() < end, "no fault after the unplug"),
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Environment variable naming the port a child host process drives.
const CHILD_PORT: &str = "PENELOPE_GALIL_WATCHDOG_CHILD_PORT";

/// Not a test on its own: the host process that `a_killed_host_...` starts and kills. It drives
/// torque until it is killed.
#[test]
#[ignore = "run as a child process by a_killed_host_process_leaves_the_motors_off"]
fn child_host_driving_torque() {
    let Ok(port) = std::env::var(CHILD_PORT) else {
        return;
    };
    let start = Instant::now();
    let mut board = GalilBoard::open(config(&port)).unwrap();
    drive_torque(&mut board, start);
    println!("driving");
    // Keep the board (and its heartbeat) alive until the parent kills this process; a parent
    // that died leaves this process ending after a minute.
    let end = Instant::now() + Duration::from_secs(60);
    while Instant::now() < end {
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn a_killed_host_process_leaves_the_motors_off() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let mut child = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "child_host_driving_torque",
            "--ignored",
            "--nocapture",
        ])
        .env(CHILD_PORT, emu.path())
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let end = Instant::now() + Duration::from_secs(20);
    while !emu.inspect(torque_on) {
        if let Ok(Some(status)) = child.try_wait() {
            panic!("the host process ended on its own: {status}");
        }
        assert!(Instant::now() < end, "the host process never drove torque");
        std::thread::sleep(Duration::from_millis(5));
    }
    // No goodbye: SIGKILL.
    child.kill().unwrap();
    child.wait().unwrap();
    wait_dmc(&emu, "motors off", all_off);
    assert_watchdog_bound(emu.inspect(off_delay));
    assert_eq!(emu.inspect(|d| d.variable(TRIPPED)), Some(1.0));
}

/// A serial link on which line noise can turn the next reply into a lone `?`.
struct Noisy {
    inner: SerialLink,
    noise: Arc<AtomicBool>,
}

impl Link for Noisy {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), GalilError> {
        self.inner.write_all(bytes)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, GalilError> {
        if self.noise.swap(false, Ordering::SeqCst) && !buf.is_empty() {
            buf[0] = b'?';
            return Ok(1);
        }
        self.inner.read(buf, timeout)
    }
}

#[test]
fn a_line_fault_on_a_line_that_still_answers_zeroes_the_offset_and_turns_the_motors_off() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let noise = Arc::new(AtomicBool::new(false));
    let settings = SerialSettings::new(emu.path().to_string_lossy(), 115_200);
    let factory_noise = Arc::clone(&noise);
    let factory = Box::new(move || {
        let inner = SerialLink::open(&settings)?;
        Ok(Box::new(Noisy {
            inner,
            noise: Arc::clone(&factory_noise),
        }) as Box<dyn Link + Send>)
    });
    let start = Instant::now();
    let mut board =
        GalilBoard::with_link_factory(config(&emu.path().to_string_lossy()), factory).unwrap();
    drive_torque(&mut board, start);
    wait_dmc(&emu, "torque on every axis", torque_on);

    noise.store(true, Ordering::SeqCst);
    wait_dmc(&emu, "motors off with OF 0", |d| {
        axes(d).iter().all(|a| !a.motor_on && a.offset == 0.0)
    });
    // The host did it (the watchdog, still fed, never tripped), and says why.
    assert_eq!(emu.inspect(|d| d.variable(TRIPPED)), Some(0.0));
    let mut out = [AxisState::default(); AXES];
    let err = board.read_axes(now(start), &mut out).unwrap_err();
    assert!(
        matches!(
            err,
            GalilBoardError::Fault(BoardFault::Rejected(_) | BoardFault::Garbled)
        ),
        "{err:?}"
    );
    // Re-arming brings the board (and its watchdog) back.
    board.rearm();
    let end = Instant::now() + Duration::from_secs(10);
    while board.is_faulted() {
        assert!(Instant::now() < end, "no recovery");
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(emu.inspect(|d| d.thread_running(usize::from(WATCHDOG_THREAD))));
}

#[test]
fn release_turns_the_amplifiers_off_and_halts_the_watchdog() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let start = Instant::now();
    let mut board = GalilBoard::open(config(&emu.path().to_string_lossy())).unwrap();
    drive_torque(&mut board, start);
    wait_dmc(&emu, "torque on every axis", torque_on);
    board.release();
    // Synchronous: release returns after the I/O thread said goodbye.
    emu.inspect(|d| {
        assert!(axes(d).iter().all(|a| !a.motor_on && a.offset == 0.0));
        assert!(!d.thread_running(usize::from(WATCHDOG_THREAD)));
        assert_eq!(d.variable(TRIPPED), Some(0.0));
    });
}

#[test]
fn an_axis_whose_joint_counts_backwards_gets_the_opposite_volts() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let start = Instant::now();
    let mut board = GalilBoard::open(config(&emu.path().to_string_lossy())).unwrap();
    // Joint 0 with a negative gear (counts down as the joint turns up), joint 1 positive.
    board.orient(&[AxisBinding::new(0, -9549.3), AxisBinding::new(1, 15915.5)]);
    assert_eq!(&board.directions()[..3], &[-1.0, 1.0, 1.0]);
    board.set_enabled(true).unwrap();
    let mut cmd = [AxisCommand::Off; AXES];
    cmd[0] = AxisCommand::Effort(1.0);
    cmd[1] = AxisCommand::Effort(1.0);
    board.write_axes(now(start), &cmd).unwrap();
    wait_dmc(&emu, "OF on axes A and B", |d| {
        let (a, b) = (d.axis(0).unwrap(), d.axis(1).unwrap());
        a.offset == -SCALE && b.offset == SCALE
    });
    // And the measured torque comes back in the joint's sense.
    let end = Instant::now() + Duration::from_secs(10);
    let mut out = [AxisState::default(); AXES];
    loop {
        if board.read_axes(now(start), &mut out).is_ok()
            && (out[0].effort - 1.0).abs() < 1e-3
            && (out[1].effort - 1.0).abs() < 1e-3
        {
            break;
        }
        assert!(Instant::now() < end, "{out:?}");
        std::thread::sleep(Duration::from_millis(2));
    }
}
