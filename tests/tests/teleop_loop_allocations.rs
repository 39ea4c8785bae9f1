//! The teleoperation loops a node builds allocate nothing: both control tasks (the FRHC pushed
//! by the scripted hand under force display, the PUMA 200 under slave tracking against a wall,
//! with its sensor cell) and both communication tasks (the two ends of the channel), built by
//! the creator exactly as `activate` builds them and stepped here on a simulated clock for
//! 100,000 control ticks each; then again with the channel's delay line each way (`faults`);
//! then with the FRHC on its FPGA board (`board/fpga`: the board's bit-exact kinematics and
//! force transformation in the master's law, its command delay on the plant); then with
//! Lawrence's four-channel halves (both master channels, and the slave's local force feedback).
//!
//! The counting allocator counts the allocations of this test's thread (where the loops are
//! stepped); this binary holds this one test only.

use std::time::Duration;

use penelope_hal::{Frame, Timestamp, Wrench};
use penelope_rt_core::cell::Stamped;
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_testkit::alloc::CountingAllocator;
use penelope_tests::papers_task::connect_and_configure;
use penelope_tests::{assert_pair_ran, step_teleop_pair};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn a_hundred_thousand_teleoperation_ticks_allocate_nothing() {
    // The channel as cells, and through its delay line each way (delay, jitter, loss); the
    // FRHC on a simulated board, then on its FPGA board.
    let classic = (
        "controller/force-display",
        "",
        "controller/slave-tracking",
        "",
    );
    for (frhc_board, faults, laws) in [
        ("board/sim", "", classic),
        (
            "board/sim",
            "\nfaults = { delay_ms = 20.0, jitter_ms = 5.0, loss = 0.01 }",
            classic,
        ),
        ("board/fpga", "", classic),
        (
            "board/sim",
            "",
            (
                "controller/four-channel-master",
                "c2 = 1.0\nc4 = 0.5",
                "controller/four-channel-slave",
                "c5 = 0.5",
            ),
        ),
    ] {
        ticks_allocate_nothing(frhc_board, faults, laws);
    }
}

/// The task with the FRHC on `frhc_board`, `faults` added to the channel's configuration, and
/// the laws' halves `(master kind, its keys, slave kind, its keys)`, stepped 100,000 ticks.
fn ticks_allocate_nothing(frhc_board: &str, faults: &str, laws: (&str, &str, &str, &str)) {
    let mut config = CreatorConfig::new("alloc");
    config.rt.priority = None;
    let c = Creator::new(config);
    let wall = "[[shapes]]\nkind = \"plane\"\npoint = [0, 0, 0.1]";
    for (kind, name, cfg) in [
        ("robot/frhc", "frhc", ""),
        (frhc_board, "frhc-io", ""),
        ("sensor/operator-hand", "hand", "robot = \"frhc\""),
        ("robot/puma200", "puma", ""),
        ("board/sim", "puma-io", wall),
        ("sensor/virtual", "wrist", wall),
        (
            "trajectory/teleop",
            "link",
            &format!("master = \"frhc\"\nslave = \"puma\"{faults}"),
        ),
        (laws.0, "display", laws.1),
        (laws.2, "follow", laws.3),
    ] {
        c.create(kind, name, cfg)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    connect_and_configure(&c);
    let on_fpga = c
        .info("frhc")
        .expect("the FRHC")
        .relations
        .iter()
        .any(|(k, v)| k == "kinematics" && v.starts_with("fpga board"));
    assert_eq!(on_fpga, frhc_board == "board/fpga");
    let mut master = c.detach_loop("display").expect("the master's loop builds");
    let mut slave = c.detach_loop("follow").expect("the slave's loop builds");
    let mut wrench = slave.wrench.take().expect("a sensor is bound");
    // What the sensor feed does each period, without its thread; under slave tracking silent
    // for 200 ms once, so that the slave's loop notes a sensor error, rings its communication
    // thread, and the urgent sample crosses to the master's early wake (a four-channel slave
    // needs its sensor: without it, it faults, as it should).
    let from = Timestamp::from_nanos(50_000_000_000);
    let silent = from..from + Duration::from_millis(200);
    let fail_once = laws.2 == "controller/slave-tracking";
    let mut feed = |now: Timestamp| {
        if fail_once && silent.contains(&now) {
            return;
        }
        wrench.write(Stamped {
            stamp: now,
            value: Wrench::zero(Frame::Base),
        });
    };
    // Warm-up: the first ticks start the channels and anchor the mapping.
    step_teleop_pair(&mut master, &mut slave, 1..1001, &mut feed);
    let allocated = step_teleop_pair(&mut master, &mut slave, 1001..101_001, &mut feed);
    assert_eq!(
        allocated, 0,
        "the teleoperation loops ({frhc_board}, {faults:?}, {laws:?}) allocated or freed \
         {allocated} times"
    );
    assert_pair_ran(&master, &slave, 101_000, 50_000);
}
