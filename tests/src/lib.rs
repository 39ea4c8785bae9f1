#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

use penelope_testkit::alloc::allocations;

pub mod arm;
pub mod fixtures;
pub mod papers_task;

/// Steps the detached loops of a teleoperation pair over ticks `ticks` of a 1 kHz control clock
/// (communication every other tick, after `at_comm`, which plays any feed a thread would),
/// draining their telemetry as a pump would, and returns the allocator calls made meanwhile.
pub fn step_teleop_pair(
    master: &mut penelope_runtime::objects::DetachedLoop,
    slave: &mut penelope_runtime::objects::DetachedLoop,
    ticks: std::ops::Range<u64>,
    at_comm: &mut dyn FnMut(penelope_hal::Timestamp),
) -> u64 {
    let before = allocations();
    for i in ticks {
        let now = penelope_hal::Timestamp::from_nanos(i * 1_000_000);
        if i.is_multiple_of(2) {
            at_comm(now);
            master.comm.tick(now);
            slave.comm.tick(now);
        } else {
            // Between communication ticks, the early wake a doorbell or a socket gives the
            // threads (an urgent sample sent or handed on; otherwise nothing to do).
            master.comm.early(now);
            slave.comm.early(now);
        }
        master.control.tick(now);
        slave.control.tick(now);
        while master.telemetry.pop().is_some() {}
        while slave.telemetry.pop().is_some() {}
    }
    allocations() - before
}

/// Asserts that both loops of a pair ran `ticks` control ticks with no fault and published
/// more than `published` references.
pub fn assert_pair_ran(
    master: &penelope_runtime::objects::DetachedLoop,
    slave: &penelope_runtime::objects::DetachedLoop,
    ticks: u64,
    published: u64,
) {
    for (name, d) in [("master", master), ("slave", slave)] {
        let last = *d.control.control_loop().last_sample();
        assert_eq!(last.seq, ticks, "{name}");
        assert_eq!(
            last.state,
            penelope_rt_core::safety::SafetyState::Running,
            "{name}: {:?}",
            last.fault
        );
        assert!(d.comm.published() > published, "{name}");
    }
}

/// Calls `method` on `object` of creator `c`, panicking with the object's name on an error
/// (set-up steps of the allocation tests).
pub fn call_object(
    c: &penelope_runtime::objects::Creator,
    object: &str,
    method: penelope_protocol::proto::Method,
) {
    c.call_object(object, method)
        .unwrap_or_else(|e| panic!("{object}: {e}"));
}
