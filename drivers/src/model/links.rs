//! Every link frame of a robot, and its description as a URDF: what a 3D viewer needs to draw
//! the arm ([`SerialRobotModel::link_names`], [`SerialRobotModel::link_frames`],
//! [`SerialRobotModel::urdf`]).
//!
//! # The frames of a DH robot
//!
//! `base_link` (the robot's world frame, where the base transform starts), `link1`..`linkN`,
//! `tool`. Joint `j`'s motion must be a rotation about (translation along) an axis through the
//! origin of the frame it moves, as in URDF, so `linkj` is DH frame `j-1` moved by joint `j`
//! (`Tz(d_j) Rz(theta_j)` of the row) — not DH frame `j`, whose origin is off that axis when
//! `a_j ≠ 0`. Its z axis is joint `j`'s axis; the row's `Tx(a_j) Rx(alpha_j)` is the fixed part
//! of the next joint's origin (the tool transform's, after the last row). `tool` is the tool
//! frame, so the last frame is [`Kinematics::forward`](penelope_hal::Kinematics::forward).
//!
//! # The frames of a URDF robot
//!
//! The URDF's own links below the chain's base link, root first, the tip link last. A link
//! behind a moving joint that is not on the chain is placed as if that joint were at zero.
//!
//! # Real-time
//! Not for a control loop: [`SerialRobotModel::link_frames`] allocates its answer. It is for
//! recordings, viewers and clients.
//!
//! [`SerialRobotModel::link_names`]: super::SerialRobotModel::link_names
//! [`SerialRobotModel::link_frames`]: super::SerialRobotModel::link_frames
//! [`SerialRobotModel::urdf`]: super::SerialRobotModel::urdf

use std::fmt::Write;

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use penelope_hal::{JointLimits, JointVector, Pose};

use super::chain::{ChainJoint, SerialChain};
use super::dh::{JointKind, Rt};

/// How a link moves relative to its parent after its fixed origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Motion {
    /// Not at all.
    Fixed,
    /// By chain joint `index` (0-based): rotation about, or translation along, the unit `axis`
    /// of the joint frame.
    Joint {
        index: usize,
        kind: JointKind,
        axis: Vector3<f64>,
    },
}

/// One link of a [`LinkTree`].
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct LinkNode {
    pub name: String,
    /// The parent link's index (always lower than this link's); `None` for the root.
    pub parent: Option<usize>,
    /// The joint frame in the parent link's frame.
    pub origin: Rt,
    pub motion: Motion,
}

/// The links of a robot as a tree in topological order (the root first, every parent before
/// its children), with the order they are reported in (the tip last) and the robot's own URDF
/// text when it has one.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkTree {
    nodes: Vec<LinkNode>,
    /// Indexes into `nodes` in reporting order.
    order: Vec<usize>,
    /// The robot's own URDF (`None`: generate one from the nodes).
    urdf: Option<String>,
}

fn identity() -> Rt {
    Rt {
        r: Matrix3::identity(),
        p: Vector3::zeros(),
    }
}

fn translation(v: Vector3<f64>) -> Rt {
    Rt {
        r: Matrix3::identity(),
        p: v,
    }
}

fn rotation_z(angle: f64) -> Rt {
    Rt {
        r: *Rotation3::from_axis_angle(&Vector3::z_axis(), angle).matrix(),
        p: Vector3::zeros(),
    }
}

fn rotation_x(angle: f64) -> Rt {
    Rt {
        r: *Rotation3::from_axis_angle(&Vector3::x_axis(), angle).matrix(),
        p: Vector3::zeros(),
    }
}

impl LinkTree {
    /// The tree of a URDF robot: `nodes` in topological order, `tip` (an index) reported last.
    /// (`text`: the robot's own URDF; `None`: generate one from the nodes).
    pub(crate) fn from_urdf(nodes: Vec<LinkNode>, tip: usize, text: Option<String>) -> Self {
        let mut order: Vec<usize> = (0..nodes.len()).filter(|&i| i != tip).collect();
        order.push(tip);
        LinkTree {
            nodes,
            order,
            urdf: text,
        }
    }

    /// Replaces the URDF text (the file's own, rather than the parser's re-serialisation).
    pub(crate) fn set_urdf(&mut self, text: String) {
        self.urdf = Some(text);
    }

    /// The tree of a chain: `base_link`, `link1`..`linkN`, `tool` (see the module doc).
    pub(crate) fn from_chain(chain: &SerialChain) -> Self {
        let n = chain.joint_count();
        let mut nodes = Vec::with_capacity(n + 2);
        nodes.push(LinkNode {
            name: "base_link".into(),
            parent: None,
            origin: identity(),
            motion: Motion::Fixed,
        });
        // The fixed transform left over from the previous joint, to go before the next one.
        let mut pending = Rt::from_pose(&chain.base());
        for j in 0..n {
            let Some(joint) = chain.joint(j) else { break };
            let (origin, axis, after) = match joint {
                ChainJoint::Dh(l) => {
                    let before = match l.kind {
                        JointKind::Revolute => {
                            translation(Vector3::new(0.0, 0.0, l.d)).mul(&rotation_z(l.offset))
                        }
                        JointKind::Prismatic => {
                            rotation_z(l.theta).mul(&translation(Vector3::new(0.0, 0.0, l.offset)))
                        }
                    };
                    let after = translation(Vector3::new(l.a, 0.0, 0.0)).mul(&rotation_x(l.alpha));
                    (pending.mul(&before), Vector3::z(), after)
                }
                ChainJoint::Axis(a) => (
                    pending.mul(&Rt::from_pose(&a.origin)),
                    a.axis.normalize(),
                    identity(),
                ),
            };
            nodes.push(LinkNode {
                name: format!("link{}", j + 1),
                parent: Some(j),
                origin,
                motion: Motion::Joint {
                    index: j,
                    kind: joint.kind(),
                    axis,
                },
            });
            pending = after;
        }
        nodes.push(LinkNode {
            name: "tool".into(),
            parent: Some(n),
            origin: pending.mul(&Rt::from_pose(&chain.tool())),
            motion: Motion::Fixed,
        });
        LinkTree {
            order: (0..nodes.len()).collect(),
            nodes,
            urdf: None,
        }
    }

    /// True when every moving link names a joint below `joints` (a tree made for this chain).
    pub(crate) fn fits(&self, joints: usize) -> bool {
        self.nodes.iter().all(|n| match n.motion {
            Motion::Fixed => true,
            Motion::Joint { index, .. } => index < joints,
        })
    }

    /// The link names in reporting order.
    pub(crate) fn names(&self) -> Vec<String> {
        self.order
            .iter()
            .map(|&i| self.nodes[i].name.clone())
            .collect()
    }

    /// Each link's pose in the root frame at `q`, in reporting order.
    pub(crate) fn frames(&self, q: &JointVector) -> Vec<Pose> {
        let mut at: Vec<Rt> = Vec::with_capacity(self.nodes.len());
        for node in &self.nodes {
            let parent = node.parent.map_or_else(identity, |p| at[p]);
            let joint_frame = parent.mul(&node.origin);
            let frame = match node.motion {
                Motion::Fixed => joint_frame,
                Motion::Joint { index, kind, axis } => {
                    let v = q[index];
                    let moved = match kind {
                        JointKind::Revolute => Rt {
                            r: *Rotation3::from_axis_angle(&Unit::new_unchecked(axis), v).matrix(),
                            p: Vector3::zeros(),
                        },
                        JointKind::Prismatic => translation(axis * v),
                    };
                    joint_frame.mul(&moved)
                }
            };
            at.push(frame);
        }
        self.order.iter().map(|&i| at[i].to_pose()).collect()
    }

    /// The robot's own URDF text, or one generated from the tree (see [`generate_urdf`]).
    pub(crate) fn urdf(&self, robot: &str, joint_names: &[String], limits: &JointLimits) -> String {
        match &self.urdf {
            Some(text) => text.clone(),
            None => self.generate_urdf(robot, joint_names, limits),
        }
    }

    /// A URDF of the tree: one `<link>` per node with simple visual geometry (a cylinder along
    /// each moving joint's axis, a cylinder from each link's origin to each child's joint, a
    /// plate under the root, a small cube at a leaf), one `<joint>` per non-root node (the
    /// chain's joint names for moving ones, `<child>_joint` for fixed ones).
    fn generate_urdf(&self, robot: &str, joint_names: &[String], limits: &JointLimits) -> String {
        // The size of the arm sets the thickness of its drawn links.
        let reach: f64 = self.nodes.iter().map(|n| n.origin.p.norm()).sum();
        let radius = (0.03 * reach).clamp(0.004, 0.04);
        let mut out = String::new();
        let _ = writeln!(out, r#"<?xml version="1.0"?>"#);
        let _ = writeln!(out, r#"<robot name="{}">"#, xml_escape(robot));
        let _ = writeln!(
            out,
            r#"  <material name="penelope_link"><color rgba="0.72 0.74 0.78 1"/></material>"#
        );
        let _ = writeln!(
            out,
            r#"  <material name="penelope_joint"><color rgba="0.95 0.55 0.1 1"/></material>"#
        );
        for (i, node) in self.nodes.iter().enumerate() {
            let _ = writeln!(out, r#"  <link name="{}">"#, xml_escape(&node.name));
            if let Motion::Joint { axis, .. } = node.motion {
                visual_cylinder(
                    &mut out,
                    &(-axis * radius * 1.3),
                    &(axis * radius * 1.3),
                    radius * 1.25,
                    "penelope_joint",
                );
            }
            let mut children = 0;
            for child in self.nodes.iter().filter(|c| c.parent == Some(i)) {
                children += 1;
                let to = child.origin.p;
                if to.norm() > 1e-6 {
                    visual_cylinder(&mut out, &Vector3::zeros(), &to, radius, "penelope_link");
                }
            }
            if node.parent.is_none() {
                let s = radius * 6.0;
                let _ = writeln!(
                    out,
                    r#"    <visual><origin xyz="0 0 {}" rpy="0 0 0"/><geometry><box size="{s} {s} {}"/></geometry><material name="penelope_link"/></visual>"#,
                    -radius * 0.5,
                    radius
                );
            } else if children == 0 {
                let s = radius * 1.5;
                let _ = writeln!(
                    out,
                    r#"    <visual><origin xyz="0 0 0" rpy="0 0 0"/><geometry><box size="{s} {s} {s}"/></geometry><material name="penelope_joint"/></visual>"#
                );
            }
            let _ = writeln!(out, "  </link>");
        }
        for node in &self.nodes {
            let Some(parent) = node.parent else { continue };
            let (xyz, rpy) = xyz_rpy(&node.origin);
            let parent = xml_escape(&self.nodes[parent].name);
            let child = xml_escape(&node.name);
            match node.motion {
                Motion::Fixed => {
                    let _ = writeln!(
                        out,
                        r#"  <joint name="{child}_joint" type="fixed"><origin xyz="{xyz}" rpy="{rpy}"/><parent link="{parent}"/><child link="{child}"/></joint>"#
                    );
                }
                Motion::Joint { index, kind, axis } => {
                    let name = joint_names
                        .get(index)
                        .cloned()
                        .unwrap_or_else(|| format!("q{}", index + 1));
                    let (lo, hi) = (limits.position_min[index], limits.position_max[index]);
                    let limited = lo.is_finite() && hi.is_finite();
                    let kind = match (kind, limited) {
                        (JointKind::Revolute, false) => "continuous",
                        (JointKind::Revolute, true) => "revolute",
                        (JointKind::Prismatic, _) => "prismatic",
                    };
                    // URDF needs finite numbers: an unbounded prismatic range becomes ±1 km, an
                    // unbounded velocity or effort 0 (which our loader reads as "not given").
                    let (lo, hi) = if limited { (lo, hi) } else { (-1e3, 1e3) };
                    let given = |v: f64| if v.is_finite() { v } else { 0.0 };
                    let (velocity, effort) = (
                        given(limits.velocity_max[index]),
                        given(limits.effort_max[index]),
                    );
                    let _ = writeln!(
                        out,
                        r#"  <joint name="{}" type="{kind}"><origin xyz="{xyz}" rpy="{rpy}"/><parent link="{parent}"/><child link="{child}"/><axis xyz="{} {} {}"/><limit lower="{lo}" upper="{hi}" velocity="{velocity}" effort="{effort}"/></joint>"#,
                        xml_escape(&name),
                        axis.x,
                        axis.y,
                        axis.z
                    );
                }
            }
        }
        let _ = writeln!(out, "</robot>");
        out
    }
}

/// `xyz` and URDF `rpy` (fixed-axis roll, pitch, yaw: `R = Rz(yaw) Ry(pitch) Rx(roll)`) of a
/// transform, as attribute text.
fn xyz_rpy(t: &Rt) -> (String, String) {
    let (roll, pitch, yaw) = Rotation3::from_matrix_unchecked(t.r).euler_angles();
    (
        format!("{} {} {}", t.p.x, t.p.y, t.p.z),
        format!("{roll} {pitch} {yaw}"),
    )
}

/// A `<visual>` cylinder from `from` to `to` (URDF cylinders lie along their z axis, centred).
fn visual_cylinder(
    out: &mut String,
    from: &Vector3<f64>,
    to: &Vector3<f64>,
    radius: f64,
    material: &str,
) {
    let d = to - from;
    let length = d.norm();
    let rotation = Rotation3::rotation_between(&Vector3::z(), &d)
        // Antiparallel to z: half a turn about x.
        .unwrap_or_else(|| Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
    let (xyz, rpy) = xyz_rpy(&Rt {
        r: *rotation.matrix(),
        p: (from + to) * 0.5,
    });
    let _ = writeln!(
        out,
        r#"    <visual><origin xyz="{xyz}" rpy="{rpy}"/><geometry><cylinder radius="{radius}" length="{length}"/></geometry><material name="{material}"/></visual>"#
    );
}

/// Text safe inside an XML attribute.
fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
}
