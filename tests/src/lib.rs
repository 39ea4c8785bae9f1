#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

thread_local! {
    // Const-initialised and without a destructor: reading it never allocates.
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn count() {
    // During thread teardown the slot may be gone; such calls are not the code under test.
    let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
}

/// A global allocator that forwards to the system allocator and counts every call (allocations,
/// frees and reallocations) per thread, for the tests that prove a real-time path allocates
/// nothing. A test binary installs it with `#[global_allocator]` and reads [`allocations`] around
/// code it steps on its own thread; other threads (the test harness's "running for over 60
/// seconds" notice, say) do not disturb the count. Such a binary still holds one test, so the
/// tests' set-up does not run beside it.
pub struct CountingAllocator;

// SAFETY: forwards to the system allocator unchanged; only counts calls.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocator calls counted so far by [`CountingAllocator`] on the calling thread.
pub fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

/// Steps the detached loops of a teleoperation pair over ticks `ticks` of a 1 kHz control clock
/// (communication every other tick, after `at_comm`, which plays any feed a thread would),
/// draining their telemetry as a pump would, and returns the allocator calls made meanwhile.
pub fn step_teleop_pair(
    master: &mut penelope_supervisor::objects::DetachedLoop,
    slave: &mut penelope_supervisor::objects::DetachedLoop,
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
    master: &penelope_supervisor::objects::DetachedLoop,
    slave: &penelope_supervisor::objects::DetachedLoop,
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
    c: &penelope_supervisor::objects::Creator,
    object: &str,
    method: penelope_protocol::proto::Method,
) {
    c.call_object(object, method)
        .unwrap_or_else(|e| panic!("{object}: {e}"));
}
