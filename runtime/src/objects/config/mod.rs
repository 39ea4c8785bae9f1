//! A kind's configuration text: parsed into its typed configuration ([`parse`], with range
//! checks that say which key is out of range), the timing keys every controller shares
//! ([`LoopTiming`], the `loop_keys!` macro), and described from the type ([`describe`]: the key
//! list with units, defaults and help that `penelope ctl kinds`, the web forms and the docs
//! show). Below the kinds and the objects whose configuration it parses: they all use it, it
//! uses none of them.

use std::time::Duration;

use crate::objects::error::ObjectError;
use serde::de::DeserializeOwned;

pub mod describe;

pub use describe::KindConfig;

// ---------------------------------------------------------------------------------------------
// Parsing helpers
// ---------------------------------------------------------------------------------------------

pub(crate) fn bad(kind: &str, message: impl Into<String>) -> ObjectError {
    ObjectError::BadConfig {
        kind: kind.to_string(),
        message: message.into(),
    }
}

/// Parses `text` as the TOML configuration of `kind` (`""`: defaults).
///
/// # Errors
/// [`ObjectError::BadConfig`] for bad TOML, unknown keys or wrong types.
pub fn parse<T: DeserializeOwned + Default>(kind: &str, text: &str) -> Result<T, ObjectError> {
    if text.trim().is_empty() {
        return Ok(T::default());
    }
    toml::from_str(text).map_err(|e| bad(kind, e.message().to_string()))
}

pub(crate) fn check_range(
    kind: &str,
    key: &str,
    v: f64,
    lo: f64,
    hi: f64,
) -> Result<(), ObjectError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(bad(kind, format!("`{key}` = {v} is outside {lo}..={hi}")))
    }
}

pub(crate) fn check_int(
    kind: &str,
    key: &str,
    v: u64,
    lo: u64,
    hi: u64,
) -> Result<(), ObjectError> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(bad(kind, format!("`{key}` = {v} is outside {lo}..={hi}")))
    }
}

// ---------------------------------------------------------------------------------------------
// Controllers
// ---------------------------------------------------------------------------------------------

/// Timing keys every controller shares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoopTiming {
    /// Control period.
    pub period: Duration,
    /// Communication (reference) period.
    pub comm_period: Duration,
    /// Reference watchdog.
    pub watchdog: Duration,
    /// Sensor feed period.
    pub sensor_period: Duration,
    /// Largest wrench age used.
    pub sensor_timeout: Duration,
    /// Telemetry batch period.
    pub telemetry_period: Duration,
}

macro_rules! loop_keys {
    ($name:ident { $($field:ident : $ty:ty = $default:expr, #[$doc:meta])* }) => {
        /// A controller's configuration.
        #[derive(Clone, Debug, PartialEq, ::serde::Deserialize, ::serde::Serialize, ::schemars::JsonSchema)]
        #[serde(deny_unknown_fields, default)]
        pub struct $name {
            $(#[$doc] pub $field: $ty,)*
            /// Control period T_ctrl, µs, 250..=20000.
            pub period_us: u64,
            /// Communication period T_com (the reference's), µs, 250..=100000.
            pub comm_period_us: u64,
            /// A reference older than this holds the robot, ms, 1..=10000.
            pub watchdog_ms: u64,
            /// Force-sensor feed period, ms, 1..=1000.
            pub sensor_period_ms: u64,
            /// An older wrench is not used, ms, 1..=10000.
            pub sensor_timeout_ms: u64,
            /// Telemetry batch period to subscribers, ms, 1..=1000.
            pub telemetry_period_ms: u64,
        }

        impl Default for $name {
            fn default() -> Self {
                $name {
                    $($field: $default,)*
                    period_us: 1000,
                    comm_period_us: 2000,
                    watchdog_ms: 50,
                    sensor_period_ms: 2,
                    sensor_timeout_ms: 20,
                    telemetry_period_ms: 10,
                }
            }
        }

        impl $name {
            /// The timing keys, checked.
            ///
            /// # Errors
            /// [`ObjectError::BadConfig`].
            pub fn timing(&self, kind: &str) -> Result<$crate::objects::config::LoopTiming, $crate::objects::error::ObjectError> {
                $crate::objects::config::check_int(kind, "period_us", self.period_us, 250, 20_000)?;
                $crate::objects::config::check_int(kind, "comm_period_us", self.comm_period_us, 250, 100_000)?;
                $crate::objects::config::check_int(kind, "watchdog_ms", self.watchdog_ms, 1, 10_000)?;
                $crate::objects::config::check_int(kind, "sensor_period_ms", self.sensor_period_ms, 1, 1000)?;
                $crate::objects::config::check_int(kind, "sensor_timeout_ms", self.sensor_timeout_ms, 1, 10_000)?;
                $crate::objects::config::check_int(kind, "telemetry_period_ms", self.telemetry_period_ms, 1, 1000)?;
                Ok($crate::objects::config::LoopTiming {
                    period: ::std::time::Duration::from_micros(self.period_us),
                    comm_period: ::std::time::Duration::from_micros(self.comm_period_us),
                    watchdog: ::std::time::Duration::from_millis(self.watchdog_ms),
                    sensor_period: ::std::time::Duration::from_millis(self.sensor_period_ms),
                    sensor_timeout: ::std::time::Duration::from_millis(self.sensor_timeout_ms),
                    telemetry_period: ::std::time::Duration::from_millis(self.telemetry_period_ms),
                })
            }
        }
    };
}

pub(crate) use loop_keys;

loop_keys!(LoopKeysOnly {});

/// The timing keys of any controller's configuration text (other keys are ignored).
///
/// # Errors
/// [`ObjectError::BadConfig`] for text that is not TOML or timing out of range.
pub fn loop_timing(kind: &str, text: &str) -> Result<LoopTiming, ObjectError> {
    let table: toml::Table = text.parse().map_err(|e| bad(kind, format!("{e}")))?;
    let keys = [
        "period_us",
        "comm_period_us",
        "watchdog_ms",
        "sensor_period_ms",
        "sensor_timeout_ms",
        "telemetry_period_ms",
    ];
    let timing: toml::Table = table
        .into_iter()
        .filter(|(k, _)| keys.contains(&k.as_str()))
        .collect();
    let keys: LoopKeysOnly = parse(kind, &timing.to_string())?;
    keys.timing(kind)
}
