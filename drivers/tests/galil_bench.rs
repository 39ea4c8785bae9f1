//! Benchmark (ignored by default): command/reply exchanges per second for a six-axis
//! target+position cycle against the emulator paced at 115200 baud, beside the line's
//! theoretical limit. Run:
//!
//! ```text
//! cargo test --release -p penelope-drivers --test galil_bench -- --ignored --nocapture
//! ```

use std::time::{Duration, Instant};

use penelope_drivers::galil::emulator::{PtyEmulator, PtyOptions};
use penelope_drivers::galil::{
    Axes, Client, ClientConfig, Command, GalilBoard, GalilBoardConfig, Reply, SerialLink,
    SerialSettings, Setting, Tell,
};
use penelope_hal::board::{AxisCommand, AxisState, Board};
use penelope_hal::time::Timestamp;

const BAUD: u32 = 115_200;

fn emulator(paced: bool) -> PtyEmulator {
    PtyEmulator::spawn(PtyOptions {
        baud: paced.then_some(BAUD),
        ..PtyOptions::default()
    })
    .unwrap()
}

/// Runs `cycles` exchanges of `PA targets;<tells>` and returns (Hz, bytes per cycle).
fn client_cycle(paced: bool, tells: &[Tell], cycles: u32) -> (f64, f64) {
    let emu = emulator(paced);
    let link = SerialLink::open(&SerialSettings::new(emu.path().to_string_lossy(), BAUD)).unwrap();
    let mut c = Client::new(link, ClientConfig::default());
    c.initialize().unwrap();
    c.ack(&Command::ServoHere(Axes::NONE)).unwrap();
    c.set(Setting::PositionTracking, &[Some(1.0); 6]).unwrap();
    let before = c.stats();
    let mut replies: [Reply; 4] = Default::default();
    let start = Instant::now();
    for k in 0..cycles {
        // Targets of realistic size (a few thousand counts, sign changing).
        let t = f64::from(k % 2000) * 7.0 - 7000.0;
        let targets = [
            Some(t),
            Some(-t),
            Some(t * 0.5),
            Some(t),
            Some(-t),
            Some(t * 0.25),
        ];
        let mut line = vec![Command::Set(Setting::PositionAbsolute, &targets)];
        line.extend(tells.iter().map(|&tl| Command::Tell(tl, Axes::NONE)));
        c.transact(&line, &mut replies).unwrap();
    }
    let elapsed = start.elapsed().as_secs_f64();
    let after = c.stats();
    let bytes = (after.bytes_in - before.bytes_in + after.bytes_out - before.bytes_out) as f64
        / f64::from(cycles);
    (f64::from(cycles) / elapsed, bytes)
}

fn board_cycle(seconds: f64) -> (f64, u64) {
    let emu = emulator(true);
    let mut board = GalilBoard::open(GalilBoardConfig::new(
        emu.path().to_string_lossy(),
        6,
        &[0.5; 6],
    ))
    .unwrap();
    let start = Instant::now();
    let now = || Timestamp::from_nanos(start.elapsed().as_nanos() as u64);
    board.set_enabled(true).unwrap();
    let mut out = [AxisState::default(); 6];
    let c0 = board.cycles();
    let mut k = 0i64;
    while start.elapsed().as_secs_f64() < seconds {
        k += 1;
        let t = (k % 2000) * 7 - 7000;
        board
            .write_axes(now(), &[AxisCommand::Position(t); 6])
            .unwrap();
        let _ = board.read_axes(now(), &mut out);
        std::thread::sleep(Duration::from_millis(1));
    }
    let cycles = board.cycles() - c0;
    (board.exchange_rate_hz(), cycles)
}

#[test]
#[ignore = "benchmark: run with --ignored --nocapture"]
fn galil_link_rate() {
    let cycles = 300;
    println!("six-axis target+position cycle, emulator paced at {BAUD} baud, {cycles} cycles");
    println!(
        "{:<28} {:>12} {:>12} {:>14} {:>9}",
        "cycle", "bytes/cycle", "achieved Hz", "line limit Hz", "ratio"
    );
    for (name, tells) in [
        ("PA ..;TP", &[Tell::Position][..]),
        ("PA ..;TP;TE", &[Tell::Position, Tell::Error][..]),
    ] {
        let (hz, bytes) = client_cycle(true, tells, cycles);
        let limit = f64::from(BAUD) / (bytes * 10.0);
        println!(
            "{name:<28} {bytes:>12.1} {hz:>12.1} {limit:>14.1} {:>8.0}%",
            100.0 * hz / limit
        );
    }
    let (hz, bytes) = client_cycle(false, &[Tell::Position], 2000);
    println!(
        "{:<28} {bytes:>12.1} {hz:>12.1} {:>14} {:>9}",
        "PA ..;TP unpaced (pty)", "-", "-"
    );
    let (hz, n) = board_cycle(3.0);
    println!(
        "GalilBoard I/O thread (PA;TP;TE + TV;TT;TS every 5th), paced: {hz:.1} Hz ({n} cycles in 3 s)"
    );
}
