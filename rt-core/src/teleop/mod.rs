//! Bilateral teleoperation: workspace mapping, the teleop channel, and the control laws.
//!
//! # The data flow of position-forward / force-back (the paper's test task)
//!
//! ```text
//!  master node                                         slave node
//!  control thread: ForceDisplay (tau = J^T F + g)      control thread: SlaveTracking (computed torque)
//!        ^ Reference::Wrench (master base)                   ^ Reference::Cartesian (slave base)
//!  TeleopChannel SlaveToMaster                         TeleopChannel MasterToSlave
//!   (k_f R_ms^T, clutch fade)                           (p_s = p_s0 + sigma R_ms (p_m - p_m0), clutch hold,
//!        ^ receive(sample: slave wrench + pose)           velocity estimate) ^ receive(sample: master pose)
//!  comm thread  <------------- UDP ----------------  comm thread  <--------- UDP ---------
//!  comm thread: track_master(pose, clutch), send {master pose, clutch}  -------------------->
//! ```
//!
//! - [`mapping`]: [`WorkspaceMapping`] (rotation `R_ms`, scale `sigma`, force gains, clutch with
//!   force fade and re-anchoring).
//! - [`channel`]: [`TeleopChannel`], a [`Trajectory`](penelope_hal::Trajectory) of kind `"teleop"`
//!   fed by the communication thread with [`TeleopSample`]s, newest-wins.
//! - Control laws ([`Controller`](penelope_hal::Controller)s):
//!   [`CartesianImpedance`] (also the slave half of position-error),
//!   [`SlaveTracking`] (position-forward slave: IK + computed torque),
//!   [`ForceDisplay`] (force-back master: `tau = J^T F`, deadband, damping, caps),
//!   [`PositionErrorMaster`] (position-error master: spring-damper to the mapped slave pose).
//! - [`passivity`]: [`PassivityObserver`] (Hannaford & Ryu, one port), and the two-port
//!   delayed form: [`TwoPortObserver`], [`TwoPortController`]
//!   (impedance or admittance form), the counters [`PortEnergy`] that travel with the samples.
//! - [`four_channel`] and [`four_channel_slave`]: Lawrence's four-channel architecture
//!   ([`FourChannelMaster`]: `C_2`, `C_4`, `C_6` and the local impedance; [`FourChannelSlave`]:
//!   `C_1`, `C_3`, `C_5`), the general form of which force-position and position-error are
//!   special cases.
//! - [`wave`]: wave variables ([`WaveMaster`], [`WaveSlave`]): passive under any delay, loss,
//!   duplication and reordering (an energy reserve on each receiving end).
//!
//! Which law sends what:
//!
//! | architecture | master sends | slave sends | master law | slave law |
//! |---|---|---|---|---|
//! | position-forward / force-back | tool pose (+ clutch) | sensor wrench (base) | [`ForceDisplay`] | [`SlaveTracking`] (or [`CartesianImpedance`]) |
//! | position-error | tool pose (+ clutch) | tool pose | [`PositionErrorMaster`] | [`CartesianImpedance`] |
//! | both (hybrid samples) | tool pose | pose + wrench (`Reference::Hybrid`) | either | either |
//! | wave variables | wave `u` (+ pose) in [`TeleopSample::port`] | wave `w` (+ pose, wrench) | [`WaveMaster`] transform, then [`ForceDisplay`] | [`WaveSlave`] transform, then [`SlaveTracking`] |
//!
//! # Real-time
//! Every `update`, `activate`, `receive`, `reference` and mapping call runs without allocation,
//! locks or blocking, in bounded time, and never panics; errors are small `Copy` enums.

pub mod channel;
pub mod display;
pub mod four_channel;
pub mod four_channel_slave;
pub mod impedance;
pub mod mapping;
pub mod passivity;
pub mod tracking;
pub mod wave;

use core::fmt;

use nalgebra::{Vector3, Vector6};
use penelope_hal::{
    ControllerError, Error, ErrorKind, Frame, JointCommand, JointVector, Pose, Twist, Wrench,
};

pub use channel::{
    ChannelConfig, ChannelDirection, ChannelStats, PortPayload, ReceiveError, TeleopChannel,
    TeleopSample, VelocityFeedForward,
};
pub use display::{ForceDisplay, ForceDisplayConfig};
pub use four_channel::{FourChannelConfig, FourChannelMaster};
pub use four_channel_slave::{FourChannelSlave, FourChannelSlaveConfig};
pub use impedance::{CartesianImpedance, ImpedanceConfig, PositionErrorMaster};
pub use mapping::{Anchors, MappingConfig, MappingError, WorkspaceMapping};
pub use passivity::{
    PassivityForm, PassivityObserver, PortEnergy, TwoPortConfig, TwoPortController, TwoPortObserver,
};
pub use tracking::{SlaveTracking, TrackingConfig, TrackingOutput};
pub use wave::{
    MissingWave, WaveConfig, WaveMaster, WaveMasterOutput, WaveReceiver, WaveSample, WaveSender,
    WaveSlave, WaveSlaveOutput, WaveStats,
};

/// A configuration value that cannot be used.
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TeleopConfigError {
    /// The named parameter is NaN or infinite where a finite value is required.
    NonFinite {
        /// The parameter's field name.
        parameter: &'static str,
    },
    /// The named parameter is outside its allowed range (for example a negative gain).
    OutOfRange {
        /// The parameter's field name.
        parameter: &'static str,
    },
}

impl fmt::Display for TeleopConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TeleopConfigError::NonFinite { parameter } => {
                write!(f, "parameter `{parameter}` is NaN or infinite")
            }
            TeleopConfigError::OutOfRange { parameter } => {
                write!(f, "parameter `{parameter}` is out of range")
            }
        }
    }
}

impl Error for TeleopConfigError {
    fn kind(&self) -> ErrorKind {
        match self {
            TeleopConfigError::NonFinite { .. } => ErrorKind::NonFinite,
            TeleopConfigError::OutOfRange { .. } => ErrorKind::InvalidInput,
        }
    }
}

/// Checks `x` is finite and `>= 0`.
pub(crate) fn check_gain(x: f64, parameter: &'static str) -> Result<(), TeleopConfigError> {
    if !x.is_finite() {
        Err(TeleopConfigError::NonFinite { parameter })
    } else if x < 0.0 {
        Err(TeleopConfigError::OutOfRange { parameter })
    } else {
        Ok(())
    }
}

/// Checks every entry is finite and `>= 0`.
pub(crate) fn check_gains(xs: &[f64], parameter: &'static str) -> Result<(), TeleopConfigError> {
    xs.iter().try_for_each(|&x| check_gain(x, parameter))
}

/// Checks `x` is `>= 0` (NaN refused); infinity allowed (a cap that does not cap).
pub(crate) fn check_cap(x: f64, parameter: &'static str) -> Result<(), TeleopConfigError> {
    if x.is_nan() || x < 0.0 {
        Err(TeleopConfigError::OutOfRange { parameter })
    } else {
        Ok(())
    }
}

/// The 6-vector pose error `[p_ref - p; log(R_ref R^T)]` in the base frame (m, rad; the
/// rotation part is the axis-angle vector of the shortest rotation from `actual` to `reference`).
pub fn pose_error(reference: &Pose, actual: &Pose) -> Vector6<f64> {
    let dp = reference.translation.vector - actual.translation.vector;
    let dr = (reference.rotation * actual.rotation.inverse()).scaled_axis();
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

/// A twist as a base-frame `[v; omega]`: `Base`/`Master` as is, `Tool`/`Flange` rotated by the
/// tool orientation of `pose`; `None` for a `Sensor`-frame twist.
pub(crate) fn twist_in_base(t: &Twist, pose: &Pose) -> Option<Vector6<f64>> {
    let (v, w) = match t.frame {
        Frame::Base | Frame::Master => (t.linear, t.angular),
        Frame::Tool | Frame::Flange => (pose.rotation * t.linear, pose.rotation * t.angular),
        Frame::Sensor => return None,
    };
    Some(Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z))
}

/// A wrench as a base-frame `[f; m]` (about the tool origin): `Base`/`Master` as is,
/// `Tool`/`Flange` rotated by the tool orientation; `None` for a `Sensor`-frame wrench (its mount
/// is unknown here).
pub(crate) fn wrench_in_base(w: &Wrench, pose: &Pose) -> Option<Vector6<f64>> {
    let (f, m) = match w.frame {
        Frame::Base | Frame::Master => (w.force, w.torque),
        Frame::Tool | Frame::Flange => (pose.rotation * w.force, pose.rotation * w.torque),
        Frame::Sensor => return None,
    };
    Some(Vector6::new(f.x, f.y, f.z, m.x, m.y, m.z))
}

/// The world's wrench on the robot as a base-frame `[f; m]` about the tool origin, for a tool
/// at `pose`: what a force law adds to its command.
///
/// - `Base`/`Master`/`Tool`/`Flange`: a feed or a model, already the world's wrench on the
///   robot, rotated into the base frame by the tool's orientation;
/// - `Sensor`: a six-axis sensor mounted at `mount` in the tool frame, which reads the robot
///   pushing on the world: moved to the tool origin, rotated into the base frame and negated.
///   `None` without a mount.
pub fn contact_in_base(w: &Wrench, pose: &Pose, mount: Option<&Pose>) -> Option<Vector6<f64>> {
    match (w.frame, mount) {
        (Frame::Sensor, Some(mount)) => Some(-sensor_to_base(w, mount, pose).to_vector()),
        _ => wrench_in_base(w, pose),
    }
}

/// A wrist-sensor reading (sensor frame, mounted at `mount` in the tool frame) as a wrench in
/// the robot's base frame about the tool origin, for a tool at `tool` (the sensor's sign kept:
/// the robot pushing on the world).
pub fn sensor_to_base(reading: &Wrench, mount: &Pose, tool: &Pose) -> Wrench {
    let in_tool = reading.expressed_in(&mount.inverse(), Frame::Tool);
    Wrench {
        force: tool.rotation * in_tool.force,
        torque: tool.rotation * in_tool.torque,
        frame: Frame::Base,
    }
}

/// Scales the whole wrench `[f; m]` by one factor so that `|f| <= max_force` and
/// `|m| <= max_torque`: the direction is kept. Returns the wrench and the factor (`<= 1`).
pub fn cap_wrench(w: &Vector6<f64>, max_force: f64, max_torque: f64) -> (Vector6<f64>, f64) {
    let f = w.fixed_rows::<3>(0).norm();
    let m = w.fixed_rows::<3>(3).norm();
    let mut k: f64 = 1.0;
    if f > max_force {
        k = k.min(max_force / f);
    }
    if m > max_torque {
        k = k.min(max_torque / m);
    }
    (w * k, k)
}

/// A continuous dead band on a vector's length: zero inside `band`, shrunk by `band` outside
/// (direction kept).
pub(crate) fn deadband(v: Vector3<f64>, band: f64) -> Vector3<f64> {
    let n = v.norm();
    if n <= band || n == 0.0 {
        Vector3::zeros()
    } else {
        v * ((n - band) / n)
    }
}

/// The gain of a first-order low-pass with corner `cutoff_hz` sampled at `dt` seconds
/// (exact discretisation `1 - exp(-2 pi f dt)`); 1 (no filtering) for a cutoff of 0 or less.
pub(crate) fn lowpass_gain(cutoff_hz: f64, dt: f64) -> f64 {
    if cutoff_hz <= 0.0 || dt <= 0.0 {
        1.0
    } else {
        1.0 - libm::exp(-2.0 * core::f64::consts::PI * cutoff_hz * dt)
    }
}

/// `Effort(tau)` when every entry is finite, else [`ControllerError::NonFinite`].
pub(crate) fn effort(tau: JointVector) -> Result<JointCommand, ControllerError> {
    if tau.iter().all(|x| x.is_finite()) {
        Ok(JointCommand::Effort(tau))
    } else {
        Err(ControllerError::NonFinite)
    }
}

/// `[a; b]` from two 3-vectors.
pub(crate) fn stack(a: &Vector3<f64>, b: &Vector3<f64>) -> Vector6<f64> {
    Vector6::new(a.x, a.y, a.z, b.x, b.y, b.z)
}

/// The linear part of `[a; b]`.
pub(crate) fn top(v: &Vector6<f64>) -> Vector3<f64> {
    v.fixed_rows::<3>(0).into()
}

/// The angular part of `[a; b]`.
pub(crate) fn bottom(v: &Vector6<f64>) -> Vector3<f64> {
    v.fixed_rows::<3>(3).into()
}
