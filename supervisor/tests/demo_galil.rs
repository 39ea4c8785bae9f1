//! The demo with the slave PUMA on a Galil DMC instead of the sim board (issue 5): the DMC is the
//! emulator on a pseudo-terminal, started in this process; the lab runs on the real-time clock.
//!
//! The emulator powers up with every axis at zero counts, and the lab takes encoder zero as the
//! PUMA's `start` pose (see `lab::devices`). To see non-zero counts become radians, the first test
//! first moves the emulated axes away from zero with a plain protocol client (as a person jogging
//! the arm before a session), then checks the lab's first slave sample reads that pose.

use std::path::Path;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use penelope_drivers::galil::emulator::{PtyEmulator, PtyOptions};
use penelope_drivers::galil::{
    Axes, Client, ClientConfig, Command, SerialLink, SerialSettings, Setting,
};
use penelope_drivers::model::{DhRobotModel, puma200};
use penelope_hal::{JointVector, NamedPose};
use penelope_rt_core::safety::{FaultCause, SafetyState};
use penelope_supervisor::lab::LabConfig;
use penelope_supervisor::lab::config::{BoardConfig, BoardKind, DEMO_TOML};
use penelope_supervisor::lab::devices::{GalilSetupError, galil_board};
use penelope_supervisor::lab::report::report;
use penelope_supervisor::lab::run::{ClockMode, Progress, RunOptions, RunOutput, run};

/// The shipped Galil variant of the demo.
const DEMO_GALIL_TOML: &str = include_str!("../../config/demo-galil.toml");

/// The port line of `config/demo-galil.toml`, replaced by the emulator's device in tests.
const PORT_LINE: &str = "port = \"/tmp/penelope-galil\"";

/// Real-time runs one at a time: two labs at once would share two cores between eight
/// SCHED_FIFO threads.
static REAL_TIME: Mutex<()> = Mutex::new(());

/// Offset the first test moves each joint from the start pose before the run, rad.
const JOG_RAD: f64 = 0.02;

fn lab_on(emulator: &PtyEmulator) -> LabConfig {
    assert_eq!(
        DEMO_GALIL_TOML.matches(PORT_LINE).count(),
        1,
        "config/demo-galil.toml has one port line"
    );
    let text = DEMO_GALIL_TOML.replace(
        PORT_LINE,
        &format!("port = \"{}\"", emulator.path().display()),
    );
    LabConfig::from_toml(&text).expect("the galil demo lab parses")
}

fn start_pose(model: &DhRobotModel) -> JointVector {
    model.named_pose(NamedPose::Start)
}

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

fn run_real_time(
    lab: &LabConfig,
    seconds: u64,
    on_progress: &mut dyn FnMut(&Progress),
) -> RunOutput {
    let options = RunOptions {
        duration: Some(Duration::from_secs(seconds)),
        clock: ClockMode::RealTime,
        ..RunOptions::default()
    };
    run(lab, &options, on_progress).expect("the galil lab builds and runs")
}

#[test]
fn the_shipped_galil_demo_differs_from_the_demo_by_the_board_kind_and_its_port() {
    let galil = LabConfig::from_toml(DEMO_GALIL_TOML).expect("config/demo-galil.toml parses");
    let demo = LabConfig::demo();
    let board = &galil.boards["puma-io"];
    assert_eq!(board.kind, BoardKind::Galil);
    assert_eq!(board.port.as_deref(), Some("/tmp/penelope-galil"));
    assert_eq!(demo.boards["puma-io"].kind, BoardKind::Sim);
    // Every other setting line is the demo's.
    let settings = |text: &str| -> Vec<String> {
        text.lines()
            .map(|l| l.split('#').next().unwrap_or("").trim().to_string())
            .filter(|l| !l.is_empty() && !l.starts_with("kind") && !l.starts_with("port"))
            .collect()
    };
    assert_eq!(settings(DEMO_GALIL_TOML), settings(DEMO_TOML));
}

#[test]
fn a_galil_board_is_refused_on_the_simulated_clock() {
    let emulator = PtyEmulator::spawn(PtyOptions::default()).expect("a pseudo-terminal");
    let lab = lab_on(&emulator);
    let options = RunOptions {
        duration: Some(Duration::from_millis(100)),
        ..RunOptions::default()
    };
    let e = run(&lab, &options, &mut |_| {})
        .err()
        .expect("a galil board cannot run on a simulated clock");
    assert!(e.to_string().contains("real-time clock"), "{e}");
}

#[test]
fn the_slave_puma_runs_on_the_emulated_galil_and_reads_its_encoders() {
    let _one_at_a_time = REAL_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let emulator = PtyEmulator::spawn(PtyOptions::default()).expect("a pseudo-terminal");
    let model = puma200();
    let start = start_pose(&model);
    // Jog every joint JOG_RAD away from the start pose: counts = JOG_RAD x counts per radian
    // (negative on the joints with a negative gear ratio).
    let mut counts = [0i64; 6];
    for (j, c) in counts.iter_mut().enumerate() {
        *c = (JOG_RAD * model.counts_per_radian(j)).round() as i64;
        assert!(c.abs() > 100, "joint {j}: {c} counts");
    }
    jog_to(emulator.path(), &counts);

    let lab = lab_on(&emulator);
    let out = run_real_time(&lab, 3, &mut |_| {});
    let r = report(&out);
    eprintln!("{}", serde_json::to_string_pretty(&r).unwrap_or_default());

    // The run completed: about 3000 slave ticks (a few may be late under load, none missing).
    assert!(out.slave.len() > 2_500, "slave ticks: {}", out.slave.len());
    assert!(
        out.master.len() > 2_500,
        "master ticks: {}",
        out.master.len()
    );
    assert!(r.faults.is_empty(), "faults: {:?}", r.faults);

    // The first slave sample is the emulator's encoders, in radians: the start pose + the jog.
    let first = &out.slave[0].telemetry;
    for j in 0..6 {
        let expected = start[j] + counts[j] as f64 / model.counts_per_radian(j);
        assert!(
            (first.q[j] - expected).abs() < 1e-3,
            "joint {j}: read {} rad, the emulator is at {} counts = {expected} rad",
            first.q[j],
            counts[j]
        );
        assert!(
            (first.q[j] - start[j]).abs() > 0.5 * JOG_RAD,
            "joint {j} did not see the jog"
        );
    }

    // The slave ran (controller active, following the master) with no simulated plant behind
    // it: no ground truth, no wrist sensor.
    let running = out
        .slave
        .iter()
        .filter(|s| s.telemetry.state == SafetyState::Running)
        .count();
    assert!(running > 2_000, "running ticks: {running}");
    assert!(out.slave.iter().all(|s| s.truth.is_none()));
    assert!(out.master.iter().all(|s| s.truth.is_some()));
    assert_eq!(r.contact.sensed_force_n, 0.0);
    assert!(r.energy.growth_ratio.is_finite() && r.contact.display_error_pct.is_finite());

    // It followed the master: the measured tool stays near its reference (the emulator is a
    // generic motor per axis, not a PUMA, so looser than the sim board's 2 mm).
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

    // The board exchanged with the emulator all along.
    let link = out
        .info
        .slave_link
        .as_ref()
        .expect("the slave is on a galil board");
    eprintln!(
        "galil link: {} cycles, mean {:.0} Hz, last window {:.0} Hz",
        link.cycles(),
        link.mean_exchange_rate_hz(),
        link.exchange_rate_hz()
    );
    assert!(link.mean_exchange_rate_hz() > 0.0 && link.exchange_rate_hz() > 0.0);
    assert!(!link.faulted());
}

#[test]
fn unplugging_the_galil_board_mid_run_faults_the_slave_into_a_safe_state() {
    let _one_at_a_time = REAL_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let emulator = PtyEmulator::spawn(PtyOptions::default()).expect("a pseudo-terminal");
    let lab = lab_on(&emulator);
    let unplug_after = Duration::from_millis(1_500);
    let mut unplugged = false;
    let out = run_real_time(&lab, 3, &mut |p| {
        if !unplugged && p.elapsed >= unplug_after {
            emulator.unplug();
            unplugged = true;
        }
    });
    assert!(unplugged, "the run ended before the unplug");
    let r = report(&out);
    eprintln!("faults: {:?}\nevents: {:?}", r.faults, r.safety_events);

    // Running before the unplug, faulted on a board read after it, and faulted to the end.
    let t = |s: &penelope_supervisor::lab::run::LabSample| s.telemetry.time - out.info.start;
    let before = out
        .slave
        .iter()
        .filter(|s| t(s) < unplug_after && s.telemetry.state == SafetyState::Running)
        .count();
    assert!(before > 1_000, "running ticks before the unplug: {before}");
    let last = &out.slave.last().expect("slave samples").telemetry;
    assert_eq!(last.state, SafetyState::Fault);
    assert!(
        matches!(last.fault, Some(FaultCause::BoardRead(_))),
        "fault: {:?}",
        last.fault
    );
    let first_fault = out
        .slave
        .iter()
        .find(|s| s.telemetry.state == SafetyState::Fault)
        .map(t)
        .expect("a fault");
    assert!(
        first_fault >= unplug_after,
        "faulted at {first_fault:?}, before the unplug"
    );
    assert!(
        out.slave
            .iter()
            .filter(|s| t(s) >= first_fault)
            .all(|s| s.telemetry.state == SafetyState::Fault),
        "the fault latches"
    );
    assert_eq!(r.faults.len(), 1, "{:?}", r.faults);
    assert!(r.faults[0].starts_with("slave"), "{:?}", r.faults);
    assert!(out.info.slave_link.as_ref().is_some_and(|l| l.faulted()));
    // The master is untouched by the slave's board: it ran to the end.
    assert!(
        out.master.len() > 2_500,
        "master ticks: {}",
        out.master.len()
    );
}

fn galil_entry(port: &str, axes: Option<Vec<u8>>) -> BoardConfig {
    BoardConfig {
        kind: BoardKind::Galil,
        robot: "puma".into(),
        axes,
        dac_bits: 16,
        port: Some(port.into()),
        baud: 115_200,
    }
}

#[test]
fn a_bad_axis_map_or_a_missing_port_is_a_typed_error() {
    let model = puma200();
    let start = start_pose(&model);
    let now = penelope_hal::Timestamp::ZERO;
    for axes in [
        vec![0, 1, 2],
        vec![0, 1, 2, 3, 4, 4],
        vec![0, 1, 2, 3, 4, 9],
    ] {
        let e = galil_board(
            &galil_entry("/nonexistent/tty", Some(axes.clone())),
            &model,
            &start,
            now,
        )
        .err()
        .expect("refused");
        assert!(matches!(e, GalilSetupError::Invalid(_)), "{axes:?}: {e}");
    }
    let e = galil_board(&galil_entry("/nonexistent/tty", None), &model, &start, now)
        .err()
        .expect("no such port");
    assert!(matches!(e, GalilSetupError::Open { .. }), "{e}");
}

#[test]
fn joints_are_read_from_their_mapped_axes() {
    let emulator = PtyEmulator::spawn(PtyOptions::default()).expect("a pseudo-terminal");
    // Axis k at 1000 (k + 1) counts; joint j on axis 5 - j.
    let counts: [i64; 6] = core::array::from_fn(|k| 1_000 * (k as i64 + 1));
    jog_to(emulator.path(), &counts);
    let model = puma200();
    let start = start_pose(&model);
    let entry = galil_entry(
        &emulator.path().display().to_string(),
        Some(vec![5, 4, 3, 2, 1, 0]),
    );
    let setup = galil_board(&entry, &model, &start, penelope_hal::Timestamp::ZERO)
        .expect("opens the emulator");
    for j in 0..6 {
        let b = setup.bindings[j];
        assert_eq!(usize::from(b.axis), 5 - j);
        assert_eq!(b.counts_per_radian, model.counts_per_radian(j));
        let expected = start[j] + counts[5 - j] as f64 / model.counts_per_radian(j);
        assert!(
            (setup.measured[j] - expected).abs() <= 1.0 / b.counts_per_radian.abs(),
            "joint {j}: {} vs {expected}",
            setup.measured[j]
        );
    }
    assert!(setup.monitor.cycles() > 0);
}
