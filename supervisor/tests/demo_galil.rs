//! The demo with the slave PUMA on a Galil DMC instead of the sim board (`config/demo-galil.toml`):
//! the DMC is the emulator on a pseudo-terminal, started in this process; the run goes through
//! the node runtime on the real-time clock.
//!
//! The emulator powers up with every axis at zero counts, and encoder zero is the PUMA's `start`
//! pose. To see non-zero counts become radians, the test first moves the emulated axes away from
//! zero with a plain protocol client (as a person jogging the arm before a session), then checks
//! the run's first slave sample reads that pose.

use std::path::Path;
use std::time::{Duration, Instant};

use penelope_drivers::galil::emulator::{PtyEmulator, PtyOptions};
use penelope_drivers::galil::{
    Axes, Client, ClientConfig, Command, SerialLink, SerialSettings, Setting,
};
use penelope_drivers::model::puma200;
use penelope_hal::NamedPose;
use penelope_rt_core::safety::SafetyState;
use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::runs::report::report;
use penelope_supervisor::runs::{DEMO_SYSTEM, RunOptions, run};
use penelope_supervisor::system::SystemFile;

/// The shipped Galil variant of the demo.
const DEMO_GALIL: &str = include_str!("../../config/demo-galil.toml");

/// The device line of `config/demo-galil.toml`, replaced by the emulator's device in tests.
const DEVICE_LINE: &str = "device = \"/tmp/penelope-galil\"";

/// One real-time run at a time: two at once on a two-core host starve each other's serial
/// line (the board watchdog then trips), which is not what these tests are about.
static ONE_RUN_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Offset the test moves each joint from the start pose before the run, rad.
const JOG_RAD: f64 = 0.02;

/// Moves every emulated axis to `counts` (a profiled move), waits until it is there, then
/// switches the motors off and closes the port.
fn jog_to(path: &Path, counts: &[i64; 6]) {
    let link = SerialLink::open(&SerialSettings::new(path.display().to_string(), 115_200))
        .expect("open the emulator");
    let mut client = Client::new(link, ClientConfig::default());
    client.initialize().expect("the emulator answers");
    let all = Axes::first(6);
    client.ack(&Command::ServoHere(all)).expect("SH");
    let targets = counts.map(|c| Some(c as f64));
    client.set(Setting::PositionAbsolute, &targets).expect("PA");
    client.ack(&Command::Begin(all)).expect("BG");
    let give_up = Instant::now() + Duration::from_secs(5);
    let mut settled = 0;
    while settled < 3 {
        assert!(
            Instant::now() < give_up,
            "the emulator did not reach {counts:?}"
        );
        std::thread::sleep(Duration::from_millis(20));
        let p = client.positions().expect("TP");
        settled = if p.iter().zip(counts).all(|(p, c)| (p - c).abs() <= 1) {
            settled + 1
        } else {
            0
        };
    }
    client.ack(&Command::MotorOff(all)).expect("MO");
}

#[test]
fn the_shipped_galil_demo_differs_from_the_demo_in_the_pumas_board_and_its_wrist_sensor() {
    assert_eq!(DEMO_GALIL.matches(DEVICE_LINE).count(), 1);
    let galil = SystemFile::parse(DEMO_GALIL).expect("config/demo-galil.toml parses");
    let demo = SystemFile::parse(DEMO_SYSTEM).unwrap();
    let kind = |f: &SystemFile, name: &str| {
        f.objects
            .iter()
            .find(|o| o.name == name)
            .map(|o| o.kind.clone())
    };
    assert_eq!(kind(&galil, "puma-io").as_deref(), Some("board/galil"));
    assert_eq!(kind(&demo, "puma-io").as_deref(), Some("board/sim"));
    assert_eq!(
        kind(&galil, "follow").as_deref(),
        Some("controller/slave-position")
    );
    // No plant for a wrist sensor to read: the virtual sensor probes the wall itself, at the
    // measured tool pose, and the slave half is bound to it.
    let wrist = galil.objects.iter().find(|o| o.name == "wrist").unwrap();
    assert_eq!(wrist.kind, "sensor/virtual");
    assert!(!wrist.config.contains("robot"), "{}", wrist.config);
    assert!(wrist.config.contains("plane"), "{}", wrist.config);
    let follow = galil.objects.iter().find(|o| o.name == "follow").unwrap();
    assert_eq!(follow.sensor.as_deref(), Some("wrist"));
}

#[test]
fn the_slave_puma_runs_on_the_emulated_galil_and_reads_its_encoders() {
    let _one = ONE_RUN_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let emulator = PtyEmulator::spawn(PtyOptions::default()).expect("a pseudo-terminal");
    let model = puma200();
    let start = model.named_pose(NamedPose::Start);
    // Jog every joint JOG_RAD away from the start pose: counts = JOG_RAD x counts per radian.
    let mut counts = [0i64; 6];
    for (j, c) in counts.iter_mut().enumerate() {
        *c = (JOG_RAD * model.counts_per_radian(j)).round() as i64;
        assert!(c.abs() > 100, "joint {j}: {c} counts");
    }
    jog_to(emulator.path(), &counts);

    let text = DEMO_GALIL.replace(
        DEVICE_LINE,
        &format!("device = \"{}\"", emulator.path().display()),
    );
    let file = SystemFile::parse(&text).unwrap();
    let options = RunOptions {
        duration: Some(Duration::from_secs(3)),
        clock: ClockMode::RealTime,
        ..RunOptions::default()
    };
    let out = run(&file, &options, &mut |_| {}).expect("the galil demo runs");
    let r = report(&out);
    eprintln!("{}", serde_json::to_string_pretty(&r).unwrap_or_default());

    // The run completed: about 3000 ticks on each side (a few may be late under load).
    assert!(out.slave.len() > 2_500, "slave ticks: {}", out.slave.len());
    assert!(
        out.master.len() > 2_500,
        "master ticks: {}",
        out.master.len()
    );
    assert!(r.faults.is_empty(), "faults: {:?}", r.faults);

    // The first slave sample is the emulator's encoders, in radians: the start pose + the jog.
    let first = &out.slave[0].sample;
    for j in 0..6 {
        let expected = start[j] + counts[j] as f64 / model.counts_per_radian(j);
        assert!(
            (first.q[j] - expected).abs() < 1e-3,
            "joint {j}: read {} rad, the emulator is at {} counts = {expected} rad",
            first.q[j],
            counts[j]
        );
    }

    // The slave ran with no simulated plant behind it: no ground truth; the run ended before
    // the contact phase, so nothing was sensed in steady contact.
    let running = out
        .slave
        .iter()
        .filter(|s| s.sample.state == SafetyState::Running)
        .count();
    assert!(running > 2_000, "running ticks: {running}");
    assert!(out.slave.iter().all(|s| s.truth.is_none()));
    assert!(out.master.iter().all(|s| s.truth.is_some()));
    assert_eq!(r.contact.sensed_force_n, 0.0);

    // It followed the master (the emulator is a generic motor per axis, not a PUMA, so looser
    // than the sim board's 2 mm).
    assert!(
        r.tracking.samples > 1_000,
        "free-motion ticks: {}",
        r.tracking.samples
    );
    assert!(
        r.tracking.max_mm < 20.0,
        "tracking max {} mm (RMS {} mm)",
        r.tracking.max_mm,
        r.tracking.rms_mm
    );
}

/// The demo script up to just past its steady contact (which ends at 14.5 s). The taps that
/// follow are left out: tapping a wall that does not stop the emulated arm can drive the slave
/// past a joint's velocity limit (seen once at 15.5 s), which is the safety doing its job, not
/// what these tests are about.
const WHOLE_SCRIPT: Duration = Duration::from_millis(14_800);

#[test]
fn the_galil_demo_reflects_its_wall_to_the_operator() {
    let _one = ONE_RUN_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let emulator = PtyEmulator::spawn(PtyOptions::default()).expect("a pseudo-terminal");
    let text = DEMO_GALIL.replace(
        DEVICE_LINE,
        // A board watchdog and a command timeout of 250 ms instead of 30 and 50: this test
        // shares a loaded host, and a watchdog trip there is not what it is about (the
        // watchdogs have their own tests).
        &format!(
            "device = \"{}\"\nwatchdog_ms = 250\ncommand_timeout_ms = 250",
            emulator.path().display()
        ),
    );
    let file = SystemFile::parse(&text).unwrap();
    let options = RunOptions {
        duration: Some(WHOLE_SCRIPT),
        clock: ClockMode::RealTime,
        ..RunOptions::default()
    };
    let out = run(&file, &options, &mut |_| {}).expect("the galil demo runs");
    let r = report(&out);
    eprintln!(
        "{}",
        serde_json::to_string_pretty(&r.contact).unwrap_or_default()
    );
    assert!(r.faults.is_empty(), "faults: {:?}", r.faults);
    let c = &r.contact;
    assert!(c.samples > 500, "steady-contact ticks: {}", c.samples);
    assert!(
        c.sensed_force_n > 1.0,
        "the wall must push back on the slave, sensed {} N",
        c.sensed_force_n
    );
    assert!(
        c.display_error_pct < 5.0,
        "the motors display {} N, {}% off the expected {} N",
        c.displayed_force_n,
        c.display_error_pct,
        c.expected_display_n
    );
}
