//! Time-domain passivity (Hannaford & Ryu, 2002): an energy observer per port, and the
//! two-port delayed form with its passivity controllers.
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
//! # The two-port, delayed form
//!
//! The one-port observer above counts energy that entered at a port as available at the same
//! port: across a delayed link that is not enough (the energy that enters at the master is
//! only available at the slave a delay later). [`TwoPortObserver`] keeps input and output
//! energy apart per port and compares this port's output with the *other* port's input, whose
//! counter ([`PortEnergy`]) travels with the samples; [`TwoPortController`] dissipates exactly
//! the deficit in impedance form (a series damper on the force) or admittance form (a parallel
//! conductance on the velocity), bounded.
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

// ---------------------------------------------------------------------------------------------
// The two-port, delayed form (Ryu, Artigas & Preusche, 2010: time-domain passivity networks)
// ---------------------------------------------------------------------------------------------

/// The energy counters one side sends with its samples: how much energy has entered the
/// communication two-port at its port since the start. They only grow.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PortEnergy {
    /// Energy that has flowed into the two-port at this side's port, J (>= 0, never
    /// decreases).
    pub input: f64,
}

/// The observer of one port of a delayed two-port (the communication channel between a master
/// and a slave, with everything of the law that lies between the two devices).
///
/// At its port the side splits the power `p = f·v` (into the two-port, same sign convention as
/// [`PassivityObserver`]) into input (`p > 0`) and output (`p < 0`) energy. The two-port is
/// passive if at each port the energy it gives out never exceeds what entered it at the other
/// port: `W(n) = E_in,remote(n - T) - E_out,local(n) >= 0`. The other side's input counter
/// travels with its samples ([`PortEnergy`]), so `T` is whatever the network delivered: an old,
/// duplicated or lost counter can only make the observer more cautious (the largest heard is
/// kept; counters only grow), never let it allow energy that has not arrived.
///
/// Energy entering at this port is not counted as available here: it is the other side's
/// budget. That is what makes this form safe under delay where the one-port observer
/// ([`PassivityObserver`]) is not.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TwoPortObserver {
    input: f64,
    output: f64,
    remote_input: f64,
    dissipated: f64,
    min_energy: f64,
}

impl TwoPortObserver {
    /// An observer with nothing in or out.
    pub const fn new() -> Self {
        TwoPortObserver {
            input: 0.0,
            output: 0.0,
            remote_input: 0.0,
            dissipated: 0.0,
            min_energy: 0.0,
        }
    }

    /// Takes the other side's counters (keeps the largest heard). Non-finite values are ignored.
    pub fn receive(&mut self, remote: &PortEnergy) {
        if remote.input.is_finite() {
            self.remote_input = self.remote_input.max(remote.input);
        }
    }

    /// Records one tick of power `p = f·v` into the two-port at this port for `dt` s. Returns
    /// [`energy`](Self::energy).
    pub fn observe_power(&mut self, dt: f64, power: f64) -> f64 {
        if power.is_finite() && dt.is_finite() && dt > 0.0 {
            if power > 0.0 {
                self.input += dt * power;
            } else {
                self.output -= dt * power;
            }
        }
        let e = self.energy();
        self.min_energy = self.min_energy.min(e);
        e
    }

    /// `E_in,remote - E_out,local`, J: the energy the two-port may still give out at this port.
    /// Negative: it has given out energy that never entered it (active, the sign of trouble).
    pub fn energy(&self) -> f64 {
        self.remote_input - self.output
    }

    /// What the energy would be after one more tick of `power`.
    pub fn energy_after(&self, dt: f64, power: f64) -> f64 {
        self.energy() + if power < 0.0 { dt * power } else { 0.0 }
    }

    /// The lowest energy seen, J (<= 0).
    pub fn min_energy(&self) -> f64 {
        self.min_energy
    }

    /// The counters to send to the other side.
    pub fn counters(&self) -> PortEnergy {
        PortEnergy { input: self.input }
    }

    /// Energy the passivity controller has dissipated at this port, J.
    pub fn dissipated(&self) -> f64 {
        self.dissipated
    }

    /// Back to nothing in or out (both sides must restart together).
    pub fn reset(&mut self) {
        *self = Self::new();
    }
}

/// How the passivity controller of a two-port port acts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PassivityForm {
    /// No controller: the observer only watches.
    #[default]
    Off,
    /// Impedance causality (the port's velocity is given, the law outputs a force): a variable
    /// damper in series with the force, `f' = f + alpha v`.
    Impedance,
    /// Admittance causality (the port's force is given, the law outputs a velocity): a variable
    /// conductance in parallel, `v' = v + beta f`.
    Admittance,
}

/// Settings of a [`TwoPortController`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwoPortConfig {
    /// Which controller, if any.
    pub form: PassivityForm,
    /// Largest damping `alpha` (impedance form), N·s/m.
    pub max_damping: f64,
    /// Largest conductance `beta` (admittance form), m/(N·s).
    pub max_conductance: f64,
    /// Below this speed (impedance) or force (admittance) nothing is added: it could not
    /// dissipate anything and would blow the gain up. m/s, N.
    pub min_flow: f64,
    /// Energy the port may give out beyond what it received before the controller acts, J:
    /// the initial stored energy `E0` of the passivity inequality `integral(P) >= -E0`, so a
    /// port held at `-E0` is still passive. Zero acts at once: on every sign of deficit, which
    /// in steady contact means acting on and off every few ticks (chatter).
    pub initial_energy: f64,
}

impl Default for TwoPortConfig {
    /// Off; at most 200 N·s/m or 0.05 m/(N·s); not below 1e-3 m/s or N.
    fn default() -> Self {
        TwoPortConfig {
            form: PassivityForm::Off,
            max_damping: 200.0,
            max_conductance: 0.05,
            min_flow: 1e-3,
            initial_energy: 0.0,
        }
    }
}

impl TwoPortConfig {
    /// Checks the values.
    ///
    /// # Errors
    /// [`TeleopConfigError`] for negative or NaN values.
    pub fn validate(&self) -> Result<(), TeleopConfigError> {
        check_cap(self.max_damping, "passivity.max_damping")?;
        check_cap(self.max_conductance, "passivity.max_conductance")?;
        check_gain(self.min_flow, "passivity.min_flow")?;
        check_gain(self.initial_energy, "passivity.initial_energy")
    }
}

/// A [`TwoPortObserver`] with the controller that dissipates exactly the deficit, bounded.
///
/// Each tick: [`correct_force`](Self::correct_force) or
/// [`correct_velocity`](Self::correct_velocity) proposes the corrected output from the law's output
/// and the port's measured flow, then [`commit`](Self::commit) records what was actually applied
/// (after any caps), so the observer stays true to the device.
///
/// # Real-time
/// All methods: `Copy` state, no allocation, constant time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwoPortController {
    config: TwoPortConfig,
    observer: TwoPortObserver,
    last_gain: f64,
}

impl TwoPortController {
    /// A controller with nothing in or out.
    ///
    /// # Errors
    /// As [`TwoPortConfig::validate`].
    pub fn new(config: TwoPortConfig) -> Result<Self, TeleopConfigError> {
        config.validate()?;
        Ok(TwoPortController {
            config,
            observer: TwoPortObserver::new(),
            last_gain: 0.0,
        })
    }

    /// The settings.
    pub fn config(&self) -> &TwoPortConfig {
        &self.config
    }

    /// Impedance form: the force `f + alpha v` that keeps the port's energy >= 0 with `force`
    /// (into the two-port) at `velocity` for `dt`, and `alpha`. `alpha = -W / (dt |v|²)` for
    /// the deficit `W < 0`, at most `max_damping`; 0 when the form is not
    /// [`PassivityForm::Impedance`].
    pub fn correct_force(
        &self,
        dt: f64,
        force: &Vector6<f64>,
        velocity: &Vector6<f64>,
    ) -> (Vector6<f64>, f64) {
        if self.config.form != PassivityForm::Impedance {
            return (*force, 0.0);
        }
        let alpha = self.gain(
            dt,
            force.dot(velocity),
            velocity.norm_squared(),
            self.config.max_damping,
        );
        (force + velocity * alpha, alpha)
    }

    /// Admittance form: the velocity `v + beta f` that keeps the port's energy >= 0 with
    /// `velocity` (out of the two-port) under `force` for `dt`, and `beta`. `beta = -W / (dt
    /// |f|²)` for the deficit `W < 0`, at most `max_conductance`; 0 when the form is not
    /// [`PassivityForm::Admittance`].
    pub fn correct_velocity(
        &self,
        dt: f64,
        force: &Vector6<f64>,
        velocity: &Vector6<f64>,
    ) -> (Vector6<f64>, f64) {
        if self.config.form != PassivityForm::Admittance {
            return (*velocity, 0.0);
        }
        let beta = self.gain(
            dt,
            force.dot(velocity),
            force.norm_squared(),
            self.config.max_conductance,
        );
        (velocity + force * beta, beta)
    }

    /// The gain that brings `energy_after(power)` back to zero through `flow2` (|v|² or |f|²).
    fn gain(&self, dt: f64, power: f64, flow2: f64, max: f64) -> f64 {
        if !(dt.is_finite() && dt > 0.0) || flow2 < self.config.min_flow * self.config.min_flow {
            return 0.0;
        }
        let w = self.observer.energy_after(dt, power) + self.config.initial_energy;
        if w.is_finite() && w < 0.0 && flow2 > 0.0 {
            (-w / (dt * flow2)).min(max)
        } else {
            0.0
        }
    }

    /// Records what was applied this tick: power `force·velocity` into the two-port for `dt`,
    /// with the controller's `gain` and the power it took, `dissipated` (W, >= 0). Returns the
    /// energy.
    pub fn commit(&mut self, dt: f64, power: f64, gain: f64, dissipated: f64) -> f64 {
        self.last_gain = gain;
        if dissipated.is_finite() && dt.is_finite() && dt > 0.0 {
            self.observer.dissipated += dt * dissipated.max(0.0);
        }
        self.observer.observe_power(dt, power)
    }

    /// Takes the other side's counters.
    pub fn receive(&mut self, remote: &PortEnergy) {
        self.observer.receive(remote);
    }

    /// The observer.
    pub fn observer(&self) -> &TwoPortObserver {
        &self.observer
    }

    /// The gain (`alpha` or `beta`) added on the last tick.
    pub fn last_gain(&self) -> f64 {
        self.last_gain
    }

    /// Back to nothing in or out.
    pub fn reset(&mut self) {
        self.observer.reset();
        self.last_gain = 0.0;
    }
}

#[cfg(test)]
#[path = "passivity_tests.rs"]
mod tests;
