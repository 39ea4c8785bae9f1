//! Robot models from DH tables (the PUMA 560, the PUMA 200, the FRHC, or any robot a lab
//! describes in a DH file) or from URDF files.
//!
//! # Layers
//!
//! - [`dh`]: one standard-DH row ([`DhLink`]) and its transform.
//! - [`chain`]: a [`SerialChain`] of rows between a base and a tool transform: forward kinematics
//!   and the geometric Jacobian (base or tool frame).
//! - [`puma`]: the closed-form inverse kinematics of the PUMA structure, 8 named branches.
//! - [`numeric_ik`]: damped least squares for any chain.
//! - [`dynamics`]: gravity (holding torque), inertia (composite rigid body), recursive
//!   Newton-Euler, friction; [`LinkDynamics`] per link.
//! - [`robot`]: [`SerialRobotModel`] (implements the hal `Kinematics`, `InverseKinematics`,
//!   `Dynamics`, `RobotModel`) and [`DhRobot`] (the hal `Robot`: model + measured state).
//! - [`file`](mod@file): the TOML DH-file format. The built-in robots are the files in
//!   `drivers/robots/`, embedded, so they are defined exactly as a lab's file is.
//! - [`urdf`]: a robot from a URDF file: the joints between a base and a tip link become
//!   [`AxisJoint`]s of the same [`SerialChain`], the links' inertials its [`LinkDynamics`].
//!
//! # Example
//!
//! ```
//! use penelope_drivers::model;
//! use penelope_hal::{IkSolutions, InverseKinematics, Kinematics, Dynamics, NamedPose};
//!
//! let puma = model::puma560();
//! let q = puma.named_pose(NamedPose::Start);
//! let pose = puma.forward(&q);
//! let mut sols = IkSolutions::new();
//! assert_eq!(puma.inverse_all(&pose, &mut sols).unwrap(), 8);
//! let hold = puma.gravity(&q); // N·m that hold the arm still
//! assert!(hold[1] > 30.0);
//! ```
//!
//! # Real-time
//! Every kinematics and dynamics call works on fixed-size stack values: no allocation, no
//! locks, bounded time. Loading a model (parsing a file) allocates and belongs at start-up.

pub mod axis_joint;
pub mod chain;
pub mod dh;
mod dh6;
pub mod dynamics;
pub mod file;
pub mod links;
pub mod numeric_ik;
pub mod puma;
pub mod robot;
pub mod urdf;

pub use axis_joint::AxisJoint;
pub use chain::{ChainError, ChainJoint, SerialChain};
pub use dh::{DhLink, JointKind};
pub use dynamics::LinkDynamics;
pub use file::{FileError, RobotFile};
pub use links::LinkTree;
pub use numeric_ik::DlsOptions;
pub use robot::{DhRobot, IkMethod, ModelError, ModelSpec, SerialRobotModel};
pub use urdf::{UrdfChain, UrdfError};

/// The PUMA 560 DH file (the Robotics Toolbox reference model).
pub const PUMA560_TOML: &str = include_str!("../../robots/puma560.toml");
/// The PUMA 200 DH file (public PUMA 260 geometry; dynamics assumed).
pub const PUMA200_TOML: &str = include_str!("../../robots/puma200.toml");
/// The FRHC DH file (the documented working model, an assumption).
pub const FRHC_TOML: &str = include_str!("../../robots/frhc.toml");

/// The names [`by_name`] knows.
pub const BUILT_IN: [&str; 3] = ["puma560", "puma200", "frhc"];

fn built_in(kind: &'static str, text: &str) -> SerialRobotModel {
    match file::model_from_str(kind, text) {
        Ok(m) => m,
        // The embedded files are checked by this crate's tests; a failure here is a build defect.
        Err(e) => panic!("built-in robot file `{kind}` is invalid: {e}"),
    }
}

/// The PUMA 560 with its pedestal (d1 = 0.67183 m), as in the Robotics Toolbox 1.5.0.
pub fn puma560() -> SerialRobotModel {
    built_in("puma560", PUMA560_TOML)
}

/// The PUMA 560 with pedestal height `d1` (m, mounting surface to the shoulder axis); `0.0` gives
/// the older MATLAB toolbox's model.
///
/// # Errors
/// [`ModelError`] for a non-finite `d1`.
pub fn puma560_with_pedestal(d1: f64) -> Result<SerialRobotModel, ModelError> {
    let mut spec = RobotFile::parse(PUMA560_TOML)
        .map_err(|e| ModelError::Invalid(e.to_string()))?
        .to_spec()?;
    if let Some(ChainJoint::Dh(waist)) = spec.joints.first_mut() {
        waist.d = d1;
    }
    SerialRobotModel::new("puma560", spec)
}

/// The PUMA 200 (public PUMA 260 geometry, flange as the tool transform; dynamics assumed).
pub fn puma200() -> SerialRobotModel {
    built_in("puma200", PUMA200_TOML)
}

/// The FRHC hand controller's working model (an assumption; see its file).
pub fn frhc() -> SerialRobotModel {
    built_in("frhc", FRHC_TOML)
}

/// A built-in model by name: `"puma560"`, `"puma200"` or `"frhc"`.
pub fn by_name(name: &str) -> Option<SerialRobotModel> {
    match name {
        "puma560" => Some(puma560()),
        "puma200" => Some(puma200()),
        "frhc" => Some(frhc()),
        _ => None,
    }
}

/// A model from DH-file text; its kind is `"dh"`.
///
/// # Errors
/// [`FileError`] for bad TOML or values.
pub fn from_toml_str(text: &str) -> Result<SerialRobotModel, FileError> {
    file::model_from_str("dh", text)
}

/// A model from a DH file on disk; its kind is `"dh"`.
///
/// # Errors
/// [`FileError`] when the file cannot be read or is invalid.
pub fn from_file(path: impl AsRef<std::path::Path>) -> Result<SerialRobotModel, FileError> {
    file::model_from_file(path)
}

/// A model from a URDF file, from its root link to `tip` (`None`: the single leaf link); its
/// kind is `"urdf"`.
///
/// # Errors
/// [`UrdfError`] naming the element at fault.
pub fn from_urdf_file(
    path: impl AsRef<std::path::Path>,
    tip: Option<&str>,
) -> Result<SerialRobotModel, UrdfError> {
    let chain = UrdfChain {
        base: None,
        tip: tip.map(str::to_string),
    };
    urdf::model_from_file(path, &chain)
}

/// True when `path` names a URDF file (it ends in `.urdf`, any case).
pub fn is_urdf_path(path: &str) -> bool {
    std::path::Path::new(path)
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("urdf"))
}

/// A built-in name, or else the path of a DH file, or of a URDF file when it ends in `.urdf`
/// (the chain from the root to the single leaf link): what the command line accepts.
///
/// # Errors
/// [`FileError`]; a name that is neither built in nor an existing file gives [`FileError::Io`].
pub fn load(name_or_path: &str) -> Result<SerialRobotModel, FileError> {
    match by_name(name_or_path) {
        Some(m) => Ok(m),
        None if is_urdf_path(name_or_path) => Ok(from_urdf_file(name_or_path, None)?),
        None => from_file(name_or_path),
    }
}
