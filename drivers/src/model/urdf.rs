//! Robots from URDF: a serial chain of a URDF's joints between a base link and a tip link, with
//! the links' inertials for the dynamics.
//!
//! # What becomes what
//!
//! - Every `revolute`, `continuous` and `prismatic` joint on the path from the base link to the
//!   tip link becomes one [`AxisJoint`]: its `<origin xyz rpy>`, then motion about (along) its
//!   `<axis>` (normalised; default `1 0 0` as in URDF).
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
//! gives is a [`DhRobotModel`] like any other: every kinematics and dynamics call is
//! allocation-free.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use nalgebra::{Matrix3, Translation3, UnitQuaternion, Vector3};
use penelope_hal::{JointLimits, JointVector, MAX_JOINTS, Pose};

use super::axis_joint::AxisJoint;
use super::chain::ChainJoint;
use super::dh::{JointKind, Rt};
use super::dynamics::LinkDynamics;
use super::robot::{DhRobotModel, IkMethod, ModelError, ModelSpec};

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
pub fn model_from_str(text: &str, chain: &UrdfChain) -> Result<DhRobotModel, UrdfError> {
    let spec = spec_from_robot(&parse(text)?, chain)?;
    Ok(DhRobotModel::new("urdf", spec)?)
}

/// A model from a URDF file; its kind is `"urdf"`.
///
/// # Errors
/// [`UrdfError::Io`] when the file cannot be read, else as [`model_from_str`].
pub fn model_from_file(
    path: impl AsRef<Path>,
    chain: &UrdfChain,
) -> Result<DhRobotModel, UrdfError> {
    Ok(DhRobotModel::new("urdf", spec_from_file(path, chain)?)?)
}

/// The model definition of a URDF file's chain, to adjust (named poses, encoders, gravity)
/// before [`DhRobotModel::new`].
///
/// # Errors
/// [`UrdfError::Io`] when the file cannot be read, else as [`spec_from_robot`].
pub fn spec_from_file(path: impl AsRef<Path>, chain: &UrdfChain) -> Result<ModelSpec, UrdfError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|source| UrdfError::Io {
        path: path.display().to_string(),
        source,
    })?;
    spec_from_robot(&parse(&text)?, chain)
}

fn pose_of(origin: &urdf_rs::Pose) -> Pose {
    let [x, y, z] = origin.xyz.0;
    let [r, p, yaw] = origin.rpy.0;
    Pose::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r, p, yaw),
    )
}

fn rt_of(origin: &urdf_rs::Pose) -> Rt {
    let [x, y, z] = origin.xyz.0;
    let [r, p, yaw] = origin.rpy.0;
    Rt {
        r: *nalgebra::Rotation3::from_euler_angles(r, p, yaw).matrix(),
        p: Vector3::new(x, y, z),
    }
}

fn finite(origin: &urdf_rs::Pose) -> bool {
    origin
        .xyz
        .0
        .iter()
        .chain(&origin.rpy.0)
        .all(|v| v.is_finite())
}

/// A link body's mass properties accumulated about its frame's origin.
#[derive(Clone, Copy, Debug)]
struct Body {
    mass: f64,
    /// First moment `Σ m c`.
    moment: Vector3<f64>,
    /// Rotational inertia about the frame's origin.
    inertia_origin: Matrix3<f64>,
}

impl Body {
    fn empty() -> Self {
        Body {
            mass: 0.0,
            moment: Vector3::zeros(),
            inertia_origin: Matrix3::zeros(),
        }
    }

    /// Adds `link`'s inertial, the link's frame at `at` in the body's frame.
    fn add(&mut self, link: &urdf_rs::Link, at: &Rt) -> Result<(), UrdfError> {
        let i = &link.inertial;
        let bad = |message: &str| UrdfError::BadLink {
            link: link.name.clone(),
            message: message.into(),
        };
        let t = &i.inertia;
        let tensor = Matrix3::new(
            t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz,
        );
        let m = i.mass.value;
        if !m.is_finite() || m < 0.0 || !finite(&i.origin) || !tensor.iter().all(|v| v.is_finite())
        {
            return Err(bad("<inertial> must be finite with a non-negative mass"));
        }
        let scale = tensor.abs().max().max(1.0);
        if tensor
            .symmetric_eigenvalues()
            .iter()
            .any(|&e| e < -1e-12 * scale)
        {
            return Err(bad("<inertia> is not positive semi-definite"));
        }
        let frame = at.mul(&rt_of(&i.origin));
        let c = frame.p;
        self.mass += m;
        self.moment += c * m;
        self.inertia_origin += frame.r * tensor * frame.r.transpose()
            + (Matrix3::identity() * c.dot(&c) - c * c.transpose()) * m;
        Ok(())
    }

    /// Mass, centre of mass and inertia about it, in the body's frame.
    fn dynamics(&self, joint: &urdf_rs::Joint) -> LinkDynamics {
        let com = if self.mass > 0.0 {
            self.moment / self.mass
        } else {
            Vector3::zeros()
        };
        let about_com = self.inertia_origin
            - (Matrix3::identity() * com.dot(&com) - com * com.transpose()) * self.mass;
        let (damping, friction) = joint
            .dynamics
            .as_ref()
            .map_or((0.0, 0.0), |d| (d.damping, d.friction));
        LinkDynamics {
            mass: self.mass,
            com,
            // Symmetrise: the parallel-axis sums leave rounding-level asymmetry.
            inertia: (about_com + about_com.transpose()) * 0.5,
            motor_inertia: 0.0,
            gear_ratio: 1.0,
            viscous: damping,
            coulomb: [friction, -friction],
        }
    }
}

/// The tree of a URDF: links and joints by name, and who hangs below whom.
struct Tree<'a> {
    links: BTreeMap<&'a str, &'a urdf_rs::Link>,
    parent: BTreeMap<&'a str, &'a urdf_rs::Joint>,
    children: BTreeMap<&'a str, Vec<&'a urdf_rs::Joint>>,
    root: &'a str,
}

impl<'a> Tree<'a> {
    fn new(robot: &'a urdf_rs::Robot) -> Result<Self, UrdfError> {
        let mut links = BTreeMap::new();
        for l in &robot.links {
            if links.insert(l.name.as_str(), l).is_some() {
                return Err(UrdfError::Duplicate {
                    what: "link",
                    name: l.name.clone(),
                });
            }
        }
        let mut names = BTreeSet::new();
        let mut parent: BTreeMap<&str, &urdf_rs::Joint> = BTreeMap::new();
        let mut children: BTreeMap<&str, Vec<&urdf_rs::Joint>> = BTreeMap::new();
        for j in &robot.joints {
            if !names.insert(j.name.as_str()) {
                return Err(UrdfError::Duplicate {
                    what: "joint",
                    name: j.name.clone(),
                });
            }
            let unsupported = match j.joint_type {
                urdf_rs::JointType::Floating => Some("floating"),
                urdf_rs::JointType::Planar => Some("planar"),
                urdf_rs::JointType::Spherical => Some("spherical"),
                _ => None,
            };
            if let Some(kind) = unsupported {
                return Err(UrdfError::UnsupportedJoint {
                    joint: j.name.clone(),
                    kind,
                });
            }
            if let Some(m) = &j.mimic {
                return Err(UrdfError::Mimic {
                    joint: j.name.clone(),
                    mimics: m.joint.clone(),
                });
            }
            for (role, link) in [("parent", &j.parent.link), ("child", &j.child.link)] {
                if !links.contains_key(link.as_str()) {
                    return Err(UrdfError::MissingLink {
                        joint: j.name.clone(),
                        role,
                        link: link.clone(),
                    });
                }
            }
            if let Some(first) = parent.insert(j.child.link.as_str(), j) {
                return Err(UrdfError::TwoParents {
                    link: j.child.link.clone(),
                    first: first.name.clone(),
                    second: j.name.clone(),
                });
            }
            children.entry(j.parent.link.as_str()).or_default().push(j);
        }
        let roots: Vec<&str> = links
            .keys()
            .copied()
            .filter(|l| !parent.contains_key(l))
            .collect();
        let root = match roots.as_slice() {
            [] if links.is_empty() => return Err(UrdfError::NoRoot),
            [] => {
                return Err(UrdfError::Loop(
                    links.keys().map(|l| l.to_string()).collect(),
                ));
            }
            [root] => *root,
            _ => {
                return Err(UrdfError::SeveralRoots(
                    roots.iter().map(|l| l.to_string()).collect(),
                ));
            }
        };
        let tree = Tree {
            links,
            parent,
            children,
            root,
        };
        // With one parent per link, links the root does not reach form a loop.
        let reached = tree.below(root);
        if reached.len() < tree.links.len() {
            return Err(UrdfError::Loop(
                tree.links
                    .keys()
                    .filter(|l| !reached.contains(*l))
                    .map(|l| l.to_string())
                    .collect(),
            ));
        }
        Ok(tree)
    }

    /// Every link at or below `link`.
    fn below(&self, link: &'a str) -> BTreeSet<&'a str> {
        let mut seen = BTreeSet::new();
        let mut stack = vec![link];
        while let Some(l) = stack.pop() {
            if seen.insert(l) {
                for j in self.children.get(l).into_iter().flatten() {
                    stack.push(j.child.link.as_str());
                }
            }
        }
        seen
    }

    fn link(&self, role: &'static str, name: &str) -> Result<&'a str, UrdfError> {
        self.links
            .get_key_value(name)
            .map(|(k, _)| *k)
            .ok_or_else(|| UrdfError::UnknownLink {
                role,
                link: name.to_string(),
            })
    }

    /// The joints from `base` down to `tip`, in order.
    fn path(&self, base: &'a str, tip: &'a str) -> Result<Vec<&'a urdf_rs::Joint>, UrdfError> {
        let mut path = Vec::new();
        let mut at = tip;
        while at != base {
            let Some(j) = self.parent.get(at) else {
                return Err(UrdfError::NotBelow {
                    base: base.to_string(),
                    tip: tip.to_string(),
                });
            };
            path.push(*j);
            at = j.parent.link.as_str();
        }
        path.reverse();
        Ok(path)
    }

    /// Adds to `body` every link fixed below `link` (whose frame is at `at` in the body's frame)
    /// through joints other than `skip`; names the moving joints met (left out) in `left_out`.
    fn merge_fixed(
        &self,
        link: &str,
        at: &Rt,
        skip: Option<&str>,
        body: &mut Body,
        left_out: &mut Vec<String>,
    ) -> Result<(), UrdfError> {
        for j in self.children.get(link).into_iter().flatten() {
            if Some(j.name.as_str()) == skip {
                continue;
            }
            if j.joint_type != urdf_rs::JointType::Fixed {
                left_out.push(j.name.clone());
                continue;
            }
            let child_at = at.mul(&rt_of(&j.origin));
            body.add(self.links[j.child.link.as_str()], &child_at)?;
            self.merge_fixed(&j.child.link, &child_at, None, body, left_out)?;
        }
        Ok(())
    }
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
    let base = match &chain.base {
        Some(b) => tree.link("base", b)?,
        None => tree.root,
    };
    let tip = match &chain.tip {
        Some(t) => tree.link("tip", t)?,
        None => {
            let leaves: Vec<&str> = tree
                .below(base)
                .into_iter()
                .filter(|l| !tree.children.contains_key(l))
                .collect();
            match leaves.as_slice() {
                [leaf] => *leaf,
                _ => {
                    return Err(UrdfError::AmbiguousTip(
                        leaves.iter().map(|l| l.to_string()).collect(),
                    ));
                }
            }
        }
    };
    let path = tree.path(base, tip)?;
    for j in &path {
        check_joint(j)?;
    }
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

    let mut joints = Vec::with_capacity(moving.len());
    let mut dynamics = Vec::with_capacity(moving.len());
    let mut limits = JointLimits::unbounded();
    let mut left_out = Vec::new();
    // The frame of the link reached, in the frame of the current body (or of the base).
    let mut pending = Rt {
        r: Matrix3::identity(),
        p: Vector3::zeros(),
    };
    let mut body: Option<(Body, &urdf_rs::Joint)> = None;
    for (k, j) in path.iter().enumerate() {
        let origin = rt_of(&j.origin);
        if j.joint_type == urdf_rs::JointType::Fixed {
            pending = pending.mul(&origin);
        } else {
            if let Some((b, bj)) = body.take() {
                dynamics.push(b.dynamics(bj));
            }
            let n = joints.len();
            let at = if pending.is_identity() {
                pose_of(&j.origin)
            } else {
                pending.mul(&origin).to_pose()
            };
            let axis = Vector3::from(j.axis.xyz.0);
            joints.push(ChainJoint::Axis(match j.joint_type {
                urdf_rs::JointType::Prismatic => AxisJoint::prismatic(at, axis),
                _ => AxisJoint::revolute(at, axis),
            }));
            let l = &j.limit;
            if j.joint_type != urdf_rs::JointType::Continuous {
                limits.position_min[n] = l.lower;
                limits.position_max[n] = l.upper;
            }
            let given = |v: f64| if v > 0.0 { v } else { f64::INFINITY };
            limits.velocity_max[n] = given(l.velocity);
            limits.effort_max[n] = given(l.effort);
            pending = Rt {
                r: Matrix3::identity(),
                p: Vector3::zeros(),
            };
            body = Some((Body::empty(), j));
        }
        // The link just reached, and whatever is fixed to it off the path, joins the body.
        if let Some((b, _)) = &mut body {
            let link = j.child.link.as_str();
            b.add(tree.links[link], &pending)?;
            let next = path.get(k + 1).map(|n| n.name.as_str());
            tree.merge_fixed(link, &pending, next, b, &mut left_out)?;
        }
    }
    if let Some((b, bj)) = body.take() {
        dynamics.push(b.dynamics(bj));
    }

    let n = joints.len();
    let mut home = JointVector::zeros();
    for j in 0..n {
        let (lo, hi) = (limits.position_min[j], limits.position_max[j]);
        // Zero when strictly inside the limits (a pose on a limit would trip the limit
        // supervision at once), else the middle of the range.
        home[j] = if lo < 0.0 && 0.0 < hi {
            0.0
        } else if lo.is_finite() && hi.is_finite() {
            0.5 * (lo + hi)
        } else {
            0.0f64.clamp(lo, hi)
        };
    }
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
        tool: pending.to_pose(),
        gravity: Vector3::new(0.0, 0.0, -9.81),
        limits,
        counts_per_radian,
        poses: ["nest", "start", "work"]
            .iter()
            .map(|p| (p.to_string(), home))
            .collect(),
        ik: IkMethod::Auto,
    })
}
