//! Time-domain passivity (Hannaford & Ryu, 2002): an energy observer per port and an optional
//! passivity controller.
//!
//! # Sign convention
//!
//! At a port, `f` is the force (or wrench `[f; m]`) *applied to* the observed subsystem and `v` the
//! port's velocity (twist `[v; omega]`) in the same frame and sign, so `f·v` is the power flowing
//! into the subsystem. The observer integrates it, `E(n) = dt * sum_k f(k)·v(k)`; a passive
//! subsystem never gives out more than it received, so `E(n) >= 0` for all `n`. A negative `E`
//! means the subsystem (the teleoperator with its delays, filters and gains) is generating
//! energy: the run-time sign of trouble to come.
//!
//! For a master device displaying a force `F_display` to the operator's hand moving at `v`, the
//! hand applies about `-F_display` to the system, so observe `f = -F_display`;
//! [`ForceDisplay`](super::ForceDisplay) and [`PositionErrorMaster`](super::PositionErrorMaster)
//! do this themselves.
//!
//! # Passivity controller
//!
//! When enabled, if the energy would go negative this tick the controller adds a damping
//! `alpha = -E / (dt |v|²)` (impedance causality: `f' = f + alpha v`), exactly dissipating the
//! deficit, bounded by [`PassivityConfig::max_damping`]. Off by default.
//!
//! # Real-time
//! All methods: `Copy` state, no allocation, constant time.

use nalgebra::Vector6;

use super::{TeleopConfigError, check_cap, check_gain};

/// Energy observer of one port.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PassivityObserver {
    energy: f64,
    min_energy: f64,
    last_power: f64,
    samples: u64,
}

impl PassivityObserver {
    /// An observer with zero energy.
    pub const fn new() -> Self {
        PassivityObserver {
            energy: 0.0,
            min_energy: 0.0,
            last_power: 0.0,
            samples: 0,
        }
    }

    /// Adds one sample: `E += dt * f·v`. `dt` in s, `f` in N (and N·m), `v` in m/s (and rad/s).
    /// Non-finite inputs are ignored (the energy stays finite). Returns the energy, J.
    pub fn observe(&mut self, dt: f64, force: &Vector6<f64>, velocity: &Vector6<f64>) -> f64 {
        self.observe_power(dt, force.dot(velocity))
    }

    /// As [`observe`](Self::observe) for a one-degree-of-freedom port.
    pub fn observe_scalar(&mut self, dt: f64, force: f64, velocity: f64) -> f64 {
        self.observe_power(dt, force * velocity)
    }

    fn observe_power(&mut self, dt: f64, power: f64) -> f64 {
        if power.is_finite() && dt.is_finite() && dt > 0.0 {
            self.last_power = power;
            self.energy += dt * power;
            self.min_energy = self.min_energy.min(self.energy);
            self.samples += 1;
        }
        self.energy
    }

    /// The energy that has flowed into the port since the last reset, J.
    pub fn energy(&self) -> f64 {
        self.energy
    }

    /// The lowest energy seen since the last reset, J (<= 0).
    pub fn min_energy(&self) -> f64 {
        self.min_energy
    }

    /// The power of the last sample, W.
    pub fn last_power(&self) -> f64 {
        self.last_power
    }

    /// How many samples were observed.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// True while the energy is not negative beyond `tolerance` (J).
    pub fn is_passive(&self, tolerance: f64) -> bool {
        self.energy >= -tolerance
    }

    /// Back to zero energy.
    pub fn reset(&mut self) {
        *self = Self::new();
    }
}

/// Settings of the time-domain passivity controller.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassivityConfig {
    /// Add damping when the energy goes negative. Off by default: the observer still runs.
    pub enabled: bool,
    /// Largest damping the controller adds, N·s/m (applied to the whole `[v; omega]`).
    pub max_damping: f64,
    /// Below this speed (norm of `[v; omega]`) no damping is added (it could not dissipate
    /// anything and would blow up `alpha`).
    pub min_speed: f64,
}

impl Default for PassivityConfig {
    /// Disabled; at most 200 N·s/m; not below 1 mm/s.
    fn default() -> Self {
        PassivityConfig {
            enabled: false,
            max_damping: 200.0,
            min_speed: 1e-3,
        }
    }
}

impl PassivityConfig {
    /// Checks the values.
    ///
    /// # Errors
    /// [`TeleopConfigError`] for negative or NaN values.
    pub fn validate(&self) -> Result<(), TeleopConfigError> {
        check_cap(self.max_damping, "passivity.max_damping")?;
        check_gain(self.min_speed, "passivity.min_speed")
    }
}

/// The observer plus, when enabled, the variable damper that keeps the port passive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassivityController {
    config: PassivityConfig,
    observer: PassivityObserver,
    last_damping: f64,
}

impl PassivityController {
    /// A controller with zero energy.
    ///
    /// # Errors
    /// As [`PassivityConfig::validate`].
    pub fn new(config: PassivityConfig) -> Result<Self, TeleopConfigError> {
        config.validate()?;
        Ok(PassivityController {
            config,
            observer: PassivityObserver::new(),
            last_damping: 0.0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &PassivityConfig {
        &self.config
    }

    /// The damping `alpha` (N·s/m) to add this tick so that the energy, with `force` applied at
    /// `velocity` for `dt`, does not go negative; 0 when disabled, when the energy stays
    /// non-negative, or below `min_speed`. Does not change the state.
    pub fn damping(&self, dt: f64, force: &Vector6<f64>, velocity: &Vector6<f64>) -> f64 {
        if !self.config.enabled || dt <= 0.0 {
            return 0.0;
        }
        let v2 = velocity.norm_squared();
        // (NaN speeds fall through to the finiteness check below.)
        if v2 < self.config.min_speed * self.config.min_speed || v2 == 0.0 {
            return 0.0;
        }
        let e = self.observer.energy() + dt * force.dot(velocity);
        if e.is_finite() && e < 0.0 {
            (-e / (dt * v2)).min(self.config.max_damping)
        } else {
            0.0
        }
    }

    /// Records what was actually applied this tick (after any caps) in the observer, and the
    /// damping that was added.
    pub fn commit(
        &mut self,
        dt: f64,
        force: &Vector6<f64>,
        velocity: &Vector6<f64>,
        damping: f64,
    ) -> f64 {
        self.last_damping = damping;
        self.observer.observe(dt, force, velocity)
    }

    /// One tick: the corrected force `f + alpha v` applied to the subsystem, energy recorded.
    pub fn apply(
        &mut self,
        dt: f64,
        force: &Vector6<f64>,
        velocity: &Vector6<f64>,
    ) -> Vector6<f64> {
        let alpha = self.damping(dt, force, velocity);
        let f = force + velocity * alpha;
        self.commit(dt, &f, velocity, alpha);
        f
    }

    /// The observer.
    pub fn observer(&self) -> &PassivityObserver {
        &self.observer
    }

    /// The damping added on the last tick, N·s/m.
    pub fn last_damping(&self) -> f64 {
        self.last_damping
    }

    /// Back to zero energy.
    pub fn reset(&mut self) {
        self.observer.reset();
        self.last_damping = 0.0;
    }
}
