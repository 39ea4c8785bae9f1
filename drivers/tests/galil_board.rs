//! The Galil `Board` end to end: its I/O thread over a real pseudo-terminal against the emulator,
//! and its behaviour on line faults.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use penelope_drivers::galil::emulator::{DmcConfig, PtyEmulator, PtyOptions};
use penelope_drivers::galil::{
    GalilBoard, GalilBoardConfig, GalilBoardError, GalilError, Link, SerialLink, SerialSettings,
    TargetMode,
};
use penelope_hal::board::{AxisCommand, AxisState, Board};
use penelope_hal::error::{Error as _, ErrorKind};
use penelope_hal::time::Timestamp;

/// A link that can be cut (reads time out, writes vanish) and restored, like a loose cable.
struct Cuttable {
    inner: SerialLink,
    cut: Arc<AtomicBool>,
}

impl Link for Cuttable {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), GalilError> {
        if self.cut.load(Ordering::SeqCst) {
            Ok(())
        } else {
            self.inner.write_all(bytes)
        }
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, GalilError> {
        if self.cut.load(Ordering::SeqCst) {
            std::thread::sleep(timeout.min(Duration::from_millis(20)));
            Ok(0)
        } else {
            self.inner.read(buf, timeout)
        }
    }
}

fn config(emu: &PtyEmulator, axes: usize) -> GalilBoardConfig {
    let mut c = GalilBoardConfig::new(emu.path().to_string_lossy(), axes, &[0.5; 8]);
    c.client.timeout = Duration::from_millis(200);
    // These tests write one command and wait: the hung-host check is tested on its own.
    c.command_timeout = None;
    c
}

fn now(start: Instant) -> Timestamp {
    Timestamp::from_nanos(start.elapsed().as_nanos() as u64)
}

/// Polls `read_axes` until `cond` holds (10 s at most).
fn wait_state(
    board: &mut GalilBoard,
    start: Instant,
    mut cond: impl FnMut(&[AxisState]) -> bool,
) -> Vec<AxisState> {
    let end = Instant::now() + Duration::from_secs(10);
    let mut out = vec![AxisState::default(); board.axis_count()];
    loop {
        if board.read_axes(now(start), &mut out).is_ok() && cond(&out) {
            return out;
        }
        assert!(Instant::now() < end, "state not reached: {out:?}");
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn streams_targets_and_efforts_through_cells() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let mut board = GalilBoard::open(config(&emu, 6)).unwrap();
    assert_eq!(board.info().identity.model, "DMC4060");
    assert_eq!(board.axis_count(), 6);
    let start = Instant::now();
    // Positions flow before anything is commanded; amplifiers are off.
    let s = wait_state(&mut board, start, |s| s.iter().all(|a| !a.enabled));
    assert!(s.iter().all(|a| a.position == 0));

    // Position tracking.
    board.set_enabled(true).unwrap();
    let targets = [1000, -2000, 0, 5, -5, 300];
    let cmds: Vec<AxisCommand> = targets.iter().map(|&p| AxisCommand::Position(p)).collect();
    board.write_axes(now(start), &cmds).unwrap();
    wait_state(&mut board, start, |s| {
        s.iter()
            .zip(&targets)
            .all(|(a, &t)| (a.position - t).abs() <= 2 && a.enabled)
    });
    // New targets stream in without any BG.
    let cmds: Vec<AxisCommand> = targets.iter().map(|&p| AxisCommand::Position(-p)).collect();
    board.write_axes(now(start), &cmds).unwrap();
    wait_state(&mut board, start, |s| {
        s.iter()
            .zip(&targets)
            .all(|(a, &t)| (a.position + t).abs() <= 2)
    });

    // Effort on axis A (OF volts with zero gains): it accelerates; the others hold.
    let mut cmds = cmds.clone();
    cmds[0] = AxisCommand::Effort(1.0);
    board.write_axes(now(start), &cmds).unwrap();
    let s = wait_state(&mut board, start, |s| s[0].velocity > 500.0);
    assert_eq!(s[0].effort, 1.0);
    assert!((s[1].position - 2000).abs() <= 2);
    // And back to position: gains restored, it servos to the target.
    cmds[0] = AxisCommand::Position(0);
    board.write_axes(now(start), &cmds).unwrap();
    wait_state(&mut board, start, |s| {
        s[0].position.abs() <= 2 && s[0].velocity.abs() < 5.0
    });

    // Off.
    board.set_enabled(false).unwrap();
    wait_state(&mut board, start, |s| s.iter().all(|a| !a.enabled));
    assert!(board.cycles() > 10);
    assert!(board.exchange_rate_hz() > 0.0);
    assert!(!board.is_faulted());

    // Bad input is refused on the control side.
    assert_eq!(
        board.write_axes(now(start), &[AxisCommand::Effort(f64::NAN); 6]),
        Err(GalilBoardError::NonFinite)
    );
    assert_eq!(
        board.write_axes(now(start), &[AxisCommand::Off; 2]),
        Err(GalilBoardError::WrongLength)
    );
    let mut short = [AxisState::default(); 3];
    assert_eq!(
        board.read_axes(now(start), &mut short),
        Err(GalilBoardError::WrongLength)
    );
}

#[test]
fn relative_moves_reach_the_target() {
    let emu = PtyEmulator::spawn(PtyOptions {
        dmc: DmcConfig {
            axes: 8,
            model: "DMC4080".into(),
            ..DmcConfig::default()
        },
        ..PtyOptions::default()
    })
    .unwrap();
    let mut c = config(&emu, 2);
    c.target_mode = TargetMode::Relative;
    let mut board = GalilBoard::open(c).unwrap();
    let start = Instant::now();
    board.set_enabled(true).unwrap();
    board
        .write_axes(
            now(start),
            &[AxisCommand::Position(800), AxisCommand::Position(-300)],
        )
        .unwrap();
    wait_state(&mut board, start, |s| {
        (s[0].position - 800).abs() <= 2 && (s[1].position + 300).abs() <= 2
    });
}

#[test]
fn device_gone_faults_the_board_without_panic() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let mut board = GalilBoard::open(config(&emu, 6)).unwrap();
    let start = Instant::now();
    board.set_enabled(true).unwrap();
    board
        .write_axes(now(start), &[AxisCommand::Position(100); 6])
        .unwrap();
    wait_state(&mut board, start, |s| s[0].enabled);
    emu.unplug();
    let end = Instant::now() + Duration::from_secs(10);
    let mut out = [AxisState::default(); 6];
    let err = loop {
        match board.read_axes(now(start), &mut out) {
            Err(e) => break e,
            Ok(()) => assert!(Instant::now() < end, "no fault after unplugging"),
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    assert!(
        matches!(err.kind(), ErrorKind::Communication | ErrorKind::Timeout),
        "{err:?}"
    );
    // Writes stay cheap and harmless; re-arming while the device is gone keeps the fault.
    board
        .write_axes(now(start), &[AxisCommand::Position(0); 6])
        .unwrap();
    board.rearm();
    std::thread::sleep(Duration::from_millis(300));
    assert!(board.read_axes(now(start), &mut out).is_err());
    assert!(board.is_faulted());
    drop(board);
}

#[test]
fn timeouts_fault_then_stale_and_rearm_recovers() {
    let emu = PtyEmulator::spawn(PtyOptions::default()).unwrap();
    let cut = Arc::new(AtomicBool::new(false));
    let path = emu.path().to_string_lossy().into_owned();
    let factory_cut = Arc::clone(&cut);
    let mut c = config(&emu, 6);
    c.client.timeout = Duration::from_millis(300);
    c.stale_after = Duration::from_millis(100);
    let factory = Box::new(move || {
        let inner = SerialLink::open(&SerialSettings::new(path.clone(), 115_200))?;
        Ok(Box::new(Cuttable {
            inner,
            cut: Arc::clone(&factory_cut),
        }) as Box<dyn Link + Send>)
    });
    let mut board = GalilBoard::with_link_factory(c, factory).unwrap();
    let start = Instant::now();
    wait_state(&mut board, start, |_| true);
    cut.store(true, Ordering::SeqCst);
    // With the I/O thread stuck waiting, the state ages: stale on the caller's clock.
    std::thread::sleep(Duration::from_millis(50));
    let mut out = [AxisState::default(); 6];
    let t = now(start);
    let _ = board.read_axes(t, &mut out);
    assert_eq!(
        board.read_axes(t + Duration::from_millis(150), &mut out),
        Err(GalilBoardError::Stale)
    );
    // Then the timeout becomes a latched fault.
    let end = Instant::now() + Duration::from_secs(10);
    while !board.is_faulted() {
        assert!(Instant::now() < end);
        std::thread::sleep(Duration::from_millis(10));
    }
    let err = board.read_axes(now(start), &mut out).unwrap_err();
    assert_eq!(err.kind(), ErrorKind::Timeout, "{err:?}");
    // Restore the line: still faulted until an explicit re-arm.
    cut.store(false, Ordering::SeqCst);
    std::thread::sleep(Duration::from_millis(100));
    assert!(board.is_faulted());
    board.rearm();
    wait_state(&mut board, start, |_| true);
    assert!(!board.is_faulted());
}

#[test]
fn wrong_axis_count_is_refused_at_open() {
    let emu = PtyEmulator::spawn(PtyOptions {
        dmc: DmcConfig {
            axes: 4,
            ..DmcConfig::default()
        },
        ..PtyOptions::default()
    })
    .unwrap();
    assert!(matches!(
        GalilBoard::open(config(&emu, 6)),
        Err(GalilError::InvalidArgument(_))
    ));
    assert!(matches!(
        GalilBoard::open(config(&emu, 0)),
        Err(GalilError::InvalidArgument(_))
    ));
}
