//! The counting allocator sees this thread's allocations and frees, and nothing of others'.

use penelope_testkit::alloc::{CountingAllocator, allocations, counted};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

#[test]
fn the_counter_sees_this_threads_allocations_and_frees_only() {
    let (v, allocs, frees) = counted(|| {
        let v = vec![1u8; 100];
        drop(v.clone());
        v
    });
    assert_eq!(v.len(), 100);
    assert_eq!((allocs, frees), (2, 1));
    let before = allocations();
    std::thread::spawn(|| vec![0u8; 1000]).join().unwrap();
    // The spawn allocates here too (the thread's handle), but the other thread's vector is not
    // counted on this one: far fewer than the thousands a per-process count would show is not
    // the point; the vector's own allocation and free happen there.
    let ((), a, f) = counted(|| ());
    assert_eq!((a, f), (0, 0));
    assert!(allocations() >= before);
}
