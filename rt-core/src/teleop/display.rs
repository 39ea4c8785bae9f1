//! Kinesthetic force display: the master half of position-forward / force-back.

use nalgebra::Vector6;
use penelope_hal::{
    ControlInput, Controller, ControllerError, Frame, JacobianFrame, JointCommand, JointState,
    Reference, RobotModel, Timestamp, Wrench,
};

use super::passivity::PassivityObserver;
use super::{
    TeleopConfigError, bottom, cap_wrench, check_cap, check_gain, check_gains, deadband, effort,
    lowpass_gain, stack, top, wrench_in_base,
};

/// Settings of a [`ForceDisplay`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceDisplayConfig {
    /// Forces smaller than this are not displayed (the sensor's noise level), N. The band is
    /// subtracted from the force's length, so the display is continuous.
    pub force_deadband: f64,
    /// Moments smaller than this are not displayed, N·m.
    pub torque_deadband: f64,
    /// Added master damping on the tool twist `[v; omega]`: N·s/m, then N·m·s/rad.
    pub damping: [f64; 6],
    /// Largest displayed force, N (the FRHC's is about 10 N).
    pub max_force: f64,
    /// Largest displayed moment, N·m (the FRHC's is about 0.5 N·m).
    pub max_torque: f64,
    /// Corner of the first-order low-pass on the reference wrench, Hz (0: no filter).
    pub filter_cutoff_hz: f64,
    /// Add the master's gravity torque `g(q)`.
    pub gravity_compensation: bool,
}

impl Default for ForceDisplayConfig {
    /// For an FRHC: 0.2 N / 0.01 N·m dead band, 2 N·s/m and 0.02 N·m·s/rad damping, 10 N /
    /// 0.5 N·m caps, 30 Hz filter, gravity compensated.
    fn default() -> Self {
        ForceDisplayConfig {
            force_deadband: 0.2,
            torque_deadband: 0.01,
            damping: [2.0, 2.0, 2.0, 0.02, 0.02, 0.02],
            max_force: 10.0,
            max_torque: 0.5,
            filter_cutoff_hz: 30.0,
            gravity_compensation: true,
        }
    }
}

impl ForceDisplayConfig {
    /// Checks the values.
    ///
    /// # Errors
    /// [`TeleopConfigError`] for negative or non-finite values (caps may be infinite).
    pub fn validate(&self) -> Result<(), TeleopConfigError> {
        check_gain(self.force_deadband, "force_deadband")?;
        check_gain(self.torque_deadband, "torque_deadband")?;
        check_gains(&self.damping, "damping")?;
        check_cap(self.max_force, "max_force")?;
        check_cap(self.max_torque, "max_torque")?;
        check_gain(self.filter_cutoff_hz, "filter_cutoff_hz")
    }
}

/// Displays a wrench on a master hand controller:
/// `F = cap(deadband(lowpass(F_ref)) - D v)`, `tau = J^T F + g(q)`, with `J^T F` from
/// the model's [`RobotModel::wrench_to_torques`] (where the robot's board computes it, the
/// board's result).
///
/// The reference is a `Reference::Wrench` (or the wrench of a `Reference::Hybrid`) already in the
/// master's base frame with the force gain applied: what a `SlaveToMaster`
/// [`TeleopChannel`](super::TeleopChannel) produces (`Base`/`Master` frame; a `Tool`-frame wrench
/// is rotated with the forward kinematics). The cap scales the whole wrench by one factor so its
/// direction is kept.
///
/// A one-port [`PassivityObserver`] watches the master port (operator force `-F`, tool twist).
/// Under delay the two-port form is the one to act on: a teleoperation channel's end runs it on
/// the reference wrench before it gets here
/// ([`TwoPortController`](super::TwoPortController), impedance form).
///
/// On activation the filter starts from zero, so the display fades in over the filter's time
/// constant instead of jumping.
///
/// # Real-time
/// `activate` and `update`: no allocation, no blocking, constant time, no panics.
#[derive(Clone, Copy, Debug)]
pub struct ForceDisplay {
    config: ForceDisplayConfig,
    filtered: Vector6<f64>,
    observer: PassivityObserver,
    last_wrench: Wrench,
    saturation: f64,
}

impl ForceDisplay {
    /// A display with these settings.
    ///
    /// # Errors
    /// As [`ForceDisplayConfig::validate`].
    pub fn new(config: ForceDisplayConfig) -> Result<Self, TeleopConfigError> {
        config.validate()?;
        Ok(ForceDisplay {
            config,
            filtered: Vector6::zeros(),
            observer: PassivityObserver::new(),
            last_wrench: Wrench::zero(Frame::Base),
            saturation: 1.0,
        })
    }

    /// The settings.
    pub fn config(&self) -> &ForceDisplayConfig {
        &self.config
    }

    /// New settings while running: the filter and the passivity observer keep their state, so
    /// nothing jumps but the gains.
    ///
    /// # Errors
    /// As [`ForceDisplayConfig::validate`]; the old settings stay.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    pub fn set_config(&mut self, config: ForceDisplayConfig) -> Result<(), TeleopConfigError> {
        config.validate()?;
        self.config = config;
        Ok(())
    }

    /// The wrench displayed on the last tick (master base frame, about the tool origin).
    pub fn last_wrench(&self) -> &Wrench {
        &self.last_wrench
    }

    /// The cap's scale factor on the last tick: 1 when within the limits, less when capped.
    pub fn saturation(&self) -> f64 {
        self.saturation
    }

    /// The energy observer of the master port (operator force `-F`, tool twist).
    pub fn passivity(&self) -> &PassivityObserver {
        &self.observer
    }
}

/// The force channel of a master: `wanted` (base frame) through the low-pass whose state is
/// `filtered`, then the dead bands of `config`. Shared with the four-channel master. No wrench
/// (`None`: the slave's sensor failed) is zero at once, not a fade through the filter: what
/// the filter holds came from the failed sensor.
pub(crate) fn force_channel(
    filtered: &mut Vector6<f64>,
    wanted: Option<&Vector6<f64>>,
    config: &ForceDisplayConfig,
    dt: f64,
) -> Vector6<f64> {
    let Some(wanted) = wanted else {
        *filtered = Vector6::zeros();
        return Vector6::zeros();
    };
    *filtered += (wanted - *filtered) * lowpass_gain(config.filter_cutoff_hz, dt);
    stack(
        &deadband(top(filtered), config.force_deadband),
        &deadband(bottom(filtered), config.torque_deadband),
    )
}

/// The reference's wrench (a `Wrench`, or a `Hybrid`'s) as a base-frame `[f; m]`; `None` for
/// a `Hybrid` without any force axis, which carries no wrench (a slave whose sensor failed
/// sends that).
///
/// # Errors
/// [`ControllerError::UnsupportedReference`] for a reference without a wrench, or one in the
/// sensor frame.
pub(crate) fn reference_wrench(
    input: &ControlInput<'_>,
) -> Result<Option<Vector6<f64>>, ControllerError> {
    let wanted = match input.reference {
        Reference::Wrench(w) => w,
        Reference::Hybrid(h) if !h.force_axes.contains(&true) => return Ok(None),
        Reference::Hybrid(h) => &h.wrench,
        _ => return Err(ControllerError::UnsupportedReference),
    };
    match wanted.frame {
        Frame::Base | Frame::Master => Ok(Some(wanted.to_vector())),
        _ => wrench_in_base(wanted, &input.model.forward(&input.state.position))
            .map(Some)
            .ok_or(ControllerError::UnsupportedReference),
    }
}

/// The joint torques that display the base-frame wrench `f` (plus gravity when asked), and `f`
/// as a [`Wrench`]: `J^T f` is the model's own force transformation (on an FPGA board, the
/// board computes it).
///
/// # Errors
/// [`ControllerError::NonFinite`] when the model refuses the wrench.
pub(crate) fn display_torques(
    input: &ControlInput<'_>,
    f: &Vector6<f64>,
    gravity_compensation: bool,
) -> Result<(penelope_hal::JointVector, Wrench), ControllerError> {
    let q = &input.state.position;
    let shown = Wrench {
        force: top(f),
        torque: bottom(f),
        frame: Frame::Base,
    };
    let mut tau = input
        .model
        .wrench_to_torques(q, &shown)
        .map_err(|_| ControllerError::NonFinite)?;
    if gravity_compensation {
        tau += input.model.gravity(q);
    }
    Ok((tau, shown))
}

impl Controller for ForceDisplay {
    fn kind(&self) -> &'static str {
        "force-display"
    }

    fn port_energy(&self) -> Option<f64> {
        Some(self.observer.energy())
    }

    fn activate(&mut self, _now: Timestamp, _measured: &JointState, _model: &dyn RobotModel) {
        self.filtered = Vector6::zeros();
        self.observer.reset();
        self.last_wrench = Wrench::zero(Frame::Base);
        self.saturation = 1.0;
    }

    fn update(&mut self, input: &ControlInput<'_>) -> Result<JointCommand, ControllerError> {
        if !input.state.is_finite() {
            return Err(ControllerError::NonFinite);
        }
        let model = input.model;
        let q = &input.state.position;
        let jac = model.jacobian(q, JacobianFrame::Base);
        let wanted = reference_wrench(input)?;
        let dt = input.period.as_secs_f64();
        let shown = force_channel(&mut self.filtered, wanted.as_ref(), &self.config, dt);
        let v = jac * input.state.velocity;
        let f = shown - Vector6::from(self.config.damping).component_mul(&v);
        let (f, k) = cap_wrench(&f, self.config.max_force, self.config.max_torque);
        // The operator applies about -f to the device: that is the power into the system.
        self.observer.observe(dt, &(-f), &v);
        self.saturation = k;
        let (tau, shown) = display_torques(input, &f, self.config.gravity_compensation)?;
        self.last_wrench = shown;
        effort(tau)
    }
}
