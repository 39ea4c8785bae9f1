//! A virtual six-axis wrist force/torque sensor.
//!
//! It reads the plant's true interaction wrench (through a [`TapReader`]), moves it into its own
//! frame at the wrist, and adds what a real sensor adds: a bias, Gaussian noise and a first-order
//! low-pass filter. Sign convention: the sensor reports the wrench the robot exerts *on* the
//! environment (pushing a wall along +x reads +x), the usual wrist-sensor convention; force
//! reflection displays its negative.

use core::f64::consts::PI;

use nalgebra::Vector3;
use penelope_hal::{Error, ErrorKind, ForceSensor, Frame, Pose, Sensor, Timestamp, Wrench};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::tap::TapReader;

/// Settings of a [`VirtualForceSensor`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceSensorConfig {
    /// The sensor frame's pose in the robot's tool frame (m, rotation).
    pub mount: Pose,
    /// Constant offset added to every reading, in the sensor frame (N, N·m).
    pub bias: Wrench,
    /// Standard deviation of the force noise per axis, N.
    pub force_noise: f64,
    /// Standard deviation of the torque noise per axis, N·m.
    pub torque_noise: f64,
    /// Cut-off of the first-order low-pass filter, Hz (0 disables the filter).
    pub cutoff_hz: f64,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl Default for ForceSensorConfig {
    /// A small wrist sensor (ATI Mini45-like noise), filtered at 30 Hz.
    fn default() -> Self {
        ForceSensorConfig {
            mount: Pose::identity(),
            bias: Wrench {
                force: Vector3::new(0.4, -0.3, 0.8),
                torque: Vector3::new(0.01, 0.02, -0.01),
                frame: Frame::Sensor,
            },
            force_noise: 0.05,
            torque_noise: 0.002,
            cutoff_hz: 30.0,
            seed: 1,
        }
    }
}

/// What can go wrong reading the virtual sensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ForceSensorError {
    /// The plant has not published a state yet.
    NoData,
    /// The plant's wrench was NaN or infinite (never passed on as a measurement).
    NonFinite,
}

impl Error for ForceSensorError {
    fn kind(&self) -> ErrorKind {
        match self {
            ForceSensorError::NoData => ErrorKind::Timeout,
            ForceSensorError::NonFinite => ErrorKind::NonFinite,
        }
    }
}

impl core::fmt::Display for ForceSensorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ForceSensorError::NoData => "no plant state published yet",
            ForceSensorError::NonFinite => "plant wrench is NaN or infinite",
        })
    }
}

/// A wrist force/torque sensor reading a simulated plant.
pub struct VirtualForceSensor {
    config: ForceSensorConfig,
    source: TapReader,
    rng: ChaCha8Rng,
    filtered: Option<(Timestamp, [f64; 6])>,
    tare: [f64; 6],
}

impl VirtualForceSensor {
    /// A sensor reading the plant behind `source`.
    pub fn new(config: ForceSensorConfig, source: TapReader) -> Self {
        VirtualForceSensor {
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            config,
            source,
            filtered: None,
            tare: [0.0; 6],
        }
    }

    /// One Gaussian sample (Box-Muller; two uniforms per call keeps the stream simple to replay).
    fn gaussian(&mut self) -> f64 {
        let u1: f64 = self.rng.random::<f64>().max(f64::MIN_POSITIVE);
        let u2: f64 = self.rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }
}

impl Sensor for VirtualForceSensor {
    type Error = ForceSensorError;
    type Reading = Wrench;

    /// # Real-time
    /// No allocation, no locks, constant time.
    fn read(&mut self, now: Timestamp) -> Result<Wrench, ForceSensorError> {
        let sample = self.source.latest().ok_or(ForceSensorError::NoData)?;
        // The environment pushes on the tool; the sensor reports the robot pushing on it.
        let on_environment = Wrench {
            force: -sample.tool_wrench.force,
            torque: -sample.tool_wrench.torque,
            frame: Frame::Tool,
        };
        if !on_environment.is_finite() {
            return Err(ForceSensorError::NonFinite);
        }
        let in_sensor = on_environment.expressed_in(&self.config.mount, Frame::Sensor);
        let bias = self.config.bias.to_vector();
        let truth = in_sensor.to_vector();
        let mut raw = [0.0; 6];
        for (i, value) in raw.iter_mut().enumerate() {
            let sigma = if i < 3 {
                self.config.force_noise
            } else {
                self.config.torque_noise
            };
            *value = truth[i] + bias[i] + sigma * self.gaussian();
        }
        let filtered = match self.filtered {
            Some((last, mut state)) if self.config.cutoff_hz > 0.0 => {
                let dt = (now - last).as_secs_f64();
                let tau = 1.0 / (2.0 * PI * self.config.cutoff_hz);
                let alpha = dt / (tau + dt);
                for (s, r) in state.iter_mut().zip(raw) {
                    *s += alpha * (r - *s);
                }
                state
            }
            _ => raw,
        };
        self.filtered = Some((now, filtered));
        let f = filtered;
        let t = self.tare;
        Ok(Wrench {
            force: Vector3::new(f[0] - t[0], f[1] - t[1], f[2] - t[2]),
            torque: Vector3::new(f[3] - t[3], f[4] - t[4], f[5] - t[5]),
            frame: Frame::Sensor,
        })
    }
}

impl ForceSensor for VirtualForceSensor {
    fn mount(&self) -> Pose {
        self.config.mount
    }

    fn tare(&mut self, now: Timestamp) -> Result<(), ForceSensorError> {
        self.tare = [0.0; 6];
        let w = self.read(now)?.to_vector();
        for (t, v) in self.tare.iter_mut().zip(w.iter()) {
            *t = *v;
        }
        Ok(())
    }
}
