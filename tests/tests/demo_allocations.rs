//! The whole demo's real-time path allocates nothing: four loops (two control, two
//! communication), the PUMA 200 and FRHC plants behind their simulated boards, inverse
//! kinematics, the teleop channels, the force sensor and the bilateral laws, over 100,000
//! control ticks per robot, including the clutch, contact and tapping phases.
//!
//! The simulated clock runs every loop on this test's thread; the counting allocator counts
//! every allocation of the process, so this binary holds this one test only.

use std::time::Duration;

use penelope_supervisor::lab::LabConfig;
use penelope_supervisor::lab::run::{ClockMode, RunOptions, run};
use penelope_tests::{CountingAllocator, allocations};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

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
        let now = allocations();
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
