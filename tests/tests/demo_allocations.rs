//! The whole demo's real-time path allocates nothing: four loops (two control, two
//! communication), the PUMA 200 and FRHC plants behind their simulated boards, inverse
//! kinematics, the teleop channels, the force sensor and the bilateral laws, over 100,000
//! control ticks per robot, including the clutch, contact and tapping phases.
//!
//! The simulated clock runs every loop on this test's thread; the counting allocator counts
//! every allocation of the process, so this binary holds this one test only.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use penelope_supervisor::lab::LabConfig;
use penelope_supervisor::lab::run::{ClockMode, RunOptions, run};

struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

// SAFETY: forwards to the system allocator unchanged; only counts calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn one_hundred_thousand_demo_ticks_allocate_nothing() {
    let options = RunOptions {
        duration: Some(Duration::from_secs(100)),
        clock: ClockMode::Simulated,
        ..RunOptions::default()
    };
    // Between the first and the last progress report only the loops run (and the logger moves
    // samples into vectors sized for the whole run before the start).
    let mut first: Option<u64> = None;
    let mut last = 0;
    let mut reports = 0u32;
    let out = run(&LabConfig::demo(), &options, &mut |_| {
        let now = ALLOCATIONS.load(Ordering::Relaxed);
        first.get_or_insert(now);
        last = now;
        reports += 1;
    })
    .expect("the demo lab runs");
    assert!(
        out.slave.len() >= 100_000,
        "ran {} slave ticks",
        out.slave.len()
    );
    assert!(reports > 100, "progress was reported {reports} times");
    let first = first.expect("progress was reported");
    assert_eq!(
        last - first,
        0,
        "the loops allocated or freed {} times",
        last - first
    );
    // The run went through every phase: contact was made and the clutch was used.
    assert!(
        out.slave
            .iter()
            .any(|s| s.telemetry.wrench.force.norm() > 5.0),
        "contact happened"
    );
}
