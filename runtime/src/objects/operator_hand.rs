//! `sensor/operator-hand`: a scripted operator's hand holding a simulated master (its
//! settings, its script, and the clutch button the master's communication thread reads).

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use penelope_drivers::sim::operator::{HandImpedance, OperatorScript};
use penelope_drivers::sim::scripts;
use serde::{Deserialize, Serialize};

use crate::objects::error::ObjectError;

/// `sensor/operator-hand` configuration: a scripted operator's hand holding a simulated master.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct HandConfig {
    /// The master whose handle it holds (required; a robot on this node on a simulated board:
    /// create the hand, then configure the robot, whose simulated body gets the hand).
    pub robot: String,
    /// What the hand does: `demo` (reach, sweeps, clutch, push, tap, release).
    pub script: String,
    /// The hand's grip: an impedance towards the scripted point, N/m, 0..=1e5.
    pub stiffness_n_per_m: f64,
    /// The grip's damping, N·s/m, 0..=1e5.
    pub damping_ns_per_m: f64,
}

impl Default for HandConfig {
    fn default() -> Self {
        HandConfig {
            robot: String::new(),
            script: "demo".into(),
            stiffness_n_per_m: 400.0,
            damping_ns_per_m: 12.0,
        }
    }
}

impl crate::objects::config::KindConfig for HandConfig {
    fn example() -> Self {
        HandConfig {
            robot: "frhc".into(),
            ..Self::default()
        }
    }
}

impl HandConfig {
    /// Checks the keys and finds the script.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`].
    pub fn check(&self, kind: &str) -> Result<OperatorScript, ObjectError> {
        let bad = |message: String| ObjectError::BadConfig {
            kind: kind.into(),
            message,
        };
        if self.robot.is_empty() {
            return Err(bad("needs `robot` (the master it holds)".into()));
        }
        for (key, v) in [
            ("stiffness_n_per_m", self.stiffness_n_per_m),
            ("damping_ns_per_m", self.damping_ns_per_m),
        ] {
            if !(v.is_finite() && (0.0..=1e5).contains(&v)) {
                return Err(bad(format!("`{key}` = {v} is outside 0..=100000")));
            }
        }
        scripts::by_name(&self.script)
            .ok_or_else(|| bad(format!("unknown script `{}` (demo)", self.script)))
    }

    /// The hand's impedance.
    pub fn impedance(&self) -> HandImpedance {
        HandImpedance {
            stiffness: self.stiffness_n_per_m,
            damping: self.damping_ns_per_m,
            ..HandImpedance::default()
        }
    }
}

/// A `sensor/operator-hand` object: its settings, script, and the clutch button its simulated
/// master's communication thread reads.
pub struct HandObj {
    /// The settings.
    pub config: HandConfig,
    /// The script.
    pub script: OperatorScript,
    /// Whether the clutch is held (written by the plant's contact model, read by the master's
    /// communication thread).
    pub clutch: Arc<AtomicBool>,
}
