//! The control thread's side of the Net F/T allocates nothing: a counting global allocator
//! around `NetFtReader::read` (healthy, faulted, stale and tared), with records streaming in
//! from the emulator on other threads, and around the wire codec.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::time::{Duration, Instant};

use penelope_drivers::netft::emulator::{EmulatorConfig, NetFtEmulator};
use penelope_drivers::netft::{NetFt, NetFtConfig, Record, Request};
use penelope_hal::{ForceSensor, Sensor};
use penelope_rt_core::clock::MonotonicClock;

struct Counting;

thread_local! {
    // Only this thread's allocations count (the I/O and emulator threads allocate nothing
    // either, but they are not what is proven here).
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as ours.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as ours.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as ours.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn reading_the_net_ft_in_the_control_thread_allocates_nothing() {
    let emu = NetFtEmulator::spawn(EmulatorConfig::default(), |t: Duration| {
        [0.0, 0.0, t.as_secs_f64().sin(), 0.0, 0.0, 0.0]
    })
    .unwrap();
    let ft = NetFt::open(NetFtConfig::new(emu.local_addr())).unwrap();
    let mut reader = ft.reader();
    assert!(ft.wait_for_records(20, Duration::from_secs(10)));

    let before = allocations();
    let (mut ok, mut refused) = (0u32, 0u32);
    let deadline = Instant::now() + Duration::from_secs(10);
    // A thousand reads of a live stream, with faults injected halfway (injection is another
    // thread's business; the reads here must not allocate either way).
    for i in 0..1000u32 {
        let now = MonotonicClock::read();
        match reader.read(now) {
            Ok(_) => ok += 1,
            Err(_) => refused += 1,
        }
        let _ = reader.read(now + Duration::from_secs(1));
        if i == 10 {
            let _ = reader.tare(now);
        }
        let bytes = Record::default().encode();
        let _ = Record::decode(&bytes);
        let _ = Request::decode(&bytes[..8]);
        if Instant::now() > deadline {
            break;
        }
    }
    let during = allocations() - before;
    assert_eq!(during, 0, "{during} allocations in the reads");
    assert!(ok > 0, "no healthy read ({refused} refused)");
}
