//! End to end over a real pseudo-terminal pair: the client (through `serialport`, as on a real
//! line) against the emulator.

use std::time::{Duration, Instant};

use penelope_drivers::galil::emulator::{DmcConfig, PtyEmulator, PtyOptions};
use penelope_drivers::galil::{
    Axes, Client, ClientConfig, Command, GalilError, Operand, SerialLink, SerialSettings, Setting,
    Tell,
};
use penelope_testkit::wait::wait_until;

fn emulator(options: PtyOptions) -> PtyEmulator {
    PtyEmulator::spawn(options).expect("pseudo-terminal")
}

fn connect(emu: &PtyEmulator, baud: u32) -> Client<SerialLink> {
    let path = emu.path().to_string_lossy().into_owned();
    let link = SerialLink::open(&SerialSettings::new(path, baud)).expect("open pty");
    Client::new(link, ClientConfig::default())
}

#[test]
fn identify_move_and_read_back() {
    let emu = emulator(PtyOptions::default());
    let mut c = connect(&emu, 115_200);
    let info = c.initialize().unwrap();
    assert_eq!(info.identity.model, "DMC4060");
    assert_eq!(info.layout.axes, 6);
    assert_eq!(info.layout.record_len(), 298);

    // A rejection end to end, with Galil's code.
    assert_eq!(
        c.command(&Command::Begin(Axes(1))).unwrap_err().code(),
        Some(20)
    );
    assert_eq!(c.command(&Command::Raw("XX")).unwrap_err().code(), Some(1));
    assert_eq!(
        c.set(Setting::OffOnError, &[Some(9.0)]).unwrap_err().code(),
        Some(6)
    );

    // Position tracking: servo on, follow targets.
    c.ack(&Command::ServoHere(Axes::NONE)).unwrap();
    c.set(Setting::PositionTracking, &[Some(1.0); 6]).unwrap();
    let targets = [
        Some(1000.0),
        Some(-2000.0),
        Some(0.0),
        Some(5.0),
        Some(-5.0),
        Some(300.0),
    ];
    c.set(Setting::PositionAbsolute, &targets).unwrap();
    wait_until("every axis at its target", || {
        let p = c.positions().unwrap();
        let v = c.tell(Tell::Velocity, Axes::NONE).unwrap();
        p.iter()
            .zip(&targets)
            .all(|(&p, t)| (p as f64 - t.unwrap()).abs() <= 1.0)
            && v.iter().all(|&v| v == 0.0)
    });
    // The binary record agrees with TP.
    let rec = c.record().unwrap();
    let tp = c.positions().unwrap();
    for (a, p) in rec.axes().iter().zip(&tp) {
        assert!((i64::from(a.position) - p).abs() <= 2, "{a:?} vs {p}");
        assert!(!a.motor_off());
    }
    // A profiled relative move with stop code 1.
    c.set(Setting::PositionTracking, &[Some(0.0)]).unwrap();
    c.set(Setting::PositionRelative, &[Some(500.0)]).unwrap();
    c.ack(&Command::Begin(Axes(1))).unwrap();
    wait_until("the move done", || {
        c.message(Operand::Moving, 0).unwrap() == 0.0
    });
    assert_eq!(c.tell(Tell::StopCode, Axes(1)).unwrap().as_slice(), &[1.0]);
    // The profiler is done; the motor settles just after.
    wait_until("axis A at 1500", || {
        (c.positions().unwrap()[0] - 1500).abs() <= 1
    });
    assert_eq!(c.query(Setting::Kp, 2).unwrap().as_slice(), &[6.0, 6.0]);
    assert!((c.servo_period().unwrap() - 1000.0).abs() < 1e-9);
    assert!(c.stats().exchanges > 10);
}

#[test]
fn leading_zeros_and_unsolicited_interleaving_end_to_end() {
    let emu = emulator(PtyOptions {
        unsolicited: Some((Duration::from_millis(5), b"MSG: from #AUTO?\r\n".to_vec())),
        ..PtyOptions::default()
    });
    let mut c = connect(&emu, 115_200);
    c.initialize().unwrap();
    c.command(&Command::LeadingZeros(true)).unwrap();
    c.ack(&Command::ServoHere(Axes::NONE)).unwrap();
    c.set(Setting::PositionTracking, &[Some(1.0)]).unwrap();
    c.set(Setting::PositionAbsolute, &[Some(-7.0)]).unwrap();
    for _ in 0..200 {
        let p = c.positions().unwrap();
        assert_eq!(p.len(), 6);
    }
    wait_until("axis A at -7", || c.positions().unwrap()[0] == -7);
    let text = String::from_utf8(c.take_unsolicited()).unwrap();
    assert!(text.contains("MSG: from #AUTO?"), "{text:?}");
}

#[test]
fn device_disappearing_mid_exchange() {
    let emu = emulator(PtyOptions {
        dmc: DmcConfig {
            axes: 4,
            model: "DMC4040".into(),
            ..DmcConfig::default()
        },
        ..PtyOptions::default()
    });
    let mut c = connect(&emu, 115_200);
    assert_eq!(c.initialize().unwrap().layout.axes, 4);
    assert_eq!(c.positions().unwrap().len(), 4);
    emu.unplug();
    wait_until("the emulator unplugged", || !emu.is_plugged());
    let err = c.positions().unwrap_err();
    assert!(err.is_link_fault(), "{err:?}");
    // Every later call fails cleanly, never hangs for long and never panics.
    for _ in 0..3 {
        let start = Instant::now();
        let err = c.positions().unwrap_err();
        assert!(err.is_link_fault(), "{err:?}");
        assert!(start.elapsed() < Duration::from_secs(5));
    }
    drop(emu);
    // Opening the vanished device fails with a typed error too.
    let gone = SerialLink::open(&SerialSettings::new("/dev/pts/does-not-exist", 115_200));
    assert!(matches!(gone, Err(GalilError::Closed | GalilError::Io(_))));
}

/// The one paced test: the emulator keeps a real 115200-baud line's timing.
#[test]
fn paced_line_at_115200() {
    let emu = emulator(PtyOptions {
        baud: Some(115_200),
        ..PtyOptions::default()
    });
    let mut c = connect(&emu, 115_200);
    c.initialize().unwrap();
    let rec = c.record().unwrap();
    assert_eq!(rec.axes().len(), 6);
    let (rx, tx) = emu.bytes();
    assert!(tx >= 298 && rx > 0);
}
