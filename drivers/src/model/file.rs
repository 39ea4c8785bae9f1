//! The DH file: a robot model as TOML, the format a lab fills in with its measured values.
//!
//! The built-in robots are defined by the same files (`drivers/robots/*.toml`, embedded in the
//! binary), so the shipped files are complete, commented examples. In short:
//!
//! ```toml
//! name = "myarm"                      # short name
//! description = "where the numbers come from"
//! assumptions = ["masses are guesses"] # values that are not measurements (optional)
//! gravity = [0.0, 0.0, -9.81]         # m/s², world frame (optional, this is the default)
//! inverse_kinematics = "auto"         # "auto" (closed form if PUMA-like) or "numerical"
//!
//! [units]                             # optional; defaults m and rad
//! length = "m"                        # "m", "mm" or "in": d, a, com, base/tool xyz, prismatic q
//! angle = "deg"                       # "rad" or "deg": alpha, offset, theta, limits, rpy, poses
//!
//! [base]                              # optional: frame 0 in the world frame
//! xyz = [0.0, 0.0, 0.0]
//! rpy = [0.0, 0.0, 0.0]               # roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll)
//!
//! [tool]                              # optional: tool frame in the last link frame
//! xyz = [0.0, 0.0, 0.05]
//!
//! [[joints]]                          # one table per joint, base to tip
//! name = "waist"                      # optional
//! type = "revolute"                   # or "prismatic" (then give theta, and d is the variable)
//! d = 0.5                             # standard DH: A = Rz(theta) Tz(d) Tx(a) Rx(alpha)
//! a = 0.0
//! alpha = 90.0
//! offset = 0.0                        # theta = q + offset (optional, default 0)
//! limits = [-160.0, 160.0]            # optional (unbounded otherwise)
//! velocity_max = 120.0                # angle unit per second (optional)
//! effort_max = 97.6                   # N·m (N for prismatic), optional
//! gear_ratio = -62.6111               # motor turns per joint turn (sign = direction), default 1
//! encoder_counts_per_rev = 1000       # counts per motor turn, default 2π (1 count per motor rad)
//! [joints.dynamics]                   # optional (massless without)
//! mass = 17.4                         # kg
//! com = [-0.3638, 0.006, 0.2275]      # length unit, link frame
//! inertia = [0.13, 0.524, 0.539]      # kg·m² about the COM: Ixx Iyy Izz [Ixy Iyz Ixz]
//! motor_inertia = 200e-6              # kg·m² at the motor
//! viscous = 0.817e-3                  # N·m·s/rad at the motor
//! coulomb = [0.126, -0.071]           # N·m at the motor, for qd > 0 and qd < 0
//!
//! [poses]                             # angle unit; nest, start and work are required
//! nest = [0, 0, 0, 0, 0, 0]
//! ```
//!
//! Unknown keys are errors (a typo must not silently leave a default in place).

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Matrix3, Translation3, UnitQuaternion, Vector3};
use penelope_hal::{JointLimits, JointVector, MAX_JOINTS, Pose};
use serde::{Deserialize, Serialize};

use super::chain::ChainJoint;
use super::dh::DhLink;
use super::dynamics::LinkDynamics;
use super::robot::{IkMethod, ModelError, ModelSpec, SerialRobotModel};

/// Why a DH file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The path given.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The text is not valid TOML or does not match the format.
    #[error("{0}")]
    Parse(#[from] toml::de::Error),
    /// The values do not make a valid model.
    #[error("{0}")]
    Model(#[from] ModelError),
    /// A URDF file that does not make a model.
    #[error("{0}")]
    Urdf(#[from] super::urdf::UrdfError),
}

/// Length unit of a DH file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LengthUnit {
    /// Metres.
    #[default]
    M,
    /// Millimetres.
    Mm,
    /// Inches.
    In,
}

impl LengthUnit {
    /// Metres per unit.
    pub fn to_metres(self) -> f64 {
        match self {
            LengthUnit::M => 1.0,
            LengthUnit::Mm => 1e-3,
            LengthUnit::In => 0.0254,
        }
    }
}

/// Angle unit of a DH file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AngleUnit {
    /// Radians.
    #[default]
    Rad,
    /// Degrees.
    Deg,
}

impl AngleUnit {
    /// Radians per unit.
    pub fn to_radians(self, x: f64) -> f64 {
        match self {
            AngleUnit::Rad => x,
            AngleUnit::Deg => x.to_radians(),
        }
    }
}

/// The `[units]` table.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Units {
    /// Unit of lengths.
    #[serde(default)]
    pub length: LengthUnit,
    /// Unit of angles.
    #[serde(default)]
    pub angle: AngleUnit,
}

/// A `[base]` or `[tool]` transform.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformEntry {
    /// Translation, length unit.
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Roll, pitch, yaw (fixed axes x, y, z), angle unit.
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// The `inverse_kinematics` key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IkEntry {
    /// Closed form when the chain is PUMA-like, else numerical.
    #[default]
    Auto,
    /// Always numerical.
    Numerical,
}

/// The joint type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointType {
    /// Rotates.
    #[default]
    Revolute,
    /// Slides.
    Prismatic,
}

/// A `[joints.dynamics]` table.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsEntry {
    /// kg.
    #[serde(default)]
    pub mass: f64,
    /// Centre of mass in the link frame, length unit.
    #[serde(default)]
    pub com: [f64; 3],
    /// `[Ixx, Iyy, Izz]` or `[Ixx, Iyy, Izz, Ixy, Iyz, Ixz]` about the COM, kg·m².
    #[serde(default)]
    pub inertia: Vec<f64>,
    /// Rotor inertia at the motor, kg·m².
    #[serde(default)]
    pub motor_inertia: f64,
    /// Viscous friction at the motor, N·m·s/rad.
    #[serde(default)]
    pub viscous: f64,
    /// Coulomb friction at the motor for positive and negative speed, N·m.
    #[serde(default)]
    pub coulomb: [f64; 2],
}

/// A `[[joints]]` table.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointEntry {
    /// Joint name.
    pub name: Option<String>,
    /// Revolute or prismatic.
    #[serde(rename = "type", default)]
    pub kind: JointType,
    /// Fixed angle of a prismatic joint, angle unit.
    #[serde(default)]
    pub theta: f64,
    /// Offset along the previous z, length unit (revolute joints).
    #[serde(default)]
    pub d: f64,
    /// Length along the new x, length unit.
    #[serde(default)]
    pub a: f64,
    /// Twist about the new x, angle unit.
    #[serde(default)]
    pub alpha: f64,
    /// Added to the joint variable, angle (or length) unit.
    #[serde(default)]
    pub offset: f64,
    /// `[min, max]`, angle (or length) unit.
    pub limits: Option<[f64; 2]>,
    /// Largest speed, angle (or length) unit per second.
    pub velocity_max: Option<f64>,
    /// Largest torque, N·m (force, N, for prismatic joints).
    pub effort_max: Option<f64>,
    /// Motor turns per joint turn (motor radians per metre for a prismatic joint); sign gives
    /// direction.
    pub gear_ratio: Option<f64>,
    /// Encoder counts per motor turn.
    pub encoder_counts_per_rev: Option<f64>,
    /// Mass properties and drive.
    pub dynamics: Option<DynamicsEntry>,
}

/// A whole DH file.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotFile {
    /// Short name.
    pub name: String,
    /// Where the numbers come from.
    #[serde(default)]
    pub description: String,
    /// Values that are assumptions.
    #[serde(default)]
    pub assumptions: Vec<String>,
    /// Units of the numbers below.
    #[serde(default)]
    pub units: Units,
    /// Gravity in the world frame, m/s².
    pub gravity: Option<[f64; 3]>,
    /// Inverse-kinematics method.
    #[serde(default)]
    pub inverse_kinematics: IkEntry,
    /// Frame 0 in the world frame.
    pub base: Option<TransformEntry>,
    /// Tool frame in the last link frame.
    pub tool: Option<TransformEntry>,
    /// The DH table, base to tip.
    pub joints: Vec<JointEntry>,
    /// Named configurations, angle (or length) unit.
    #[serde(default)]
    pub poses: BTreeMap<String, Vec<f64>>,
}

impl RobotFile {
    /// Parses TOML text.
    ///
    /// # Errors
    /// [`FileError::Parse`] with the line and column of the problem.
    pub fn parse(text: &str) -> Result<Self, FileError> {
        Ok(toml::from_str(text)?)
    }

    /// The model definition in SI units.
    ///
    /// # Errors
    /// [`ModelError`] for a wrong joint count or malformed entries.
    pub fn to_spec(&self) -> Result<ModelSpec, ModelError> {
        let n = self.joints.len();
        if n == 0 || n > MAX_JOINTS {
            return Err(ModelError::Invalid(format!(
                "a robot needs 1 to {MAX_JOINTS} joints, the file has {n}"
            )));
        }
        let len = self.units.length.to_metres();
        let ang = |x: f64| self.units.angle.to_radians(x);
        // Joint variables are angles for revolute joints, lengths for prismatic ones.
        let var = |j: usize, x: f64| match self.joints[j].kind {
            JointType::Revolute => ang(x),
            JointType::Prismatic => x * len,
        };
        let transform = |t: &Option<TransformEntry>| {
            let t = t.unwrap_or_default();
            Pose::from_parts(
                Translation3::new(t.xyz[0] * len, t.xyz[1] * len, t.xyz[2] * len),
                UnitQuaternion::from_euler_angles(ang(t.rpy[0]), ang(t.rpy[1]), ang(t.rpy[2])),
            )
        };
        let mut links = Vec::with_capacity(n);
        let mut dynamics = Vec::with_capacity(n);
        let mut counts = Vec::with_capacity(n);
        let mut names = Vec::with_capacity(n);
        let mut limits = JointLimits::unbounded();
        for (j, e) in self.joints.iter().enumerate() {
            links.push(ChainJoint::Dh(match e.kind {
                JointType::Revolute => {
                    DhLink::revolute(e.d * len, e.a * len, ang(e.alpha), ang(e.offset))
                }
                JointType::Prismatic => {
                    DhLink::prismatic(ang(e.theta), e.a * len, ang(e.alpha), e.offset * len)
                }
            }));
            names.push(e.name.clone().unwrap_or_else(|| format!("q{}", j + 1)));
            if let Some([lo, hi]) = e.limits {
                limits.position_min[j] = var(j, lo);
                limits.position_max[j] = var(j, hi);
            }
            if let Some(v) = e.velocity_max {
                limits.velocity_max[j] = var(j, v);
            }
            if let Some(t) = e.effort_max {
                limits.effort_max[j] = t;
            }
            let gear = e.gear_ratio.unwrap_or(1.0);
            let cpr = e.encoder_counts_per_rev.unwrap_or(core::f64::consts::TAU);
            counts.push(cpr * gear / core::f64::consts::TAU);
            dynamics.push(link_dynamics(j, e, gear, len)?);
        }
        let poses = self.poses_in_si(&var)?;
        let g = self.gravity.unwrap_or([0.0, 0.0, -9.81]);
        Ok(ModelSpec {
            name: self.name.clone(),
            description: self.description.clone(),
            assumptions: self.assumptions.clone(),
            joint_names: names,
            joints: links,
            dynamics,
            base: transform(&self.base),
            tool: transform(&self.tool),
            gravity: Vector3::new(g[0], g[1], g[2]),
            limits,
            counts_per_radian: counts,
            poses,
            ik: match self.inverse_kinematics {
                IkEntry::Auto => IkMethod::Auto,
                IkEntry::Numerical => IkMethod::Numerical,
            },
            links: None,
        })
    }

    /// The named poses in SI units (each with one value per joint): the standard poses first,
    /// then the others in name order.
    fn poses_in_si(
        &self,
        var: &dyn Fn(usize, f64) -> f64,
    ) -> Result<Vec<(String, JointVector)>, ModelError> {
        let n = self.joints.len();
        let mut poses = Vec::with_capacity(self.poses.len());
        // Standard poses first, then the others in name order.
        let mut ordered: Vec<(&String, &Vec<f64>)> = self.poses.iter().collect();
        ordered.sort_by_key(|(name, _)| match name.as_str() {
            "nest" => 0,
            "start" => 1,
            "work" => 2,
            _ => 3,
        });
        for (name, values) in ordered {
            if values.len() != n {
                return Err(ModelError::Invalid(format!(
                    "pose `{name}` has {} values, the robot has {n} joints",
                    values.len()
                )));
            }
            let mut q = JointVector::zeros();
            for (j, v) in values.iter().enumerate() {
                q[j] = var(j, *v);
            }
            poses.push((name.clone(), q));
        }
        Ok(poses)
    }
}

/// Joint `j`'s link dynamics from its entry `e` (lengths scaled by `len`); the inertia is
/// the diagonal (3 values) or the full symmetric matrix (6 values).
fn link_dynamics(
    j: usize,
    e: &JointEntry,
    gear: f64,
    len: f64,
) -> Result<LinkDynamics, ModelError> {
    let d = e.dynamics.clone().unwrap_or_default();
    let inertia = match d.inertia.as_slice() {
        [] => Matrix3::zeros(),
        [xx, yy, zz] => Matrix3::from_diagonal(&Vector3::new(*xx, *yy, *zz)),
        [xx, yy, zz, xy, yz, xz] => Matrix3::new(*xx, *xy, *xz, *xy, *yy, *yz, *xz, *yz, *zz),
        other => {
            return Err(ModelError::Invalid(format!(
                "joint {}: inertia needs 3 or 6 values, got {}",
                j + 1,
                other.len()
            )));
        }
    };
    Ok(LinkDynamics {
        mass: d.mass,
        com: Vector3::new(d.com[0], d.com[1], d.com[2]) * len,
        inertia,
        motor_inertia: d.motor_inertia,
        gear_ratio: gear,
        viscous: d.viscous,
        coulomb: d.coulomb,
    })
}

/// Parses a DH file's text into a model whose [`kind`](SerialRobotModel::kind) is `kind`.
///
/// # Errors
/// [`FileError::Parse`] or [`FileError::Model`].
pub fn model_from_str(kind: &'static str, text: &str) -> Result<SerialRobotModel, FileError> {
    let spec = RobotFile::parse(text)?.to_spec()?;
    Ok(SerialRobotModel::new(kind, spec)?)
}

/// Loads a lab's DH file; the model's kind is `"dh"`.
///
/// # Errors
/// [`FileError`] when the file cannot be read, parsed or turned into a model.
pub fn model_from_file(path: impl AsRef<Path>) -> Result<SerialRobotModel, FileError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|source| FileError::Io {
        path: path.display().to_string(),
        source,
    })?;
    model_from_str("dh", &text)
}
