//! The tree of a URDF and the walk down one chain of it: which link hangs below which, the
//! path from a base to a tip, and each moving joint's body with the links fixed to it lumped in.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::{Matrix3, Vector3};
use penelope_hal::JointLimits;

use super::{UrdfChain, UrdfError, finite, pose_of, rt_of};
use crate::model::axis_joint::AxisJoint;
use crate::model::chain::ChainJoint;
use crate::model::dh::JointKind;
use crate::model::dh::Rt;
use crate::model::dynamics::LinkDynamics;
use crate::model::links::{LinkNode, LinkTree, Motion};

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
pub(super) struct Tree<'a> {
    links: BTreeMap<&'a str, &'a urdf_rs::Link>,
    parent: BTreeMap<&'a str, &'a urdf_rs::Joint>,
    children: BTreeMap<&'a str, Vec<&'a urdf_rs::Joint>>,
    root: &'a str,
}

impl<'a> Tree<'a> {
    pub(super) fn new(robot: &'a urdf_rs::Robot) -> Result<Self, UrdfError> {
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
    pub(super) fn below(&self, link: &'a str) -> BTreeSet<&'a str> {
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

    pub(super) fn link(&self, role: &'static str, name: &str) -> Result<&'a str, UrdfError> {
        self.links
            .get_key_value(name)
            .map(|(k, _)| *k)
            .ok_or_else(|| UrdfError::UnknownLink {
                role,
                link: name.to_string(),
            })
    }

    /// The joints from `base` down to `tip`, in order.
    pub(super) fn path(
        &self,
        base: &'a str,
        tip: &'a str,
    ) -> Result<Vec<&'a urdf_rs::Joint>, UrdfError> {
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

/// What walking a chain's path from base to tip gives.
pub(super) struct ChainWalk {
    /// The moving joints, each placed in the frame of the body before it.
    pub(super) joints: Vec<ChainJoint>,
    /// Each moving joint's body: its links and whatever is fixed to them.
    pub(super) dynamics: Vec<LinkDynamics>,
    /// The joints' limits.
    pub(super) limits: JointLimits,
    /// Joints off the chain whose links are left out of the dynamics.
    pub(super) left_out: Vec<String>,
    /// The tip in the frame of the last body: the tool.
    pub(super) tool: Rt,
}

impl<'a> Tree<'a> {
    /// The chain's base (the root unless named) and tip (the only leaf below the base unless
    /// named).
    pub(super) fn chain_ends(&self, chain: &UrdfChain) -> Result<(&'a str, &'a str), UrdfError> {
        let base = match &chain.base {
            Some(b) => self.link("base", b)?,
            None => self.root,
        };
        let tip = match &chain.tip {
            Some(t) => self.link("tip", t)?,
            None => {
                let leaves: Vec<&str> = self
                    .below(base)
                    .into_iter()
                    .filter(|l| !self.children.contains_key(l))
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
        Ok((base, tip))
    }

    /// Walks `path` from base to tip: each moving joint placed after the fixed ones before it,
    /// with its limits, and the links up to the next moving joint (and what is fixed to them)
    /// lumped into its body.
    pub(super) fn walk(&self, path: &[&'a urdf_rs::Joint]) -> Result<ChainWalk, UrdfError> {
        let mut joints = Vec::with_capacity(path.len());
        let mut dynamics = Vec::with_capacity(path.len());
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
                set_limits(&mut limits, n, j);
                pending = Rt {
                    r: Matrix3::identity(),
                    p: Vector3::zeros(),
                };
                body = Some((Body::empty(), j));
            }
            // The link just reached, and whatever is fixed to it off the path, joins the body.
            if let Some((b, _)) = &mut body {
                let link = j.child.link.as_str();
                b.add(self.links[link], &pending)?;
                let next = path.get(k + 1).map(|n| n.name.as_str());
                self.merge_fixed(link, &pending, next, b, &mut left_out)?;
            }
        }
        if let Some((b, bj)) = body.take() {
            dynamics.push(b.dynamics(bj));
        }
        Ok(ChainWalk {
            joints,
            dynamics,
            limits,
            left_out,
            tool: pending,
        })
    }
}

impl<'a> Tree<'a> {
    /// Every link at or below `base` as a [`LinkTree`] (breadth first, `tip` reported last): the
    /// moving joints of `path` move their links; any other joint is placed at its origin.
    pub(super) fn link_tree(
        &self,
        base: &'a str,
        tip: &'a str,
        path: &[&'a urdf_rs::Joint],
        text: Option<String>,
    ) -> LinkTree {
        let moving: BTreeMap<&str, usize> = path
            .iter()
            .filter(|j| j.joint_type != urdf_rs::JointType::Fixed)
            .enumerate()
            .map(|(k, j)| (j.name.as_str(), k))
            .collect();
        let mut nodes = vec![LinkNode {
            name: base.to_string(),
            parent: None,
            origin: Rt {
                r: Matrix3::identity(),
                p: Vector3::zeros(),
            },
            motion: Motion::Fixed,
        }];
        let mut tip_index = 0;
        let mut next = 0;
        while next < nodes.len() {
            let name = nodes[next].name.clone();
            for j in self.children.get(name.as_str()).into_iter().flatten() {
                let motion = match moving.get(j.name.as_str()) {
                    Some(&index) => Motion::Joint {
                        index,
                        kind: match j.joint_type {
                            urdf_rs::JointType::Prismatic => JointKind::Prismatic,
                            _ => JointKind::Revolute,
                        },
                        axis: Vector3::from(j.axis.xyz.0).normalize(),
                    },
                    None => Motion::Fixed,
                };
                if j.child.link == tip {
                    tip_index = nodes.len();
                }
                nodes.push(LinkNode {
                    name: j.child.link.clone(),
                    parent: Some(next),
                    origin: rt_of(&j.origin),
                    motion,
                });
            }
            next += 1;
        }
        LinkTree::from_urdf(nodes, tip_index, text)
    }
}

/// Joint `n`'s limits from its URDF joint `j` (a continuous joint has no position limits; a
/// velocity or effort limit of zero is none).
fn set_limits(limits: &mut JointLimits, n: usize, j: &urdf_rs::Joint) {
    let l = &j.limit;
    if j.joint_type != urdf_rs::JointType::Continuous {
        limits.position_min[n] = l.lower;
        limits.position_max[n] = l.upper;
    }
    let given = |v: f64| if v > 0.0 { v } else { f64::INFINITY };
    limits.velocity_max[n] = given(l.velocity);
    limits.effort_max[n] = given(l.effort);
}
