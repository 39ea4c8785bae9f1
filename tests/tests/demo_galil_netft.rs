//! The Galil demo with a Net F/T on the slave's wrist (`config/demo-galil-netft.toml`), end to
//! end: the DMC emulator on a pseudo-terminal and the Net F/T emulator on a loopback UDP port,
//! both in this process; the sensor's load is the demo's wall probed at the emulated arm's tool
//! (read from the DMC's encoders). The run goes through the node runtime on the real-time
//! clock, with `sensor/netft` in the slave's loop.
//!
//! One run checks two things: in steady contact the master displays the wall's force within
//! the demo's 5% bound, and an error status injected mid-contact (before the report's steady
//! window) brings the master to zero force within two communication periods.

mod sensor_fault;

use std::time::{Duration, Instant};

use penelope_drivers::galil::emulator::{PtyEmulator, PtyOptions};
use penelope_drivers::model::puma200;
use penelope_drivers::netft::Status;
use penelope_drivers::netft::emulator::{
    EmulatorConfig, NetFtEmulator, ProbedContact, galil_tool_pose,
};
use penelope_drivers::sim::environment::{ContactModel, Environment, Shape};
use penelope_hal::{NamedPose, Pose, Timestamp};
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::netft::NetFtSensorConfig;
use penelope_supervisor::runs::report::report;
use penelope_supervisor::runs::{RunOptions, run};
use penelope_supervisor::system::SystemFile;
use sensor_fault::assert_master_let_go;

/// The shipped file.
const DEMO_GALIL_NETFT: &str = include_str!("../../config/demo-galil-netft.toml");
/// Its Galil device line and Net F/T address line, replaced by the emulators' in the test.
const DEVICE_LINE: &str = "device = \"/tmp/penelope-galil\"";
const ADDRESS_LINE: &str = "address = \"127.0.0.1:49152\"";

/// The demo script up to just past its steady contact (which ends at 14.5 s). The taps that
/// follow are left out: tapping a wall that does not stop the emulated arm can drive the slave
/// past a joint's velocity limit (seen once at 15.5 s), which is the safety doing its job, not
/// what these tests are about.
const WHOLE_SCRIPT: Duration = Duration::from_millis(14_800);
/// How long the injected fault lasts.
const FAULT_FOR: Duration = Duration::from_millis(150);

/// The wall of `config/demo-galil.toml`'s virtual sensor (the same model in both demos).
fn wall() -> Environment {
    let text = include_str!("../../config/demo-galil.toml");
    let file = SystemFile::parse(text).unwrap();
    let wrist = file.objects.iter().find(|o| o.name == "wrist").unwrap();
    let cfg: penelope_runtime::objects::kinds::SensorConfig =
        toml::from_str(&wrist.config).unwrap();
    let s = &cfg.shapes[0];
    Environment::new()
        .with(ContactModel {
            shape: Shape::Plane {
                point: s.point.into(),
                normal: nalgebra::Unit::new_normalize(s.normal.into()),
            },
            stiffness: s.stiffness,
            damping: s.damping,
        })
        .unwrap()
}

#[test]
fn the_galil_demo_with_a_net_ft_displays_the_wall_and_drops_to_zero_on_a_sensor_fault() {
    let dmc = PtyEmulator::spawn(PtyOptions::default()).expect("a pseudo-terminal");
    let model = puma200();
    let zero = model.named_pose(NamedPose::Start);
    let file = SystemFile::parse(DEMO_GALIL_NETFT).unwrap();
    let wrist = file.objects.iter().find(|o| o.name == "wrist").unwrap();
    assert_eq!(wrist.kind, "sensor/netft");
    let mount: Pose = toml::from_str::<NetFtSensorConfig>(&wrist.config)
        .unwrap()
        .mount();
    let ft = NetFtEmulator::spawn(
        EmulatorConfig::default(),
        ProbedContact::new(wall(), mount, galil_tool_pose(dmc.observer(), model, zero)),
    )
    .unwrap();

    let file = the_demo_file_on_the_emulators(&dmc, &ft);
    let options = RunOptions {
        duration: Some(WHOLE_SCRIPT),
        clock: ClockMode::RealTime,
        ..RunOptions::default()
    };

    // The fault: once the wall has pushed for 300 ms without a break (mid-contact, before the
    // report's steady window, the second half of the contact phase), an error status for
    // FAULT_FOR, then healthy again. Bounded polls on the emulator's own contact force.
    let fault = std::thread::scope(|scope| {
        let injector = scope.spawn(|| a_sensor_fault_once_the_wall_pushes(&ft));
        let out = run(&file, &options, &mut |_| {}).expect("the galil demo with a net f/t runs");
        (out, injector.join().unwrap())
    });
    let (out, fault_at) = fault;
    let r = report(&out);
    eprintln!(
        "{}",
        serde_json::to_string_pretty(&r.contact).unwrap_or_default()
    );
    let emu = ft.counters();
    eprintln!("net f/t emulator: {emu:?}");
    // The sensor was read in the loop all along, at the emulator's rate, with nothing lost.
    assert!(r.faults.is_empty(), "faults: {:?}", r.faults);
    assert!(emu.sent > 10_000, "{emu:?}");

    // Steady contact: the wall's force, displayed within the demo's 5% bound.
    let c = &r.contact;
    assert!(c.samples > 500, "steady-contact ticks: {}", c.samples);
    assert!(c.sensed_force_n > 1.0, "sensed {} N", c.sensed_force_n);
    assert!(
        c.display_error_pct < 5.0,
        "the motors display {} N, {}% off the expected {} N",
        c.displayed_force_n,
        c.display_error_pct,
        c.expected_display_n
    );

    // The fault mid-contact: the master displayed a force just before it, and none from two
    // communication periods after it until it cleared. The chain: the fault reaches the
    // slave's loop with the next record (the sensor period) and its next tick (T_ctrl); the
    // loop rings its communication thread, which sends the sample at once, marked urgent; that
    // wakes the master's communication thread, which hands it on at once; the master's loop
    // applies it at its next tick (T_ctrl). 1 + 1 + 1 ms and two wake-ups: within 2 T_com.
    let fault_at: Timestamp = fault_at.expect("the slave never pressed on the wall");
    let t_com = Duration::from_micros(2000);
    let one_node = "one node (the Galil demo)";
    assert_master_let_go(&out, fault_at, 0.3, t_com * 2, FAULT_FOR - t_com, one_node);
    // The slave's loop saw the fault as sensor errors.
    let sensor_errors = out
        .slave
        .iter()
        .filter(|s| {
            s.sample
                .events
                .contains(penelope_rt_core::safety::SafetyEvent::SensorError)
        })
        .count();
    assert!(
        sensor_errors > 100,
        "slave sensor-error ticks: {sensor_errors}"
    );
}

/// The demo file with the board on `dmc`'s line and the sensor at `ft`'s address.
fn the_demo_file_on_the_emulators(dmc: &PtyEmulator, ft: &NetFtEmulator) -> SystemFile {
    assert_eq!(DEMO_GALIL_NETFT.matches(DEVICE_LINE).count(), 1);
    assert_eq!(DEMO_GALIL_NETFT.matches(ADDRESS_LINE).count(), 1);
    let text = DEMO_GALIL_NETFT
        .replace(
            DEVICE_LINE,
            // A board watchdog and a command timeout of 250 ms instead of 30 and 50: this test
            // shares a loaded host, and a watchdog trip there is not what it is about (the
            // watchdogs have their own tests).
            &format!(
                "device = \"{}\"\nwatchdog_ms = 250\ncommand_timeout_ms = 250",
                dmc.path().display()
            ),
        )
        .replace(ADDRESS_LINE, &format!("address = \"{}\"", ft.local_addr()));
    SystemFile::parse(&text).unwrap()
}

/// Once the wall has pushed for 300 ms without a break, an error status for [`FAULT_FOR`],
/// then healthy again; returns when it was injected (`None` if the wall never pushed).
fn a_sensor_fault_once_the_wall_pushes(ft: &NetFtEmulator) -> Option<Timestamp> {
    let give_up = Instant::now() + WHOLE_SCRIPT + Duration::from_secs(10);
    let mut pressing_since: Option<Instant> = None;
    loop {
        if Instant::now() > give_up {
            return None;
        }
        std::thread::sleep(Duration::from_millis(1));
        if ft.true_force_n() > 1.0 {
            let since = *pressing_since.get_or_insert_with(Instant::now);
            if since.elapsed() >= Duration::from_millis(300) {
                break;
            }
        } else {
            pressing_since = None;
        }
    }
    ft.faults().status(Status::ERROR | 0x20);
    let at = ft.faults().injected_at();
    let until = Instant::now() + FAULT_FOR;
    while Instant::now() < until {
        std::thread::sleep(Duration::from_millis(1));
    }
    ft.faults().clear();
    at
}
