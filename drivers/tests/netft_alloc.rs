//! The control thread's side of the Net F/T allocates nothing: a counting global allocator
//! around `NetFtReader::read` (healthy, faulted, stale and tared), with records streaming in
//! from the emulator on other threads, and around the wire codec.

use penelope_testkit::alloc::{CountingAllocator, allocations};
use std::time::{Duration, Instant};

use penelope_drivers::netft::emulator::{EmulatorConfig, NetFtEmulator};
use penelope_drivers::netft::{NetFt, NetFtConfig, Record, Request};
use penelope_hal::{ForceSensor, Sensor};
use penelope_rt_core::clock::MonotonicClock;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

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
