//! The port between a communication task and its control loop: the newest stamped reference
//! (a latest-value cell) and the safety events the communication task raised with it (an
//! [`EventCell`]: a teleoperation channel's link lost or restored), so that each such
//! transition is an event of the control loop's tick, in its telemetry; and the energy of the
//! channel's two-port passivity observer at this side's port (one atomic word), for the same
//! telemetry.

use penelope_hal::Reference;
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, Stamped};
use std::sync::Arc;

use penelope_rt_core::cell::{Fresh, latest};
use penelope_rt_core::control::ReferenceSource;
use penelope_rt_core::events::EventCell;
use penelope_rt_core::safety::{EventSet, SafetyEvent};
use std::sync::atomic::AtomicU64;

/// The bits of "no energy published yet" (a NaN no observer writes: it writes finite values).
const NO_ENERGY: u64 = u64::MAX;

/// The communication task's half: publishes references and raises events.
pub struct ReferenceOut {
    reference: ArcLatestWriter<Stamped<Reference>>,
    events: Arc<EventCell>,
    channel_energy: Arc<AtomicU64>,
}

/// The control loop's half: reads the newest reference and takes the raised events.
pub struct ReferencePort {
    reference: ArcLatestReader<Stamped<Reference>>,
    events: Arc<EventCell>,
    channel_energy: Arc<AtomicU64>,
}

/// A new reference port, split into its two halves. Allocates here, once; the halves never do.
pub fn reference_port() -> (ReferenceOut, ReferencePort) {
    let (w, r) = latest();
    let events = Arc::new(EventCell::new());
    let channel_energy = Arc::new(AtomicU64::new(NO_ENERGY));
    (
        ReferenceOut {
            reference: w,
            events: events.clone(),
            channel_energy: channel_energy.clone(),
        },
        ReferencePort {
            reference: r,
            events,
            channel_energy,
        },
    )
}

impl ReferenceOut {
    /// Publishes `reference`.
    ///
    /// # Real-time
    /// One wait-free cell write.
    pub fn write(&mut self, reference: Stamped<Reference>) {
        self.reference.write(reference);
    }

    /// Raises `event` for the control loop's next tick. Raise it after writing the reference
    /// it goes with: the loop then sees both in the same tick.
    ///
    /// # Real-time
    /// One atomic `fetch_or`.
    pub fn raise(&self, event: SafetyEvent) {
        self.events.raise(event);
    }

    /// Publishes the channel's two-port energy at this side's port, J (finite values only).
    ///
    /// # Real-time
    /// One atomic store.
    pub fn set_channel_energy(&self, joules: f64) {
        if joules.is_finite() {
            self.channel_energy
                .store(joules.to_bits(), std::sync::atomic::Ordering::Relaxed);
        }
    }
}

impl ReferenceSource for ReferencePort {
    /// # Real-time
    /// One wait-free cell read.
    fn read(&mut self) -> Fresh<Stamped<Reference>> {
        self.reference.read()
    }

    /// # Real-time
    /// One atomic `swap`.
    fn take_events(&mut self) -> EventSet {
        self.events.take()
    }

    /// # Real-time
    /// One atomic load.
    fn channel_energy(&mut self) -> Option<f64> {
        match self
            .channel_energy
            .load(std::sync::atomic::Ordering::Relaxed)
        {
            NO_ENERGY => None,
            bits => Some(f64::from_bits(bits)),
        }
    }
}
