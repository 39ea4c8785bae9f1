//! One control tick as it leaves a loop: what the telemetry ring carries to the pump, what a
//! recording holds and what a replayed sensor or hand reads back; and the stream of them a
//! recorder takes from the pump.

use std::sync::Arc;
use std::sync::atomic::AtomicU64;
use std::sync::mpsc::Receiver;

use penelope_drivers::sim::tap::TapSample;
use penelope_rt_core::telemetry::TelemetrySample;

/// One control tick as the telemetry ring carries it: what the loop reported, and the simulated
/// plant's true state at that instant (robots on simulated boards).
#[derive(Clone, Copy, Debug, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct TickRecord {
    /// What the control loop reported.
    pub sample: TelemetrySample,
    /// The plant's ground truth (`None` on real boards).
    pub truth: Option<TapSample>,
    /// Whether the operator's hand held the clutch at this tick (`None` for a robot no hand
    /// holds): what a replayed hand presses again.
    #[serde(default)]
    pub clutch: Option<bool>,
}

/// The receiving end of a recorder's subscription to every tick of one controller
/// ([`Subscriptions::record`](crate::objects::runtime::Subscriptions::record)).
#[derive(Debug)]
pub struct TickStream {
    /// Every tick, in order.
    pub ticks: Receiver<TickRecord>,
    /// Ticks lost because the stream was full (its reader fell behind).
    pub dropped: Arc<AtomicU64>,
}

impl TickStream {
    /// Moves every tick received so far into `into`.
    pub fn drain_into(&self, into: &mut Vec<TickRecord>) {
        while let Ok(t) = self.ticks.try_recv() {
            into.push(t);
        }
    }
}
