//! Event-driven handoff (issue 36) keeps its rates bounded and allocates nothing: the two
//! teleoperation loops a node builds (FRHC under force display, PUMA 200 under slave tracking
//! against a wall), stepped on a simulated clock with a flood of early wakes before and after
//! every control tick (what a doorbell rung many times, or a socket that stays readable, gives
//! the communication threads), send at most one sample per control tick; with `handoff =
//! "periodic"` one per communication period, however often the threads wake.
//!
//! The counting allocator counts the allocations of this test's thread (where the loops are
//! stepped).

use std::time::Duration;

use penelope_hal::{Frame, Timestamp, Wrench};
use penelope_rt_core::cell::Stamped;
use penelope_runtime::objects::{CreatorConfig, DetachedLoop};
use penelope_testkit::alloc::{CountingAllocator, allocations};
use penelope_tests::papers_task::wall_pair;
use penelope_tests::{assert_pair_ran, step_teleop_pair};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

/// Early wakes given each communication thread before and after each control tick.
const FLOOD: usize = 25;

/// The master's and the slave's loops of the demo's task, the channel's `handoff` as given.
fn pair(handoff: &str) -> (DetachedLoop, DetachedLoop) {
    let mut config = CreatorConfig::new("handoff");
    config.rt.priority = None;
    let c = wall_pair(config, &format!("handoff = \"{handoff}\""));
    let master = c.detach_loop("display").expect("the master's loop builds");
    let slave = c.detach_loop("follow").expect("the slave's loop builds");
    (master, slave)
}

/// Samples both ends have sent.
fn sent(master: &DetachedLoop, slave: &DetachedLoop) -> (u64, u64) {
    let of = |d: &DetachedLoop| d.comm.teleop_samples_sent().expect("a teleoperation end");
    (of(master), of(slave))
}

/// Steps the pair over control ticks `ticks` (1 ms apart; communication ticks every 2 ms), each
/// communication thread woken [`FLOOD`] times before and after each control tick; returns the
/// allocations made.
fn flood(
    master: &mut DetachedLoop,
    slave: &mut DetachedLoop,
    ticks: std::ops::Range<u64>,
    feed: &mut dyn FnMut(Timestamp),
) -> u64 {
    let before = allocations();
    for i in ticks {
        let now = Timestamp::from_nanos(i * 1_000_000);
        if i.is_multiple_of(2) {
            feed(now);
            master.comm.tick(now);
            slave.comm.tick(now);
        }
        for k in 0..FLOOD as u64 {
            master.comm.early(now + Duration::from_nanos(k));
            slave.comm.early(now + Duration::from_nanos(k));
        }
        master.control.tick(now);
        slave.control.tick(now);
        for k in 0..FLOOD as u64 {
            let at = now + Duration::from_micros(100) + Duration::from_nanos(k);
            master.comm.early(at);
            slave.comm.early(at);
        }
        while master.telemetry.pop().is_some() {}
        while slave.telemetry.pop().is_some() {}
    }
    allocations() - before
}

/// Runs the pair with `handoff` for 10,000 control ticks under the flood; returns the samples
/// each end sent over them.
fn sends_under_a_flood(handoff: &str) -> (u64, u64) {
    let (mut master, mut slave) = pair(handoff);
    let mut wrench = slave.wrench.take().expect("a sensor is bound");
    let mut feed = |now: Timestamp| {
        wrench.write(Stamped {
            stamp: now,
            value: Wrench::zero(Frame::Base),
        });
    };
    // Warm-up: the channels start and the mapping anchors.
    step_teleop_pair(&mut master, &mut slave, 1..1001, &mut feed);
    // The warm-up's last sample goes out (event-driven) before the count starts: from here on
    // every sample sent is one of the counted ticks'.
    let after = Timestamp::from_nanos(1000 * 1_000_000) + Duration::from_micros(100);
    master.comm.early(after);
    slave.comm.early(after);
    let (m0, s0) = sent(&master, &slave);
    let allocated = flood(&mut master, &mut slave, 1001..11_001, &mut feed);
    let (m1, s1) = sent(&master, &slave);
    assert_eq!(
        allocated, 0,
        "{handoff} handoff under a flood of early wakes allocated or freed {allocated} times"
    );
    assert_pair_ran(&master, &slave, 11_000, 5_000);
    (m1 - m0, s1 - s0)
}

#[test]
fn event_handoff_sends_each_sample_once_however_often_the_thread_wakes() {
    let ticks = 10_000;
    let (master, slave) = sends_under_a_flood("event");
    eprintln!(
        "event handoff: {master} and {slave} samples sent over {ticks} control ticks, \
         {} early wakes per thread",
        2 * FLOOD as u64 * ticks
    );
    for (side, sent) in [("master", master), ("slave", slave)] {
        // At most one send per control tick; every tick's sample sent (the doorbell after it).
        assert!(
            sent <= ticks,
            "{side}: {sent} sends over {ticks} control ticks"
        );
        assert!(
            sent >= ticks - 1,
            "{side}: {sent} sends over {ticks} control ticks"
        );
    }
}

#[test]
fn periodic_handoff_sends_once_per_communication_period_however_often_the_thread_wakes() {
    let ticks = 10_000;
    let (master, slave) = sends_under_a_flood("periodic");
    eprintln!("periodic handoff: {master} and {slave} samples sent over {ticks} control ticks");
    for (side, sent) in [("master", master), ("slave", slave)] {
        // One per communication tick (2 ms): the early wakes send nothing (no safety event).
        assert_eq!(sent, ticks / 2, "{side}");
    }
}
