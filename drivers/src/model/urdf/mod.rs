//! Robots from URDF: a serial chain of a URDF's joints between a base link and a tip link, with
//! the links' inertials for the dynamics.
//!
//! # What becomes what
//!
//! - Every `revolute`, `continuous` and `prismatic` joint on the path from the base link to the
//!   tip link becomes one [`AxisJoint`](super::axis_joint::AxisJoint): its `<origin xyz rpy>`,
//!   then motion about (along) its `<axis>` (normalised; default `1 0 0` as in URDF).
//! - `fixed` joints are folded: into the next moving joint's origin, or, after the last one, into
//!   the tool transform (so a fixed tool or flange link is the tool frame).
//! - `<limit lower upper velocity effort>` become the joint limits; a `continuous` joint has no
//!   position limits; a velocity or effort of 0 (or a missing `<limit>`) means "not given" and
//!   becomes unbounded. `<dynamics damping friction>` become viscous and symmetric Coulomb
//!   friction at the joint (gear ratio 1, no rotor inertia: URDF has none).
//! - Each moving joint's link body is its child link plus every link fixed to it (through fixed
//!   joints, on or off the path): masses, centres of mass and inertia tensors (about the centre
//!   of mass, in the `<inertial><origin>` frame) are combined in the child link's frame. Links
//!   fixed to the base link carry no dynamics (they do not move). Subtrees hanging off the chain
//!   behind moving joints that are not on it are left out of the dynamics and listed in the
//!   model's assumptions.
//! - The world frame is the base link's frame; gravity is `[0, 0, -9.81]`. Named poses `nest`,
//!   `start` and `work` are all the zero configuration (a joint whose limits do not hold zero
//!   strictly inside: the middle of its range). URDF gives no encoders: a joint is read as by a
//!   19-bit absolute encoder on the joint ([`URDF_COUNTS_PER_RADIAN`]), a prismatic one at 1 µm
//!   ([`URDF_COUNTS_PER_METRE`]).
//!
//! Refused, with a [`UrdfError`] naming the element: `floating`, `planar` and `spherical` joints,
//! `<mimic>` joints, closed chains (a link with two parents, or a loop of joints), links that a
//! joint names but the file does not define, duplicate names, malformed XML or numbers, and more
//! than [`MAX_JOINTS`] moving joints on the chain.
//!
//! Parsing uses the `urdf-rs` crate; loading allocates and belongs at start-up. The model it
//! gives is a [`SerialRobotModel`] like any other: every kinematics and dynamics call is
//! allocation-free.

mod tree;

use std::path::Path;

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use penelope_hal::{JointLimits, JointVector, MAX_JOINTS, Pose};

use super::dh::{JointKind, Rt};
use super::robot::{IkMethod, ModelError, ModelSpec, SerialRobotModel};
use tree::{ChainWalk, Tree};

/// Encoder counts per joint radian a URDF robot is given (URDF has no encoders): a 19-bit
/// absolute encoder on the joint, `2^19 / 2π`.
pub const URDF_COUNTS_PER_RADIAN: f64 = 524_288.0 / core::f64::consts::TAU;

/// Encoder counts per metre of a URDF robot's prismatic joint: 1 µm per count.
pub const URDF_COUNTS_PER_METRE: f64 = 1e6;

/// Which part of a URDF's tree becomes the chain.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct UrdfChain {
    /// The link whose frame is the robot's world frame; `None`: the root link.
    pub base: Option<String>,
    /// The link whose frame is the tool frame; `None`: the single leaf link below the base.
    pub tip: Option<String>,
}

impl UrdfChain {
    /// From the root to the single leaf.
    pub fn whole() -> Self {
        UrdfChain::default()
    }

    /// From the root to the link `tip`.
    pub fn to_tip(tip: impl Into<String>) -> Self {
        UrdfChain {
            base: None,
            tip: Some(tip.into()),
        }
    }
}

/// Why a URDF does not make a model. Each variant names the element at fault.
#[derive(Debug, thiserror::Error)]
pub enum UrdfError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The path given.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// Not well-formed XML, or not a URDF `<robot>` (the parser's message).
    #[error("malformed URDF: {0}")]
    Malformed(String),
    /// A `floating`, `planar` or `spherical` joint.
    #[error(
        "joint `{joint}`: type \"{kind}\" is not supported (a serial chain takes revolute, \
         continuous, prismatic and fixed joints)"
    )]
    UnsupportedJoint {
        /// The joint's name.
        joint: String,
        /// Its type.
        kind: &'static str,
    },
    /// A `<mimic>` joint.
    #[error(
        "joint `{joint}`: <mimic joint=\"{mimics}\"> is not supported (every moving joint must \
         be independent)"
    )]
    Mimic {
        /// The joint's name.
        joint: String,
        /// The joint it mimics.
        mimics: String,
    },
    /// A link that is the child of two joints: a closed chain.
    #[error(
        "link `{link}` is the child of joints `{first}` and `{second}`: closed kinematic chains \
         are not supported"
    )]
    TwoParents {
        /// The link.
        link: String,
        /// One parent joint.
        first: String,
        /// The other.
        second: String,
    },
    /// Joints that form a loop (links with a parent but no way back to the root).
    #[error("the joints above links {} form a loop: closed kinematic chains are not supported", .0.join(", "))]
    Loop(Vec<String>),
    /// A joint names a link the file does not define.
    #[error("joint `{joint}`: its {role} link `{link}` is not defined")]
    MissingLink {
        /// The joint's name.
        joint: String,
        /// `"parent"` or `"child"`.
        role: &'static str,
        /// The missing link's name.
        link: String,
    },
    /// Two links or two joints with one name.
    #[error("{what} `{name}` is defined twice")]
    Duplicate {
        /// `"link"` or `"joint"`.
        what: &'static str,
        /// The name.
        name: String,
    },
    /// No link without a parent.
    #[error("the URDF has no root link")]
    NoRoot,
    /// Several links without a parent: the tree is not connected.
    #[error("the URDF has several root links ({}): its tree is not connected", .0.join(", "))]
    SeveralRoots(Vec<String>),
    /// A base or tip link that the file does not define.
    #[error("{role} link `{link}` is not in the URDF")]
    UnknownLink {
        /// `"base"` or `"tip"`.
        role: &'static str,
        /// The name asked for.
        link: String,
    },
    /// The tip link is not below the base link.
    #[error("tip link `{tip}` is not below base link `{base}`")]
    NotBelow {
        /// The base link.
        base: String,
        /// The tip link.
        tip: String,
    },
    /// No tip given and several leaf links below the base.
    #[error("several leaf links ({}): choose the tip link, for example `{}`", .0.join(", "), .0.last().map_or("", String::as_str))]
    AmbiguousTip(Vec<String>),
    /// More moving joints on the chain than a model holds.
    #[error(
        "the chain from `{base}` to `{tip}` has {} moving joints ({}); at most {max} are supported",
        .joints.len(), .joints.join(", "), max = MAX_JOINTS
    )]
    TooManyJoints {
        /// The base link.
        base: String,
        /// The tip link.
        tip: String,
        /// The moving joints on the chain.
        joints: Vec<String>,
    },
    /// The chain has no moving joint.
    #[error("the chain from `{base}` to `{tip}` has no moving joint")]
    NoMovingJoint {
        /// The base link.
        base: String,
        /// The tip link.
        tip: String,
    },
    /// A joint's numbers are unusable (non-finite, zero axis, inverted limits).
    #[error("joint `{joint}`: {message}")]
    BadJoint {
        /// The joint's name.
        joint: String,
        /// What is wrong.
        message: String,
    },
    /// A link's inertial is unusable (non-finite, negative mass, inertia not positive
    /// semi-definite).
    #[error("link `{link}`: {message}")]
    BadLink {
        /// The link's name.
        link: String,
        /// What is wrong.
        message: String,
    },
    /// The chain does not make a valid model.
    #[error(transparent)]
    Model(#[from] ModelError),
}

fn bad_joint(joint: &urdf_rs::Joint, message: impl Into<String>) -> UrdfError {
    UrdfError::BadJoint {
        joint: joint.name.clone(),
        message: message.into(),
    }
}

/// Parses URDF text into the parser's tree (no checks beyond well-formedness).
///
/// # Errors
/// [`UrdfError::Malformed`].
pub fn parse(text: &str) -> Result<urdf_rs::Robot, UrdfError> {
    urdf_rs::read_from_string(text).map_err(|e| UrdfError::Malformed(e.to_string()))
}

/// A model from URDF text, the chain chosen by `chain`; its kind is `"urdf"`.
///
/// # Errors
/// [`UrdfError`] naming the element at fault.
pub fn model_from_str(text: &str, chain: &UrdfChain) -> Result<SerialRobotModel, UrdfError> {
    let spec = spec_from_str(text, chain)?;
    Ok(SerialRobotModel::new("urdf", spec)?)
}

/// A model from a URDF file; its kind is `"urdf"`.
///
/// # Errors
/// [`UrdfError::Io`] when the file cannot be read, else as [`model_from_str`].
pub fn model_from_file(
    path: impl AsRef<Path>,
    chain: &UrdfChain,
) -> Result<SerialRobotModel, UrdfError> {
    Ok(SerialRobotModel::new("urdf", spec_from_file(path, chain)?)?)
}

/// The model definition of a URDF file's chain, to adjust (named poses, encoders, gravity)
/// before [`SerialRobotModel::new`].
///
/// # Errors
/// [`UrdfError::Io`] when the file cannot be read, else as [`spec_from_robot`].
pub fn spec_from_file(path: impl AsRef<Path>, chain: &UrdfChain) -> Result<ModelSpec, UrdfError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|source| UrdfError::Io {
        path: path.display().to_string(),
        source,
    })?;
    spec_from_str(&text, chain)
}

/// The model definition of URDF text's chain, keeping the text as the robot's own description
/// ([`SerialRobotModel::urdf`]).
///
/// # Errors
/// As [`spec_from_robot`].
pub fn spec_from_str(text: &str, chain: &UrdfChain) -> Result<ModelSpec, UrdfError> {
    let mut spec = spec_from_robot(&parse(text)?, chain)?;
    if let Some(links) = &mut spec.links {
        links.set_urdf(text.to_string());
    }
    Ok(spec)
}

pub(super) fn pose_of(origin: &urdf_rs::Pose) -> Pose {
    let [x, y, z] = origin.xyz.0;
    let [r, p, yaw] = origin.rpy.0;
    Pose::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r, p, yaw),
    )
}

pub(super) fn rt_of(origin: &urdf_rs::Pose) -> Rt {
    let [x, y, z] = origin.xyz.0;
    let [r, p, yaw] = origin.rpy.0;
    Rt {
        r: *nalgebra::Rotation3::from_euler_angles(r, p, yaw).matrix(),
        p: Vector3::new(x, y, z),
    }
}

pub(super) fn finite(origin: &urdf_rs::Pose) -> bool {
    origin
        .xyz
        .0
        .iter()
        .chain(&origin.rpy.0)
        .all(|v| v.is_finite())
}

fn check_joint(j: &urdf_rs::Joint) -> Result<(), UrdfError> {
    if !finite(&j.origin) {
        return Err(bad_joint(j, "<origin> must be finite"));
    }
    if j.joint_type == urdf_rs::JointType::Fixed {
        return Ok(());
    }
    let a = j.axis.xyz.0;
    if !a.iter().all(|v| v.is_finite()) || Vector3::from(a).norm() < 1e-9 {
        return Err(bad_joint(j, "<axis xyz> must be finite and non-zero"));
    }
    let l = &j.limit;
    if l.lower.is_nan() || l.upper.is_nan() || l.velocity.is_nan() || l.effort.is_nan() {
        return Err(bad_joint(j, "<limit> values must be numbers"));
    }
    if l.velocity < 0.0 || l.effort < 0.0 {
        return Err(bad_joint(j, "<limit> velocity and effort must be >= 0"));
    }
    if j.joint_type != urdf_rs::JointType::Continuous {
        if l.lower > l.upper {
            return Err(bad_joint(
                j,
                format!("<limit> lower {} is above upper {}", l.lower, l.upper),
            ));
        }
        if l.lower == l.upper {
            return Err(bad_joint(
                j,
                "<limit> lower equals upper (a revolute or prismatic joint needs a <limit> with \
                 lower < upper; use type=\"continuous\" for an unlimited revolute joint)",
            ));
        }
    }
    if let Some(d) = &j.dynamics
        && !(d.damping.is_finite()
            && d.friction.is_finite()
            && d.damping >= 0.0
            && d.friction >= 0.0)
    {
        return Err(bad_joint(
            j,
            "<dynamics> damping and friction must be finite and >= 0",
        ));
    }
    Ok(())
}

/// The model definition of the chain `chain` of a parsed URDF.
///
/// # Errors
/// [`UrdfError`] naming the element at fault.
pub fn spec_from_robot(robot: &urdf_rs::Robot, chain: &UrdfChain) -> Result<ModelSpec, UrdfError> {
    let tree = Tree::new(robot)?;
    let (base, tip) = tree.chain_ends(chain)?;
    let path = tree.path(base, tip)?;
    for j in &path {
        check_joint(j)?;
    }
    let moving = moving_joints(&path, base, tip)?;
    // The description a viewer draws: the parser's re-serialisation of the robot (the callers
    // that have the file's text put it back), or, should that fail, one generated from the tree.
    let links = tree.link_tree(base, tip, &path, urdf_rs::write_to_string(robot).ok());
    let ChainWalk {
        joints,
        dynamics,
        limits,
        left_out,
        tool,
    } = tree.walk(&path)?;
    let home = home_joints(&limits, joints.len());
    let mut assumptions = vec![
        "URDF has no rotor inertia, gear ratio or encoders: no rotor inertia, gear ratio 1, \
         a 19-bit encoder on each revolute joint and 1 µm counts on each prismatic one"
            .to_string(),
        "named poses nest, start and work are all the zero configuration (a joint whose limits \
         do not hold zero strictly inside: the middle of its range)"
            .to_string(),
    ];
    if !left_out.is_empty() {
        assumptions.push(format!(
            "the links behind joints {} hang off the chain and are left out of the dynamics",
            left_out.join(", ")
        ));
    }
    let counts_per_radian = joints
        .iter()
        .map(|j| match j.kind() {
            JointKind::Revolute => URDF_COUNTS_PER_RADIAN,
            JointKind::Prismatic => URDF_COUNTS_PER_METRE,
        })
        .collect();
    Ok(ModelSpec {
        name: robot.name.clone(),
        description: format!("URDF robot `{}`, chain `{base}` to `{tip}`", robot.name),
        assumptions,
        joint_names: moving.iter().map(|j| j.name.clone()).collect(),
        joints,
        dynamics,
        base: Pose::identity(),
        tool: tool.to_pose(),
        gravity: Vector3::new(0.0, 0.0, -9.81),
        limits,
        counts_per_radian,
        poses: ["nest", "start", "work"]
            .iter()
            .map(|p| (p.to_string(), home))
            .collect(),
        ik: IkMethod::Auto,
        links: Some(links),
    })
}

/// The moving joints of `path`: at least one, at most [`MAX_JOINTS`].
fn moving_joints<'a>(
    path: &[&'a urdf_rs::Joint],
    base: &str,
    tip: &str,
) -> Result<Vec<&'a urdf_rs::Joint>, UrdfError> {
    let moving: Vec<&urdf_rs::Joint> = path
        .iter()
        .copied()
        .filter(|j| j.joint_type != urdf_rs::JointType::Fixed)
        .collect();
    if moving.is_empty() {
        return Err(UrdfError::NoMovingJoint {
            base: base.to_string(),
            tip: tip.to_string(),
        });
    }
    if moving.len() > MAX_JOINTS {
        return Err(UrdfError::TooManyJoints {
            base: base.to_string(),
            tip: tip.to_string(),
            joints: moving.iter().map(|j| j.name.clone()).collect(),
        });
    }
    Ok(moving)
}

/// The home joints: zero where strictly inside the limits (a pose on a limit would trip the
/// limit supervision at once), else the middle of the range.
fn home_joints(limits: &JointLimits, n: usize) -> JointVector {
    let mut home = JointVector::zeros();
    for j in 0..n {
        let (lo, hi) = (limits.position_min[j], limits.position_max[j]);
        home[j] = if lo < 0.0 && 0.0 < hi {
            0.0
        } else if lo.is_finite() && hi.is_finite() {
            0.5 * (lo + hi)
        } else {
            0.0f64.clamp(lo, hi)
        };
    }
    home
}
