//! A wrist sensor's fault on the slave's node reaches the master's display on another node
//! within two communication periods: the demo's two-node system (`config/demo-two-nodes.toml`)
//! on the real-time clock, its slave's wrist sensor a `sensor/netft` against the Net F/T
//! emulator, the two nodes linked over the data plane on loopback.
//!
//! The chain: the slave's loop reads the fault (the next record, then its next tick), rings its
//! communication thread, which sends its sample at once, marked urgent; the datagram wakes the
//! master's communication thread, which hands it to the master's loop at once; the master's loop
//! applies it at its next tick. Without the urgent path each communication thread would add up
//! to a period of its own (measured before: up to 4.7 ms on one node).

mod sensor_fault;

use std::time::Duration;

use penelope_drivers::netft::Status;
use penelope_drivers::netft::emulator::{EmulatorConfig, NetFtEmulator};
use penelope_hal::Timestamp;
use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::runs::report::report;
use penelope_supervisor::runs::{RunOptions, run};
use penelope_supervisor::system::SystemFile;
use penelope_testkit::net::free_udp_port;
use sensor_fault::assert_master_let_go;

/// The force the emulated transducer feels all along, N (along the sensor's z).
const LOAD_N: f64 = 8.0;
/// How long the injected fault lasts.
const FAULT_FOR: Duration = Duration::from_millis(150);

/// The two-node demo on free ports, its wrist sensor a Net F/T at `sensor`.
fn two_nodes_with_net_ft(sensor: std::net::SocketAddr) -> String {
    let text = include_str!("../../config/demo-two-nodes.toml");
    let start = text.find("[sensors.wrist]\n").expect("the wrist sensor");
    let end = start + text[start..].find("\n[").expect("a section after it");
    let wrist = format!(
        "[sensors.wrist]\nnode = \"slave\"\nkind = \"netft\"\naddress = \"{sensor}\"\n\
         counts_per_force = 1000000.0\ncounts_per_torque = 1000000.0\ntimeout_ms = 20\n\
         max_gap = 4\nbias_on_start = false\n"
    );
    format!("{}{wrist}{}", &text[..start], &text[end..])
        .replace("127.0.0.1:7410", &format!("127.0.0.1:{}", free_udp_port()))
        .replace("127.0.0.1:7420", &format!("127.0.0.1:{}", free_udp_port()))
}

#[test]
fn a_sensor_fault_on_the_slaves_node_zeroes_the_masters_display_within_two_comm_periods() {
    let ft = NetFtEmulator::spawn(EmulatorConfig::default(), |_| {
        [0.0, 0.0, LOAD_N, 0.0, 0.0, 0.0]
    })
    .unwrap();
    let file = SystemFile::parse(&two_nodes_with_net_ft(ft.local_addr())).unwrap();
    let options = RunOptions {
        duration: Some(Duration::from_secs(4)),
        clock: ClockMode::RealTime,
        ..RunOptions::default()
    };
    // The fault once the master has displayed the load for 300 ms of the run's progress
    // reports, for FAULT_FOR; then healthy again.
    let mut displayed_since: Option<Duration> = None;
    let mut fault: Option<(Timestamp, Duration)> = None;
    let out = run(&file, &options, &mut |p| match fault {
        None if p.commanded_force > 1.0 => {
            let since = *displayed_since.get_or_insert(p.elapsed);
            if p.elapsed >= since + Duration::from_millis(300) {
                ft.faults().status(Status::ERROR | 0x20);
                let at = ft.faults().injected_at().expect("the injection's time");
                fault = Some((at, p.elapsed));
            }
        }
        None => displayed_since = None,
        Some((_, from)) if p.elapsed >= from + FAULT_FOR => ft.faults().clear(),
        Some(_) => {}
    })
    .expect("the two-node demo with a net f/t runs");
    let (fault_at, _) = fault.expect("the master never displayed the load");
    let r = report(&out);
    assert!(r.faults.is_empty(), "faults: {:?}", r.faults);

    let t_com = Duration::from_micros(2000);
    let two_nodes = "two nodes";
    assert_master_let_go(&out, fault_at, 1.0, t_com * 2, FAULT_FOR / 2, two_nodes);
}
