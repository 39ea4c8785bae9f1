//! A counting global allocator.
//!
//! A test binary installs [`CountingAllocator`] with `#[global_allocator]` and wraps the code it
//! steps on its own thread in [`counted`] (or reads [`allocations`] around it). Counts are per
//! thread: the test harness's own threads (its "running for over 60 seconds" notice, say) and
//! tests running beside it do not disturb them.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

thread_local! {
    // Const-initialised and without destructors: reading them never allocates.
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
    static FREES: Cell<u64> = const { Cell::new(0) };
}

fn count(allocs: u64, frees: u64) {
    // During thread teardown the slots may be gone; such calls are not the code under test.
    let _ = ALLOCS.try_with(|n| n.set(n.get() + allocs));
    let _ = FREES.try_with(|n| n.set(n.get() + frees));
}

/// A global allocator that forwards to the system allocator and counts, per thread, the blocks
/// it hands out and takes back (a reallocation is both).
pub struct CountingAllocator;

// SAFETY: forwards to the system allocator unchanged; only counts calls.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count(1, 0);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        count(0, 1);
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count(1, 0);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count(1, 1);
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocator calls (allocations and frees together) made so far on the calling thread, as
/// counted by [`CountingAllocator`].
pub fn allocations() -> u64 {
    ALLOCS.with(Cell::get) + FREES.with(Cell::get)
}

/// Runs `f` on the calling thread and returns its result with the allocations and the frees it
/// made.
pub fn counted<T>(f: impl FnOnce() -> T) -> (T, u64, u64) {
    let (a0, f0) = (ALLOCS.with(Cell::get), FREES.with(Cell::get));
    let out = f();
    let (a1, f1) = (ALLOCS.with(Cell::get), FREES.with(Cell::get));
    (out, a1 - a0, f1 - f0)
}

/// The allocations and the frees made so far on the calling thread, for a count that spans
/// more than one call (from a periodic thread's first tick to its last, say).
pub fn counts() -> (u64, u64) {
    (ALLOCS.with(Cell::get), FREES.with(Cell::get))
}
