//! `sensor/test-signal`: a signal generator in the place of a force sensor, for the bench. Its
//! wrench is a sinusoid of the loop's clock, `A sin(2π f t + φ)` per axis, read in the control
//! loop's own thread: a master's force display can be checked against a known force (the
//! displayed force follows it, capped), and a law's response measured, without a slave. It is
//! also the example of a kind that is one module plus its catalog line.

use std::f64::consts::TAU;

use nalgebra::Vector3;
use penelope_hal::{Frame, Pose, Timestamp, Wrench};
use penelope_protocol::proto::{Reply, SensorMethod, WrenchMsg};
use serde::{Deserialize, Serialize};

use super::KindState;
use super::kind_entry::{KindEntry, MakeArgs};
use super::loop_sensor::LoopSensorObject;
use crate::objects::config::describe::{KindConfig, described};
use crate::objects::config::{check_range, parse};
use crate::objects::error::ObjectError;
use crate::objects::kinds::Kind;
use crate::objects::runtime::{LoopSensorRead, LoopSensorReader};

/// `sensor/test-signal`.
pub const TEST_SIGNAL: Kind = Kind::named("sensor/test-signal");

/// Its catalog entry.
pub(super) const ENTRY: KindEntry = KindEntry::new(
    TEST_SIGNAL,
    "a signal generator in the place of a force sensor: a sinusoidal wrench of the loop's clock, read in the loop (a master's force display checked against a known force)",
    described::<TestSignalConfig>(),
    make,
);

/// `sensor/test-signal` configuration.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct TestSignalConfig {
    /// Force amplitude per axis of the sensor frame, N, each -1000..=1000.
    pub force_amplitude_n: [f64; 3],
    /// Moment amplitude per axis of the sensor frame, N·m, each -100..=100.
    pub torque_amplitude_nm: [f64; 3],
    /// Frequency, Hz, 0..=500 (0: a constant wrench, sin φ times the amplitude).
    pub frequency_hz: f64,
    /// Phase at the clock's zero, degrees, -360..=360.
    pub phase_deg: f64,
}

impl Default for TestSignalConfig {
    fn default() -> Self {
        TestSignalConfig {
            force_amplitude_n: [0.0, 0.0, 1.0],
            torque_amplitude_nm: [0.0; 3],
            frequency_hz: 1.0,
            phase_deg: 0.0,
        }
    }
}

impl KindConfig for TestSignalConfig {}

impl TestSignalConfig {
    fn check(&self, kind: &str) -> Result<TestSignal, ObjectError> {
        for f in self.force_amplitude_n {
            check_range(kind, "force_amplitude_n", f, -1000.0, 1000.0)?;
        }
        for t in self.torque_amplitude_nm {
            check_range(kind, "torque_amplitude_nm", t, -100.0, 100.0)?;
        }
        check_range(kind, "frequency_hz", self.frequency_hz, 0.0, 500.0)?;
        check_range(kind, "phase_deg", self.phase_deg, -360.0, 360.0)?;
        Ok(TestSignal {
            force: Vector3::from(self.force_amplitude_n),
            torque: Vector3::from(self.torque_amplitude_nm),
            omega: TAU * self.frequency_hz,
            phase: self.phase_deg.to_radians(),
        })
    }
}

/// The signal: a wrench of time, in the sensor frame, mounted at the flange.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TestSignal {
    force: Vector3<f64>,
    torque: Vector3<f64>,
    omega: f64,
    phase: f64,
}

impl TestSignal {
    /// The wrench at `now`.
    pub fn at(&self, now: Timestamp) -> Wrench {
        let s = (self.omega * now.as_secs_f64() + self.phase).sin();
        Wrench {
            force: self.force * s,
            torque: self.torque * s,
            frame: Frame::Sensor,
        }
    }
}

impl LoopSensorRead for TestSignal {
    /// Never fails: the signal is a function of time.
    fn read_wrench(&mut self, now: Timestamp) -> Result<Wrench, penelope_hal::ErrorKind> {
        Ok(self.at(now))
    }

    fn sensor_mount(&self) -> Pose {
        Pose::identity()
    }
}

fn make(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: TestSignalConfig = parse(k, a.config)?;
    Ok(KindState::LoopSensor(Box::new(cfg.check(k)?)))
}

impl LoopSensorObject for TestSignal {
    /// Nothing to open.
    fn configure(&mut self) -> Result<(), ObjectError> {
        Ok(())
    }

    fn release(&mut self) {}

    fn mount(&self) -> Pose {
        Pose::identity()
    }

    fn relations(&self) -> Vec<(String, String)> {
        vec![(
            "signal".to_string(),
            format!(
                "F = [{:.3} {:.3} {:.3}] N, M = [{:.3} {:.3} {:.3}] N·m, x sin(2π·{:.3} Hz·t + {:.1}°)",
                self.force.x,
                self.force.y,
                self.force.z,
                self.torque.x,
                self.torque.y,
                self.torque.z,
                self.omega / TAU,
                self.phase.to_degrees()
            ),
        )]
    }

    /// `read`: the signal now, on the node's monotonic clock (a loop reads it on its own
    /// clock, simulated or real).
    fn method(&self, kind: Kind, m: SensorMethod) -> Result<Reply, ObjectError> {
        match m {
            SensorMethod::Read => Ok(Reply::Wrench(WrenchMsg::from(
                &self.at(penelope_rt_core::clock::MonotonicClock::read()),
            ))),
            other => Err(ObjectError::Unsupported {
                kind: kind.as_str().into(),
                method: format!("{other:?} (a signal generator has no bias and takes no probe)")
                    .into(),
            }),
        }
    }

    fn loop_reader(&self) -> Result<LoopSensorReader, ObjectError> {
        Ok(LoopSensorReader::new(*self))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signal(text: &str) -> Result<TestSignal, ObjectError> {
        let k = TEST_SIGNAL.as_str();
        parse::<TestSignalConfig>(k, text)?.check(k)
    }

    #[test]
    fn the_wrench_is_the_configured_sinusoid_of_the_clock() {
        let s =
            signal("force_amplitude_n = [2, 0, -4]\nfrequency_hz = 10\nphase_deg = 90").unwrap();
        let mut reader = LoopSensorReader::new(s);
        for ms in [0u64, 25, 50, 75, 1_000] {
            let t = Timestamp::from_nanos(ms * 1_000_000);
            let w = penelope_hal::Sensor::read(&mut reader, t).unwrap();
            let expected = (TAU * 10.0 * ms as f64 / 1000.0 + TAU / 4.0).sin();
            assert!((w.force.x - 2.0 * expected).abs() < 1e-9, "{ms} ms: {w:?}");
            assert!((w.force.z + 4.0 * expected).abs() < 1e-9, "{ms} ms: {w:?}");
            assert_eq!((w.force.y, w.torque.norm()), (0.0, 0.0));
        }
        assert_eq!(reader.mount(), Pose::identity());
    }

    #[test]
    fn amplitudes_frequency_and_phase_are_range_checked() {
        for bad in [
            "force_amplitude_n = [2000, 0, 0]",
            "torque_amplitude_nm = [0, nan, 0]",
            "frequency_hz = -1",
            "frequency_hz = 1e4",
            "phase_deg = 400",
            "gain = 1",
        ] {
            assert!(
                matches!(signal(bad), Err(ObjectError::BadConfig { .. })),
                "{bad}"
            );
        }
    }
}
