//! One control tick as it leaves a loop: what the telemetry ring carries to the pump, what a
//! recording holds and what a replayed sensor or hand reads back.

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
