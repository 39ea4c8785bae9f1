//! A one-node channel's delay line allocates and frees nothing per sample: a counting global
//! allocator watches 100,000 samples go through delay, jitter, loss, duplication and
//! reordering into the receiving cell (the communication thread's work each tick).

use penelope_hal::{CartesianReference, Pose, Reference, Timestamp, Twist};
use penelope_rt_core::cell::{Fresh, latest};
use penelope_rt_core::teleop::TeleopSample;
use penelope_runtime::dataplane::faults::FaultConfig;
use penelope_runtime::objects::delay_line::DelayLine;
use penelope_testkit::alloc::{CountingAllocator, counted};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

#[test]
fn a_hundred_thousand_samples_through_every_fault_allocate_nothing() {
    let config = FaultConfig {
        delay_ms: 50.0,
        jitter_ms: 20.0,
        loss: 0.1,
        duplicate: 0.1,
        reorder: 0.1,
        ..FaultConfig::default()
    };
    let mut line = DelayLine::new(&config, 5).expect("a valid configuration");
    let (mut send, mut receive) = latest::<TeleopSample>();
    // Ticks after which the receiving end found a new sample.
    let mut delivered = 0u64;
    let ((), allocs, frees) = counted(|| {
        for k in 1..=100_000u64 {
            let sample = TeleopSample::new(
                k,
                Timestamp::from_nanos(k * 2_000_000),
                Reference::Cartesian(CartesianReference {
                    pose: Pose::translation(k as f64 * 1e-6, 0.0, 0.0),
                    twist: Twist::default(),
                }),
            );
            line.send(sample, &mut send);
            if let Fresh::New(_) = receive.read() {
                delivered += 1;
            }
        }
    });
    let c = line.counters();
    println!(
        "delay line: {c:?}, {delivered} new in the cell, capacity {}",
        line.capacity()
    );
    assert_eq!((allocs, frees), (0, 0), "the delay line allocated or freed");
    assert_eq!(c.dropped_capacity, 0, "the queue is sized for the delay");
    assert!(c.dropped_loss > 5_000 && c.duplicated > 5_000 && c.reordered > 5_000);
    // Every sample not lost comes out (duplicates too); the cell keeps the newest of a tick's.
    assert_eq!(
        c.delivered + line.in_flight() as u64,
        c.sent - c.dropped_loss + c.duplicated
    );
    assert!(delivered > 50_000, "{delivered} ticks saw a new sample");
}
