//! A single-producer single-consumer ring of `Copy` values, for streams (telemetry out of the
//! control thread, commands into it).
//!
//! [`Ring<T, N>`] holds exactly `N` values (`N` a power of two, checked at compile time). The
//! producer never waits: when the ring is full, [`push`](Producer::push) hands the value back and
//! counts a drop, which the consumer can read with [`dropped`](Consumer::dropped). Both sides are
//! wait-free, and nothing allocates after construction.
//!
//! As with [`crate::cell`], the halves hold any pointer to the ring: `&'a Ring` from
//! [`Ring::split`], or `Arc<Ring>` from [`ring`] under `std`.
//!
//! ```
//! use penelope_rt_core::ring::Ring;
//!
//! let ring = Ring::<u32, 4>::new();
//! let (mut tx, mut rx) = ring.split().expect("split once");
//! for i in 0..5 {
//!     let _ = tx.push(i); // the fifth does not fit
//! }
//! assert_eq!(rx.dropped(), 1);
//! assert_eq!(rx.pop(), Some(0));
//! assert_eq!(rx.len(), 3);
//! ```

use core::fmt;
use core::marker::PhantomData;
use core::mem::MaybeUninit;
use core::ops::Deref;

pub use crate::cell::AlreadySplit;
use crate::sync::{AtomicBool, AtomicUsize, Ordering, UnsafeCell};

/// The ring was full: the value is handed back and the drop was counted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Full<T>(pub T);

impl<T> fmt::Display for Full<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("ring full, value dropped")
    }
}

/// Storage of a single-producer single-consumer ring of `N` values.
pub struct Ring<T, const N: usize> {
    slots: [UnsafeCell<MaybeUninit<T>>; N],
    /// Count of values ever popped (wrapping); written by the consumer only.
    head: AtomicUsize,
    /// Count of values ever pushed (wrapping); written by the producer only.
    tail: AtomicUsize,
    /// Count of values refused because the ring was full (wrapping); written by the producer only.
    dropped: AtomicUsize,
    split: AtomicBool,
}

// SAFETY: a slot is written only by the producer while it lies between `tail` and `head + N` and
// read only by the consumer while it lies between `head` and `tail`; the indices are published with
// release and read with acquire ordering, so no slot is accessed by both sides at once.
unsafe impl<T: Copy + Send, const N: usize> Sync for Ring<T, N> {}

impl<T: Copy, const N: usize> Default for Ring<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Copy, const N: usize> Ring<T, N> {
    const CAPACITY_IS_A_POWER_OF_TWO: () = assert!(N.is_power_of_two(), "N must be a power of two");

    /// An empty ring (`const`, so it can be a `static`).
    #[cfg(not(loom))]
    pub const fn new() -> Self {
        let () = Self::CAPACITY_IS_A_POWER_OF_TWO;
        Ring {
            slots: [const { UnsafeCell::new(MaybeUninit::uninit()) }; N],
            head: AtomicUsize::new(0),
            tail: AtomicUsize::new(0),
            dropped: AtomicUsize::new(0),
            split: AtomicBool::new(false),
        }
    }

    /// An empty ring.
    #[cfg(loom)]
    pub fn new() -> Self {
        let () = Self::CAPACITY_IS_A_POWER_OF_TWO;
        Ring {
            slots: core::array::from_fn(|_| UnsafeCell::new(MaybeUninit::uninit())),
            head: AtomicUsize::new(0),
            tail: AtomicUsize::new(0),
            dropped: AtomicUsize::new(0),
            split: AtomicBool::new(false),
        }
    }

    /// How many values the ring holds.
    pub const fn capacity(&self) -> usize {
        N
    }

    /// Splits a borrowed (or `static`) ring into its producer and consumer.
    ///
    /// # Errors
    /// [`AlreadySplit`] on every call after the first.
    #[allow(clippy::type_complexity)]
    pub fn split(&self) -> Result<(Producer<T, N, &Self>, Consumer<T, N, &Self>), AlreadySplit> {
        Self::split_shared(self)
    }

    /// Splits a ring behind any cloneable pointer (`Arc`, `&'static`).
    ///
    /// # Errors
    /// [`AlreadySplit`] on every call after the first.
    #[allow(clippy::type_complexity)]
    pub fn split_shared<P>(ring: P) -> Result<(Producer<T, N, P>, Consumer<T, N, P>), AlreadySplit>
    where
        P: Deref<Target = Self> + Clone,
    {
        if ring.split.swap(true, Ordering::AcqRel) {
            return Err(AlreadySplit);
        }
        Ok(Self::halves(ring))
    }

    fn halves<P: Deref<Target = Self> + Clone>(ring: P) -> (Producer<T, N, P>, Consumer<T, N, P>) {
        (
            Producer {
                ring: ring.clone(),
                tail: 0,
                dropped: 0,
                _value: PhantomData,
            },
            Consumer {
                ring,
                head: 0,
                _value: PhantomData,
            },
        )
    }
}

/// The producing half of a [`Ring`].
pub struct Producer<T, const N: usize, P> {
    ring: P,
    tail: usize,
    dropped: usize,
    _value: PhantomData<T>,
}

impl<T: Copy, const N: usize, P: Deref<Target = Ring<T, N>>> Producer<T, N, P> {
    /// Appends `value`, or hands it back and counts a drop when the ring is full.
    ///
    /// # Errors
    /// [`Full`] when the consumer has not made room.
    ///
    /// # Real-time
    /// Wait-free: one atomic load, one copy of `T` and one atomic store. Never allocates, locks or
    /// blocks.
    pub fn push(&mut self, value: T) -> Result<(), Full<T>> {
        let ring = &*self.ring;
        let head = ring.head.load(Ordering::Acquire);
        if self.tail.wrapping_sub(head) >= N {
            self.dropped = self.dropped.wrapping_add(1);
            ring.dropped.store(self.dropped, Ordering::Relaxed);
            return Err(Full(value));
        }
        // SAFETY: the slot lies outside `head..tail`, so the consumer does not read it until the
        // release store of `tail` below publishes it.
        ring.slots[self.tail % N].with_mut(|slot| unsafe { slot.write(MaybeUninit::new(value)) });
        self.tail = self.tail.wrapping_add(1);
        ring.tail.store(self.tail, Ordering::Release);
        Ok(())
    }

    /// Room left for pushes (a lower bound: the consumer may be freeing more).
    ///
    /// # Real-time
    /// Wait-free.
    pub fn free(&self) -> usize {
        N - self
            .tail
            .wrapping_sub(self.ring.head.load(Ordering::Acquire))
    }

    /// Values refused so far because the ring was full (wrapping).
    pub fn dropped(&self) -> usize {
        self.dropped
    }
}

impl<T, const N: usize, P> fmt::Debug for Producer<T, N, P> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Producer")
            .field("pushed", &self.tail)
            .field("dropped", &self.dropped)
            .finish_non_exhaustive()
    }
}

/// The consuming half of a [`Ring`].
pub struct Consumer<T, const N: usize, P> {
    ring: P,
    head: usize,
    _value: PhantomData<T>,
}

impl<T: Copy, const N: usize, P: Deref<Target = Ring<T, N>>> Consumer<T, N, P> {
    /// The oldest value, if any.
    ///
    /// # Real-time
    /// Wait-free: one atomic load, one copy of `T` and one atomic store.
    pub fn pop(&mut self) -> Option<T> {
        let ring = &*self.ring;
        let tail = ring.tail.load(Ordering::Acquire);
        if tail == self.head {
            return None;
        }
        // SAFETY: the slot lies inside `head..tail`: the producer wrote it before its release
        // store of `tail` and does not touch it again until the store of `head` below frees it.
        let value = ring.slots[self.head % N].with(|slot| unsafe { (*slot).assume_init() });
        self.head = self.head.wrapping_add(1);
        ring.head.store(self.head, Ordering::Release);
        Some(value)
    }

    /// Values waiting (a lower bound: the producer may be adding more).
    pub fn len(&self) -> usize {
        self.ring
            .tail
            .load(Ordering::Acquire)
            .wrapping_sub(self.head)
    }

    /// True when no value is waiting.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Values the producer could not push because the ring was full, so far (wrapping).
    pub fn dropped(&self) -> usize {
        self.ring.dropped.load(Ordering::Relaxed)
    }
}

impl<T, const N: usize, P> fmt::Debug for Consumer<T, N, P> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Consumer")
            .field("popped", &self.head)
            .finish_non_exhaustive()
    }
}

/// Producer of a heap-allocated ring made by [`ring`].
#[cfg(all(feature = "std", not(loom)))]
pub type ArcProducer<T, const N: usize> = Producer<T, N, std::sync::Arc<Ring<T, N>>>;
/// Consumer of a heap-allocated ring made by [`ring`].
#[cfg(all(feature = "std", not(loom)))]
pub type ArcConsumer<T, const N: usize> = Consumer<T, N, std::sync::Arc<Ring<T, N>>>;

/// A new ring on the heap, split into its producer and consumer, for threads spawned with
/// `std::thread::spawn`. Allocates once, here; the halves never allocate.
#[cfg(all(feature = "std", not(loom)))]
pub fn ring<T: Copy, const N: usize>() -> (ArcProducer<T, N>, ArcConsumer<T, N>) {
    let () = Ring::<T, N>::CAPACITY_IS_A_POWER_OF_TWO;
    // Built in place on the heap: `Arc::new(Ring::new())` makes the ring on the stack first in
    // unoptimized builds, and a ring of 4096 telemetry samples (megabytes) overflows a thread's
    // stack.
    let mut storage = std::boxed::Box::<Ring<T, N>>::new_uninit();
    let p = storage.as_mut_ptr();
    // SAFETY: `p` points to writable, exclusively owned memory for one `Ring`. The slots are
    // `UnsafeCell<MaybeUninit<T>>`, for which uninitialized bytes are a valid value; every other
    // field is written here before `assume_init`.
    let ring = unsafe {
        core::ptr::addr_of_mut!((*p).head).write(AtomicUsize::new(0));
        core::ptr::addr_of_mut!((*p).tail).write(AtomicUsize::new(0));
        core::ptr::addr_of_mut!((*p).dropped).write(AtomicUsize::new(0));
        core::ptr::addr_of_mut!((*p).split).write(AtomicBool::new(false));
        storage.assume_init()
    };
    // Moves heap to heap (a copy into the Arc's allocation), never through the stack.
    let ring: std::sync::Arc<Ring<T, N>> = std::sync::Arc::from(ring);
    Ring::halves(ring)
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;

    #[test]
    fn a_ring_larger_than_a_thread_stack_is_built_on_the_heap() {
        // 8 MiB of slots: made on a 256 KiB stack, so building it there first would overflow.
        let handle = std::thread::Builder::new()
            .stack_size(256 * 1024)
            .spawn(|| {
                let (mut tx, mut rx) = ring::<[u64; 256], 4096>();
                assert!(tx.push([7; 256]).is_ok());
                assert_eq!(rx.pop().map(|v| v[255]), Some(7));
                assert_eq!(rx.pop(), None);
                tx.free()
            })
            .unwrap();
        assert_eq!(handle.join().unwrap(), 4096);
    }

    #[test]
    fn fifo_order_and_counted_drops() {
        let ring = Ring::<u16, 8>::new();
        let (mut tx, mut rx) = ring.split().unwrap();
        assert!(rx.is_empty());
        for i in 0..8 {
            assert_eq!(tx.push(i), Ok(()));
        }
        assert_eq!(tx.push(99), Err(Full(99)));
        assert_eq!(tx.free(), 0);
        assert_eq!((tx.dropped(), rx.dropped()), (1, 1));
        for i in 0..8 {
            assert_eq!(rx.pop(), Some(i));
        }
        assert_eq!(rx.pop(), None);
        assert!(ring.split().is_err());
    }

    #[test]
    fn wraps_around_many_times() {
        let ring = Ring::<u32, 4>::new();
        let (mut tx, mut rx) = ring.split().unwrap();
        for i in 0..1000 {
            tx.push(i).unwrap();
            tx.push(i + 1).unwrap();
            assert_eq!(rx.pop(), Some(i));
            assert_eq!(rx.pop(), Some(i + 1));
        }
        assert_eq!(rx.len(), 0);
    }

    #[test]
    fn arc_halves_stream_across_threads_in_order() {
        let (mut tx, mut rx) = ring::<u64, 64>();
        let producer = std::thread::spawn(move || {
            let mut sent = 0u64;
            let mut i = 0u64;
            while sent < 10_000 {
                if tx.push(i).is_ok() {
                    sent += 1;
                }
                i += 1;
            }
            tx.dropped()
        });
        let mut got = 0u64;
        let mut last = None;
        while got < 10_000 {
            if let Some(v) = rx.pop() {
                assert!(
                    last.is_none_or(|l| v > l),
                    "order broken: {v} after {last:?}"
                );
                last = Some(v);
                got += 1;
            }
        }
        let dropped = producer.join().unwrap();
        assert_eq!(dropped, rx.dropped());
    }
}

#[cfg(all(test, loom))]
mod loom_tests {
    use super::*;
    use loom::sync::Arc;

    #[test]
    fn loom_ring_delivers_in_order_without_tearing() {
        loom::model(|| {
            let ring = Arc::new(Ring::<(u32, u32), 2>::new());
            let (mut tx, mut rx) = Ring::split_shared(ring).unwrap();
            let t = loom::thread::spawn(move || {
                let mut pushed = 0;
                for i in 1..=3u32 {
                    if tx.push((i, i)).is_ok() {
                        pushed += 1;
                    }
                }
                pushed
            });
            let mut last = 0;
            let mut got = 0;
            for _ in 0..2 {
                if let Some((a, b)) = rx.pop() {
                    assert_eq!(a, b, "torn value");
                    assert!(a > last, "out of order");
                    last = a;
                    got += 1;
                }
            }
            let pushed = t.join().unwrap();
            while let Some((a, b)) = rx.pop() {
                assert_eq!(a, b);
                assert!(a > last);
                last = a;
                got += 1;
            }
            assert_eq!(got, pushed);
            assert_eq!(rx.dropped(), 3 - pushed);
        });
    }

    #[test]
    fn loom_ring_full_then_freed() {
        loom::model(|| {
            let ring = Arc::new(Ring::<u32, 1>::new());
            let (mut tx, mut rx) = Ring::split_shared(ring).unwrap();
            tx.push(7).unwrap();
            let t = loom::thread::spawn(move || rx.pop());
            // Either the consumer freed the slot (push succeeds) or not (counted drop).
            let second = tx.push(8);
            let popped = t.join().unwrap();
            assert_eq!(popped, Some(7));
            if second.is_err() {
                assert_eq!(tx.dropped(), 1);
            }
        });
    }
}
