//! `sensor/netft` as an object of the creator, against the Net F/T emulator on loopback:
//! configure opens the stream and waits for its first record, `describe` shows the driver's
//! counters, `read` and `bias` reach the box, probes are refused, cleanup stops the stream; a
//! bad configuration, an absent box and the simulated clock are typed refusals.

use std::time::Duration;

use penelope_drivers::netft::emulator::{EmulatorConfig, NetFtEmulator};
use penelope_hal::Transition;
use penelope_protocol::proto::{CallError, Method, PoseMsg, Reply, SensorMethod, WireError};
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::{Creator, CreatorConfig};

mod common;

use common::*;

#[test]
fn a_net_ft_object_streams_reads_biases_and_stops() {
    let emu = NetFtEmulator::spawn(
        EmulatorConfig {
            noise: [0.0, 0.0],
            ..EmulatorConfig::default()
        },
        |_t: Duration| [1.0, -2.0, 3.0, 0.1, 0.0, -0.1],
    )
    .unwrap();
    let c = creator();
    let (s, _rx) = session(1);
    let config = format!(
        "address = \"{}\"\ncounts_per_force = 1000000.0\ncounts_per_torque = 1000000.0\ntimeout_ms = 1000",
        emu.local_addr()
    );
    create(&c, &s, "sensor/netft", "ft", &config);
    // Not configured: nothing to read.
    assert!(matches!(
        call(&c, &s, ("ft", Method::Sensor(SensorMethod::Read))),
        Err(WireError::Call(CallError::NotReady(_)))
    ));
    lifecycle(&c, &s, "ft", Transition::Configure).expect("the emulator answers");
    assert!(emu.counters().streaming);

    // The load plus the transducer's offset, calibrated (offset and load as configured).
    let Ok(Reply::Wrench(w)) = call(&c, &s, ("ft", Method::Sensor(SensorMethod::Read))) else {
        panic!("read");
    };
    let off = EmulatorConfig::default().offset;
    for (i, (got, want)) in w.force.iter().zip([1.0, -2.0, 3.0]).enumerate() {
        assert!((got - (want + off[i])).abs() < 1e-5, "F{i}: {got}");
    }
    // The box's software bias zeroes it.
    call(&c, &s, ("ft", Method::Sensor(SensorMethod::Bias))).unwrap();
    wait_for("the emulator's bias", Duration::from_secs(5), || {
        emu.counters().biases == 1
    });
    wait_for("a biased reading", Duration::from_secs(5), || {
        matches!(
            call(&c, &s, ("ft", Method::Sensor(SensorMethod::Read))),
            Ok(Reply::Wrench(w)) if w.force.iter().all(|f| f.abs() < 1e-5)
        )
    });

    // describe shows where and how the stream goes.
    let Ok(Reply::Object(info)) = call(&c, &s, ("ft", Method::Describe)) else {
        panic!("describe");
    };
    let line = |k: &str| {
        info.relations
            .iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.clone())
            .unwrap_or_default()
    };
    assert_eq!(line("address"), emu.local_addr().to_string());
    assert!(line("stream").contains("0 missed"), "{}", line("stream"));

    // A probe is a virtual sensor's business.
    let probe = SensorMethod::Measure {
        pose: PoseMsg::from(&penelope_hal::Pose::identity()),
        velocity: [0.0; 3],
    };
    assert!(matches!(
        call(&c, &s, ("ft", Method::Sensor(probe))),
        Err(WireError::Call(CallError::Unsupported { .. }))
    ));

    // Cleanup stops the stream (a stop request to the box).
    lifecycle(&c, &s, "ft", Transition::Cleanup).unwrap();
    wait_for("the stream to stop", Duration::from_secs(5), || {
        !emu.counters().streaming
    });
}

#[test]
fn bad_configurations_an_absent_box_and_the_simulated_clock_are_typed_refusals() {
    let c = creator();
    let (s, _rx) = session(1);
    for bad in [
        "",
        "address = \"not an address\"",
        "address = \"127.0.0.1:49152\"\ncounts_per_force = 0.0",
        "address = \"127.0.0.1:49152\"\ncounts_per_torque = nan",
        "address = \"127.0.0.1:49152\"\ntimeout_ms = 0",
        "address = \"127.0.0.1:49152\"\ncolour = \"red\"",
    ] {
        let e = WireError::from(c.create("sensor/netft", "ft", bad).unwrap_err());
        assert!(
            matches!(e, WireError::Call(CallError::BadConfig { .. })),
            "{bad:?}: {e:?}"
        );
    }
    // Nobody answers on this port: configure says so, and the object stays unconfigured.
    let silent = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let config = format!("address = \"{}\"", silent.local_addr().unwrap());
    create(&c, &s, "sensor/netft", "ft", &config);
    let e = lifecycle(&c, &s, "ft", Transition::Configure).unwrap_err();
    assert!(
        matches!(&e, WireError::Call(CallError::Device(m)) if m.contains("no RDT record")),
        "{e:?}"
    );

    let mut config = CreatorConfig::new("lab");
    config.clock = ClockMode::Simulated;
    let sim = Creator::new(config);
    let e = WireError::from(
        sim.create("sensor/netft", "ft", "address = \"127.0.0.1:49152\"")
            .unwrap_err(),
    );
    assert!(
        matches!(&e, WireError::Call(CallError::Unsupported { method, .. }) if method.contains("simulated clock")),
        "{e:?}"
    );
}

/// A Net F/T box that reboots under a node (its RDT sequence starts again at 0) is read again
/// within a second: the node's `sensor/netft` takes the new sequence instead of refusing it as
/// out of order.
#[test]
fn a_net_ft_box_rebooted_under_a_node_is_read_again_within_a_second() {
    let quiet = EmulatorConfig {
        noise: [0.0, 0.0],
        ..EmulatorConfig::default()
    };
    let emu = NetFtEmulator::spawn(quiet, |_t: Duration| [0.0, 0.0, 5.0, 0.0, 0.0, 0.0]).unwrap();
    let address = emu.local_addr();
    let c = creator();
    let (s, _rx) = session(1);
    let config = format!(
        "address = \"{address}\"\ncounts_per_force = 1000000.0\ncounts_per_torque = 1000000.0"
    );
    create(&c, &s, "sensor/netft", "ft", &config);
    lifecycle(&c, &s, "ft", Transition::Configure).expect("the emulator answers");
    let off = EmulatorConfig::default().offset;
    let force_z = || match call(&c, &s, ("ft", Method::Sensor(SensorMethod::Read))) {
        Ok(Reply::Wrench(w)) => Some(w.force[2] - off[2]),
        _ => None,
    };
    wait_for("the first box's 5 N", Duration::from_secs(10), || {
        force_z().is_some_and(|f| (f - 5.0).abs() < 1e-4)
    });
    // Long enough that the old sequence is far ahead of the new one's (a reordering window
    // is 64 records).
    wait_for(
        "500 records of the first box",
        Duration::from_secs(30),
        || emu.counters().sent >= 500,
    );

    // The box reboots: the emulator stops and another starts on the same port, from record 0,
    // loaded differently so that its readings are told apart.
    emu.stop();
    let emu = NetFtEmulator::spawn(
        EmulatorConfig {
            bind: address,
            ..quiet
        },
        |_t: Duration| [0.0, 0.0, 7.0, 0.0, 0.0, 0.0],
    )
    .unwrap();
    let restarted = std::time::Instant::now();
    wait_for("the rebooted box's 7 N", Duration::from_secs(30), || {
        force_z().is_some_and(|f| (f - 7.0).abs() < 1e-4)
    });
    let back = restarted.elapsed();
    println!("the sensor was read again {back:?} after its box rebooted");
    assert!(back < Duration::from_secs(1), "{back:?}");
    emu.stop();
}
