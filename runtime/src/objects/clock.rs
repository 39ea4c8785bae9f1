//! What clocks a creator's loops ([`ClockMode`]): real time (each active controller's control
//! and communication threads, SCHED_FIFO where permitted) or a simulated clock (the
//! [`SimWorld`](super::sim_world::SimWorld) steps them); and the node's time as a thread outside
//! the loops reads it ([`ClockReader`]: a recorder's stamps).

use std::sync::{Arc, Mutex};

use penelope_hal::Timestamp;

/// A simulated clock's time, as [`ClockReader`] reads it (the simulated world's).
pub trait SimulatedTime: Send {
    /// The simulated time now.
    fn now(&self) -> Timestamp;
}

/// A node's clock as a thread of the node outside its loops reads it (a recorder): the real
/// clock, or the simulated one (behind the lock its steps take).
#[derive(Clone)]
pub enum ClockReader {
    /// `CLOCK_MONOTONIC`.
    Real,
    /// The simulated clock of this world.
    Simulated(Arc<Mutex<dyn SimulatedTime>>),
}

impl ClockReader {
    /// The time now, ns.
    pub fn now_ns(&self) -> u64 {
        match self {
            ClockReader::Real => penelope_rt_core::clock::MonotonicClock::read().as_nanos(),
            ClockReader::Simulated(world) => world.lock().map_or(0, |w| w.now().as_nanos()),
        }
    }
}

/// How a creator's loops are clocked.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ClockMode {
    /// Threads on `CLOCK_MONOTONIC`.
    #[default]
    RealTime,
    /// Stepped on a simulated clock that starts at zero and moves only when told to
    /// ([`Creator::advance`](super::Creator::advance)).
    Simulated,
}
