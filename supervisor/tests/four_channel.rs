//! Lawrence's four channels (`controller/four-channel-master`, `controller/four-channel-slave`)
//! on the demo's task: set as force-position or as position-error, the whole system runs the
//! same telemetry as the classical halves, tick for tick, to the last bit (both robots, plant
//! truth included); with a handle sensor on the master, the slave's `C_3` pushes the wall with
//! the operator's force.

use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::runs::{DEMO_SYSTEM, RunOptions, RunOutput, run};
use penelope_supervisor::system::SystemFile;

/// The demo with its active master half, `controllers.display`, of kind `kind` (and `keys`).
fn with_master(kind: &str, keys: &str) -> RunOutput {
    run_text(&DEMO_SYSTEM.replacen(
        "kind = \"force-display\"",
        &format!("kind = \"{kind}\"\n{keys}"),
        1,
    ))
}

/// The demo with its active slave half, `controllers.follow`, of kind `kind` (and `keys`).
fn with_slave(system: &str, kind: &str, keys: &str) -> RunOutput {
    run_text(&system.replacen(
        "kind = \"slave-tracking\"",
        &format!("kind = \"{kind}\"\n{keys}"),
        1,
    ))
}

/// The demo with a force sensor on the FRHC's handle, read by the master's loop: the master's end
/// then sends the operator's wrench beside its pose.
fn with_handle_sensor() -> String {
    let sensor = "[sensors.handle]\nkind = \"virtual\"\nrobot = \"frhc\"\n\n[robots.frhc]";
    DEMO_SYSTEM.replacen("[robots.frhc]", sensor, 1).replacen(
        "kind = \"force-display\"",
        "kind = \"force-display\"\nsensor = \"handle\"",
        1,
    )
}

fn run_text(text: &str) -> RunOutput {
    let system = SystemFile::parse(text).expect("a valid system file");
    let options = RunOptions {
        clock: ClockMode::Simulated,
        ..RunOptions::default()
    };
    run(&system, &options, &mut |_| {}).expect("the system runs")
}

/// Every tick of both robots equal. `channel_energy` is left out: the classical force display
/// runs the channel's two-port observer, the general law does not.
fn assert_same(a: &RunOutput, b: &RunOutput) {
    for (side, x, y) in [
        ("master", &a.master, &b.master),
        ("slave", &a.slave, &b.slave),
    ] {
        assert_eq!(x.len(), y.len(), "{side} ticks");
        assert!(x.len() > 19_000, "{side}: {} ticks", x.len());
        for (k, (p, q)) in x.iter().zip(y).enumerate() {
            let (mut p, mut q) = (*p, *q);
            p.sample.channel_energy = None;
            q.sample.channel_energy = None;
            assert_eq!(p, q, "{side} tick {k}");
        }
    }
    let pushed = a
        .master
        .iter()
        .filter(|t| t.sample.commanded_wrench.force.norm() > 1.0)
        .count();
    assert!(
        pushed > 1000,
        "a run that displayed nothing compares nothing: {pushed}"
    );
}

#[test]
fn set_as_force_position_it_runs_the_force_displays_task_bit_for_bit() {
    let classic = with_master("force-display", "");
    let general = with_master("four-channel-master", "c2 = 1.0\nc4 = 0.0");
    assert_same(&classic, &general);
}

#[test]
fn set_as_position_error_it_runs_the_position_error_masters_task_bit_for_bit() {
    let classic = with_master("position-error-master", "");
    let general = with_master(
        "four-channel-master",
        "c2 = 0.0\nc4 = 1.0\ndamping = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]",
    );
    assert_same(&classic, &general);
    // And both channels at once is another law: the runs part.
    let both = with_master("four-channel-master", "c2 = 1.0\nc4 = 1.0");
    assert_ne!(
        both.master[5000].sample.effort,
        classic.master[5000].sample.effort
    );
}

#[test]
fn set_as_slave_tracking_the_four_channel_slave_runs_its_task_bit_for_bit() {
    let classic = with_master("force-display", "");
    let general = with_slave(
        DEMO_SYSTEM,
        "four-channel-slave",
        "c1 = 1.0\nc3 = 0.0\nc5 = 0.0",
    );
    assert_same(&classic, &general);
}

/// The largest contact force on the slave's tool (the plant's truth) while it pushes the wall.
fn largest_contact(run: &RunOutput) -> f64 {
    run.slave
        .iter()
        .filter_map(|t| t.truth.map(|tap| tap.base_wrench.force.norm()))
        .fold(0.0, f64::max)
}

#[test]
fn with_c3_the_slave_adds_the_operators_push_and_without_a_handle_sensor_it_faults_safe() {
    let sensed = with_handle_sensor();
    let plain = with_slave(&sensed, "slave-tracking", "");
    let c3 = with_slave(&sensed, "four-channel-slave", "c3 = 1.0");
    for (name, run) in [("plain", &plain), ("c3", &c3)] {
        let faults: Vec<_> = run.slave.iter().filter_map(|t| t.sample.fault).collect();
        assert!(faults.is_empty(), "{name}: {:?}", faults.first());
    }
    // The operator's wrench crosses: while the hand pushes (the master's plant truth: the hand's
    // wrench on the handle), the slave's reference carries it divided by the force gain 0.5,
    // one communication period or so later (the sensor's low-pass and noise aside).
    let mut pushing = 0;
    let mut close = 0;
    for (m, s) in c3.master.iter().zip(&c3.slave).skip(20) {
        let hand = m.truth.expect("the master's plant truth").base_wrench.force / 0.5;
        if hand.norm() > 4.0 {
            pushing += 1;
            let sent = s.sample.commanded_wrench.force;
            if (sent - hand).norm() < 0.15 * hand.norm() {
                close += 1;
            }
        }
    }
    assert!(pushing > 1000, "the hand pushes: {pushing} ticks");
    assert!(
        close > pushing * 9 / 10,
        "the slave received the operator's wrench on {close} of {pushing} ticks"
    );
    // And C3 adds it, in the push's direction: the wall is pushed harder than by the tracking
    // alone (by little: the stiff tracking, c1 = 1, takes most of it; 32.55 N against 32.31 N).
    let (f_plain, f_c3) = (largest_contact(&plain), largest_contact(&c3));
    assert!(f_plain > 5.0, "the demo pushes the wall: {f_plain} N");
    assert!(
        f_c3 > f_plain + 0.1,
        "C3 did not push harder: {f_c3} N against {f_plain} N"
    );
    // Without a handle sensor the master sends its pose alone: C3 is a missing input, and the
    // slave's safety layer takes over (it holds) rather than push with a zero.
    let blind = with_slave(DEMO_SYSTEM, "four-channel-slave", "c3 = 1.0");
    let fault = blind.slave.iter().find_map(|t| t.sample.fault);
    assert!(fault.is_some(), "no fault without the operator's wrench");
}
