//! Latest-value cells: one writer publishes `Copy` values, one reader takes the newest.
//!
//! [`LatestCell`] is a triple buffer: three slots, one owned by the writer, one by the reader and
//! one in the middle, exchanged with a single atomic swap. Both sides are wait-free (one atomic
//! operation and one copy of `T` per call), nothing allocates after construction, and a reader
//! never sees a torn value. Every [`read`](LatestReader::read) says whether the value is new since
//! the last read, old, or whether nothing was ever written ([`Fresh`], OROCOS' `NewData` /
//! `OldData` / `NoData`).
//!
//! The storage is created once and split into a [`LatestWriter`] and a [`LatestReader`]. The halves
//! hold any pointer to the cell (`P: Deref<Target = LatestCell<T>>`):
//!
//! - `&'a LatestCell<T>` from [`LatestCell::split`]: a `static` cell on a microcontroller, or a cell
//!   borrowed by scoped threads;
//! - `Arc<LatestCell<T>>` from [`latest`] (feature `std`): for threads spawned freely.
//!
//! ```
//! use penelope_rt_core::cell::{Fresh, LatestCell};
//!
//! static CELL: LatestCell<[f64; 3]> = LatestCell::new();
//! let (mut writer, mut reader) = CELL.split().expect("split once");
//! assert_eq!(reader.read(), Fresh::NoData);
//! writer.write([1.0, 2.0, 3.0]);
//! assert_eq!(reader.read(), Fresh::New([1.0, 2.0, 3.0]));
//! assert_eq!(reader.read(), Fresh::Old([1.0, 2.0, 3.0]));
//! assert!(CELL.split().is_err()); // one writer and one reader, ever
//! ```

use core::fmt;
use core::marker::PhantomData;
use core::mem::MaybeUninit;
use core::ops::Deref;

use penelope_hal::Timestamp;

use crate::sync::{AtomicBool, AtomicUsize, Ordering, UnsafeCell};

/// What a read of a latest-value cell found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fresh<T> {
    /// Nothing was ever written.
    NoData,
    /// The same value as the previous read: nothing new was written since.
    Old(T),
    /// A value written since the previous read (the newest one; older ones are skipped).
    New(T),
}

impl<T> Fresh<T> {
    /// The value, new or old.
    pub fn value(self) -> Option<T> {
        match self {
            Fresh::NoData => None,
            Fresh::Old(v) | Fresh::New(v) => Some(v),
        }
    }

    /// True for [`Fresh::New`].
    pub fn is_new(&self) -> bool {
        matches!(self, Fresh::New(_))
    }

    /// Applies `f` to the value, keeping the freshness.
    pub fn map<U>(self, f: impl FnOnce(T) -> U) -> Fresh<U> {
        match self {
            Fresh::NoData => Fresh::NoData,
            Fresh::Old(v) => Fresh::Old(f(v)),
            Fresh::New(v) => Fresh::New(f(v)),
        }
    }
}

/// A value with the time it was produced, so a reader can judge its age (the control loop's
/// reference watchdog does).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stamped<T> {
    /// When the value was produced, on the clock of the thread that produced it.
    pub stamp: Timestamp,
    /// The value.
    pub value: T,
}

/// The cell was already split: it has exactly one writer and one reader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AlreadySplit;

impl fmt::Display for AlreadySplit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("cell already split into its writer and reader")
    }
}

/// Bit of `back` telling that the middle slot holds a value the reader has not taken.
const NEW: usize = 0b100;
/// Bits of `back` holding the middle slot's index.
const INDEX: usize = 0b011;

/// Storage of a triple-buffered latest-value cell for `Copy` values.
///
/// Create it once, then [`split`](LatestCell::split) it (or use [`latest`] under `std`).
pub struct LatestCell<T> {
    slots: [UnsafeCell<MaybeUninit<T>>; 3],
    /// Index of the middle slot, plus [`NEW`] when it holds an untaken value.
    back: AtomicUsize,
    split: AtomicBool,
}

// SAFETY: the writer and the reader each own one slot exclusively and exchange ownership of the
// middle slot through one atomic swap with acquire-release ordering, so no slot is ever accessed
// from two threads at once; `T: Send` lets values cross threads.
unsafe impl<T: Copy + Send> Sync for LatestCell<T> {}

impl<T: Copy> Default for LatestCell<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Copy> LatestCell<T> {
    /// An empty cell (`const`, so it can be a `static`).
    #[cfg(not(loom))]
    pub const fn new() -> Self {
        LatestCell {
            slots: [const { UnsafeCell::new(MaybeUninit::uninit()) }; 3],
            back: AtomicUsize::new(1),
            split: AtomicBool::new(false),
        }
    }

    /// An empty cell.
    #[cfg(loom)]
    pub fn new() -> Self {
        LatestCell {
            slots: core::array::from_fn(|_| UnsafeCell::new(MaybeUninit::uninit())),
            back: AtomicUsize::new(1),
            split: AtomicBool::new(false),
        }
    }

    /// Splits a borrowed (or `static`) cell into its writer and reader.
    ///
    /// # Errors
    /// [`AlreadySplit`] on every call after the first.
    #[allow(clippy::type_complexity)]
    pub fn split(&self) -> Result<(LatestWriter<T, &Self>, LatestReader<T, &Self>), AlreadySplit> {
        Self::split_shared(self)
    }

    /// Splits a cell behind any cloneable pointer (`Arc`, `&'static`).
    ///
    /// # Errors
    /// [`AlreadySplit`] on every call after the first.
    #[allow(clippy::type_complexity)]
    pub fn split_shared<P>(
        cell: P,
    ) -> Result<(LatestWriter<T, P>, LatestReader<T, P>), AlreadySplit>
    where
        P: Deref<Target = Self> + Clone,
    {
        if cell.split.swap(true, Ordering::AcqRel) {
            return Err(AlreadySplit);
        }
        Ok((
            LatestWriter {
                cell: cell.clone(),
                index: 0,
                _value: PhantomData,
            },
            LatestReader {
                cell,
                index: 2,
                has_value: false,
                _value: PhantomData,
            },
        ))
    }
}

/// The writing half of a [`LatestCell`].
pub struct LatestWriter<T, P> {
    cell: P,
    /// The slot this writer owns.
    index: usize,
    _value: PhantomData<T>,
}

impl<T: Copy, P: Deref<Target = LatestCell<T>>> LatestWriter<T, P> {
    /// Publishes `value`; the reader's next read returns it as [`Fresh::New`] (unless a later
    /// write replaces it first).
    ///
    /// # Real-time
    /// Wait-free: one copy of `T` and one atomic swap. Never allocates, locks or blocks.
    pub fn write(&mut self, value: T) {
        let cell = &*self.cell;
        // SAFETY: slot `self.index` is owned by this writer alone until it is handed over by the
        // swap below.
        cell.slots[self.index].with_mut(|slot| unsafe { slot.write(MaybeUninit::new(value)) });
        let previous = cell.back.swap(self.index | NEW, Ordering::AcqRel);
        self.index = previous & INDEX;
    }
}

impl<T, P> fmt::Debug for LatestWriter<T, P> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LatestWriter").finish_non_exhaustive()
    }
}

/// The reading half of a [`LatestCell`].
pub struct LatestReader<T, P> {
    cell: P,
    /// The slot this reader owns.
    index: usize,
    /// True once the reader's slot holds a value.
    has_value: bool,
    _value: PhantomData<T>,
}

impl<T: Copy, P: Deref<Target = LatestCell<T>>> LatestReader<T, P> {
    /// The newest value and whether it is new since the previous read.
    ///
    /// # Real-time
    /// Wait-free: at most one atomic load, one atomic swap and one copy of `T`. Never allocates,
    /// locks or blocks.
    pub fn read(&mut self) -> Fresh<T> {
        let cell = &*self.cell;
        if cell.back.load(Ordering::Relaxed) & NEW != 0 {
            let previous = cell.back.swap(self.index, Ordering::AcqRel);
            self.index = previous & INDEX;
            self.has_value = true;
            Fresh::New(self.current(cell))
        } else if self.has_value {
            Fresh::Old(self.current(cell))
        } else {
            Fresh::NoData
        }
    }

    /// The newest value, without telling whether it is new.
    ///
    /// # Real-time
    /// As [`read`](LatestReader::read).
    pub fn latest(&mut self) -> Option<T> {
        self.read().value()
    }

    fn current(&self, cell: &LatestCell<T>) -> T {
        // SAFETY: `has_value` is true, so the reader's slot was written by the writer before the
        // release-acquire swap that handed it over; the writer never touches it again until the
        // reader gives it back.
        cell.slots[self.index].with(|slot| unsafe { (*slot).assume_init() })
    }
}

impl<T, P> fmt::Debug for LatestReader<T, P> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LatestReader")
            .field("has_value", &self.has_value)
            .finish_non_exhaustive()
    }
}

/// Writer of a heap-allocated latest-value cell shared with [`latest`].
#[cfg(all(feature = "std", not(loom)))]
pub type ArcLatestWriter<T> = LatestWriter<T, std::sync::Arc<LatestCell<T>>>;
/// Reader of a heap-allocated latest-value cell shared with [`latest`].
#[cfg(all(feature = "std", not(loom)))]
pub type ArcLatestReader<T> = LatestReader<T, std::sync::Arc<LatestCell<T>>>;

/// A new latest-value cell on the heap, split into its writer and reader, for threads spawned
/// with `std::thread::spawn`. Allocates once, here; the halves never allocate.
#[cfg(all(feature = "std", not(loom)))]
pub fn latest<T: Copy>() -> (ArcLatestWriter<T>, ArcLatestReader<T>) {
    let cell = std::sync::Arc::new(LatestCell::new());
    (
        LatestWriter {
            cell: cell.clone(),
            index: 0,
            _value: PhantomData,
        },
        LatestReader {
            cell,
            index: 2,
            has_value: false,
            _value: PhantomData,
        },
    )
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;

    #[test]
    fn reports_no_data_then_new_then_old() {
        let cell = LatestCell::<u32>::new();
        let (mut w, mut r) = cell.split().unwrap();
        assert_eq!(r.read(), Fresh::NoData);
        w.write(1);
        w.write(2);
        assert_eq!(r.read(), Fresh::New(2), "older writes are skipped");
        assert_eq!(r.read(), Fresh::Old(2));
        for i in 3..100 {
            w.write(i);
            assert_eq!(r.read(), Fresh::New(i));
        }
        assert_eq!(r.latest(), Some(99));
    }

    #[test]
    fn splits_only_once() {
        let cell = LatestCell::<u8>::new();
        let halves = cell.split();
        assert!(halves.is_ok());
        assert_eq!(cell.split().err(), Some(AlreadySplit));
    }

    #[test]
    fn arc_halves_cross_threads_and_never_tear() {
        let (mut w, mut r) = latest::<[u64; 8]>();
        let writer = std::thread::spawn(move || {
            for i in 0..20_000u64 {
                w.write([i; 8]);
            }
        });
        let mut last = 0;
        let mut news = 0;
        while !writer.is_finished() || news == 0 {
            if let Fresh::New(v) = r.read() {
                assert!(v.iter().all(|x| *x == v[0]), "torn read {v:?}");
                assert!(v[0] >= last, "went back in time");
                last = v[0];
                news += 1;
            }
        }
        writer.join().unwrap();
        assert_eq!(r.read().value(), Some([19_999; 8]));
    }
}

#[cfg(all(test, loom))]
mod loom_tests {
    use super::*;
    use loom::sync::Arc;

    #[test]
    fn loom_latest_cell_reader_sees_whole_values_in_order() {
        loom::model(|| {
            let cell = Arc::new(LatestCell::<(u32, u32)>::new());
            let (mut w, mut r) = LatestCell::split_shared(cell).unwrap();
            let t = loom::thread::spawn(move || {
                w.write((1, 1));
                w.write((2, 2));
            });
            let mut last = 0;
            for _ in 0..3 {
                match r.read() {
                    Fresh::NoData => assert_eq!(last, 0),
                    Fresh::Old((a, b)) => {
                        assert_eq!(a, b);
                        assert_eq!(a, last);
                    }
                    Fresh::New((a, b)) => {
                        assert_eq!(a, b, "torn value");
                        assert!(a > last, "a new value must be newer");
                        last = a;
                    }
                }
            }
            t.join().unwrap();
            // After the writer is done, the reader gets the last value.
            assert_eq!(r.read().value(), Some((2, 2)));
        });
    }

    #[test]
    fn loom_latest_cell_three_writes_two_reads() {
        loom::model(|| {
            let cell = Arc::new(LatestCell::<u64>::new());
            let (mut w, mut r) = LatestCell::split_shared(cell).unwrap();
            let t = loom::thread::spawn(move || {
                for i in 1..=3 {
                    w.write(i);
                }
            });
            let a = r.read().value().unwrap_or(0);
            let b = r.read().value().unwrap_or(0);
            assert!(b >= a);
            t.join().unwrap();
            assert_eq!(r.read().value(), Some(3));
        });
    }
}
