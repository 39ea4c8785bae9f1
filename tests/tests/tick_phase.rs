//! Tick phase (issue 36): a teleoperation channel's two control loops, started on the real
//! clock in one node, tick half a period apart on the common clock (the master at phase 0,
//! the slave at half the period), whatever instants they were started at; the common clock
//! being this node's clock plus the offset its estimate found.
//!
//! No timing is asserted: each tick's time is the executor's scheduled deadline, so where it
//! sits in the period is exact however late the loaded machine woke the thread.

use std::time::{Duration, Instant};

use penelope_hal::Transition;
use penelope_protocol::proto::Method;
use penelope_runtime::common_clock::CommonClock;
use penelope_runtime::objects::tick::TickRecord;
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_testkit::alloc::{CountingAllocator, counts};
use penelope_tests::call_object;
use penelope_tests::papers_task::wall_pair;

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

/// The control period of both loops (the kinds' default).
const PERIOD_NS: i64 = 1_000_000;

/// The demo's two teleoperation loops (FRHC under force display, PUMA 200 following against
/// a wall) in one node whose common clock is `clock`.
fn teleop_node(clock: CommonClock) -> Creator {
    let mut config = CreatorConfig::new("phase");
    config.rt.priority = None;
    config.rt.lock_memory = false;
    config.common_clock = clock;
    wall_pair(config, "")
}

/// Where each of `ticks` falls in the period of the common clock (this node's clock plus
/// `offset_ns`), ns.
fn phases(ticks: &[TickRecord], offset_ns: i64) -> Vec<i64> {
    ticks
        .iter()
        .map(|t| (t.sample.time.as_nanos() as i64 + offset_ns).rem_euclid(PERIOD_NS))
        .collect()
}

/// Starts both loops (the slave a while after the master, at no particular phase), records
/// `n` ticks of each, stops them; returns the master's and the slave's ticks.
fn run_pair(c: &Creator, n: usize) -> (Vec<TickRecord>, Vec<TickRecord>) {
    let master = c.record_ticks("display", 4 * n).expect("record the master");
    let slave = c.record_ticks("follow", 4 * n).expect("record the slave");
    call_object(c, "display", Method::Transition(Transition::Activate));
    // Started 2.345 ms later (on a loaded machine, later still): the phase it would keep.
    let started = Instant::now();
    while started.elapsed() < Duration::from_micros(2_345) {
        std::hint::spin_loop();
    }
    call_object(c, "follow", Method::Transition(Transition::Activate));
    let (mut m, mut s) = (Vec::with_capacity(4 * n), Vec::with_capacity(4 * n));
    let deadline = Instant::now() + Duration::from_secs(60);
    while (m.len() < n || s.len() < n) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
        master.drain_into(&mut m);
        slave.drain_into(&mut s);
    }
    for name in ["follow", "display"] {
        call_object(c, name, Method::Transition(Transition::Deactivate));
    }
    assert!(
        m.len() >= n && s.len() >= n,
        "{} master and {} slave ticks recorded in 60 s",
        m.len(),
        s.len()
    );
    (m, s)
}

#[test]
fn the_slave_loop_ticks_half_a_period_after_the_master_loop_on_the_common_clock() {
    // A node that is its own common clock (offset zero).
    let (master, slave) = run_pair(&teleop_node(CommonClock::own()), 500);
    let (m, s) = (phases(&master, 0), phases(&slave, 0));
    eprintln!(
        "master phase {} ns, slave phase {} ns ({} and {} ticks)",
        m[0],
        s[0],
        m.len(),
        s.len()
    );
    assert!(m.iter().all(|p| *p == 0), "master off phase 0: {m:?}");
    assert!(
        s.iter().all(|p| *p == PERIOD_NS / 2),
        "slave off half a period: {s:?}"
    );
    // Each slave tick between two consecutive master ticks sits half a period after the first.
    let times =
        |r: &[TickRecord]| -> Vec<u64> { r.iter().map(|t| t.sample.time.as_nanos()).collect() };
    let (mt, st) = (times(&master), times(&slave));
    let mut between = 0;
    for t in &st {
        let i = mt.partition_point(|m| m <= t);
        if i > 0 && i < mt.len() && mt[i] - mt[i - 1] == PERIOD_NS as u64 {
            assert_eq!(t - mt[i - 1], PERIOD_NS as u64 / 2);
            between += 1;
        }
    }
    assert!(between > 0, "no slave tick fell between two master ticks");
}

#[test]
fn the_grid_is_on_the_common_clock_when_it_is_another_hosts() {
    // The naming host's clock reads 3.7 s plus 0.25 ms ahead of this node's (one exchange
    // with no path asymmetry tells it exactly).
    let offset = 3_700_250_000i64;
    let clock = CommonClock::of_naming("127.0.0.1:9".parse().expect("an address"));
    let mut reads = [1_000_000_000i64, 1_000_100_000].into_iter();
    clock
        .exchange_with(
            || reads.next().expect("two reads"),
            || Ok((1_000_050_000 + offset, 1_000_050_000 + offset)),
        )
        .expect("the exchange is taken");
    assert_eq!(clock.estimate().offset_ns, Some(offset));
    let (master, slave) = run_pair(&teleop_node(clock), 300);
    let (m, s) = (phases(&master, offset), phases(&slave, offset));
    assert!(m.iter().all(|p| *p == 0), "master off phase 0: {m:?}");
    assert!(s.iter().all(|p| *p == PERIOD_NS / 2), "slave: {s:?}");
    // On this node's own clock, the grid is shifted by the offset (0.25 ms in the period).
    assert!(phases(&master, 0).iter().all(|p| *p == PERIOD_NS - 250_000));
}

#[test]
fn a_phased_thread_allocates_nothing_between_its_first_tick_and_its_last_even_when_it_rephases() {
    use penelope_rt_core::exec::{self, CommonOffset, Flow, PeriodicConfig, TickPhase};
    use std::sync::Arc;
    use std::sync::atomic::{AtomicU64, Ordering};
    const TICKS: u64 = 2_000;
    let offset = Arc::new(CommonOffset::new(123_456));
    let config = PeriodicConfig {
        lock_memory: false,
        hold_dma_latency: false,
        ..PeriodicConfig::new("alloc-phase", Duration::from_micros(500))
            .normal_priority()
            .tick_phase(TickPhase::new(Duration::from_micros(250), offset.clone()))
    };
    let out = Arc::new([AtomicU64::new(u64::MAX), AtomicU64::new(u64::MAX)]);
    let seen = out.clone();
    let last_deadline = Arc::new(AtomicU64::new(0));
    let last = last_deadline.clone();
    let mut first = None;
    let thread = exec::spawn(config, move |tick| {
        let since = *first.get_or_insert_with(counts);
        if tick.index % 500 == 499 {
            // A new estimate every 500 ticks: a re-phase each time.
            offset.set(offset.get() + 200_000);
        }
        if tick.index + 1 == TICKS {
            let (a, f) = counts();
            seen[0].store(a - since.0, Ordering::Relaxed);
            seen[1].store(f - since.1, Ordering::Relaxed);
            last.store(tick.deadline.as_nanos(), Ordering::Relaxed);
            Flow::Stop
        } else {
            Flow::Continue
        }
    })
    .expect("the thread starts");
    let report = thread.join().expect("the thread runs");
    assert_eq!(report.ticks, TICKS);
    let read = (
        out[0].load(Ordering::Relaxed),
        out[1].load(Ordering::Relaxed),
    );
    assert_eq!(
        read,
        (0, 0),
        "the phased thread allocated/freed (allocs, frees)"
    );
}
