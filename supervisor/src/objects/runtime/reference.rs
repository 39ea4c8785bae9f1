//! The port between a communication task and its control loop: the newest stamped reference
//! (a latest-value cell) and the safety events the communication task raised with it (an
//! [`EventCell`]: a teleoperation channel's link lost or restored), so that each such
//! transition is an event of the control loop's tick, in its telemetry.

use super::*;

use penelope_rt_core::cell::{Fresh, latest};
use penelope_rt_core::control::ReferenceSource;
use penelope_rt_core::events::EventCell;
use penelope_rt_core::safety::{EventSet, SafetyEvent};

/// The communication task's half: publishes references and raises events.
pub struct ReferenceOut {
    reference: ArcLatestWriter<Stamped<Reference>>,
    events: Arc<EventCell>,
}

/// The control loop's half: reads the newest reference and takes the raised events.
pub struct ReferencePort {
    reference: ArcLatestReader<Stamped<Reference>>,
    events: Arc<EventCell>,
}

/// A new reference port, split into its two halves. Allocates here, once; the halves never do.
pub fn reference_port() -> (ReferenceOut, ReferencePort) {
    let (w, r) = latest();
    let events = Arc::new(EventCell::new());
    (
        ReferenceOut {
            reference: w,
            events: events.clone(),
        },
        ReferencePort {
            reference: r,
            events,
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
}
