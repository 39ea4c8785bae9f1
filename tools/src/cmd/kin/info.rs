//! `penelope kin <robot> info`: the model's joints (a DH table, or origin-and-axis rows for a
//! URDF chain), limits, named poses and assumptions.

use std::fmt::Write as _;

use penelope_drivers::model::{self, SerialRobotModel};
use penelope_hal::Kinematics;
use serde_json::json;

/// What `info` prints: text, or one JSON object.
pub(super) fn info(m: &SerialRobotModel, as_json: bool) -> String {
    let n = m.joint_count();
    let chain = m.chain();
    let links: Vec<_> = (0..n).filter_map(|j| chain.joint(j)).collect();
    if as_json {
        return info_json(m, &links);
    }
    let mut s = format!("{} — {}\n", m.name(), m.description());
    let _ = writeln!(
        s,
        "inverse kinematics: {}",
        if m.has_closed_form() {
            "closed form, 8 branches"
        } else {
            "damped least squares"
        }
    );
    // A DH table when every joint is a DH row; else origin-and-axis rows (a URDF chain).
    let dh: Vec<_> = links.iter().filter_map(chain_dh).collect();
    if dh.len() < links.len() {
        s += &axis_joints_text(m, &links);
    } else {
        s += &dh_table_text(m, &dh);
    }
    s += "named poses (deg):\n";
    for (name, q) in m.poses() {
        let q: Vec<String> = q
            .iter()
            .take(n)
            .map(|x| format!("{:.1}", x.to_degrees()))
            .collect();
        let _ = writeln!(s, "  {name:<8} [{}]", q.join(", "));
    }
    if !m.assumptions().is_empty() {
        s += "assumptions:\n";
        for a in m.assumptions() {
            let _ = writeln!(s, "  - {a}");
        }
    }
    s
}

/// `info` as one JSON object.
fn info_json(m: &SerialRobotModel, links: &[model::ChainJoint]) -> String {
    let n = m.joint_count();
    let lim = penelope_hal::RobotModel::limits(m);
    let joints: Vec<_> = links
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            let mut o = json!({
                "name": m.joint_names()[j],
                "type": if joint.kind() == model::JointKind::Revolute { "revolute" } else { "prismatic" },
                "limits": [finite_or_null(lim.position_min[j]), finite_or_null(lim.position_max[j])],
                "counts_per_radian": m.counts_per_radian(j),
            });
            let geometry = match joint {
                model::ChainJoint::Dh(l) => json!({
                    "theta": l.theta, "d": l.d, "a": l.a, "alpha": l.alpha, "offset": l.offset,
                }),
                model::ChainJoint::Axis(a) => {
                    let (r, p, y) = a.origin.rotation.euler_angles();
                    json!({
                        "origin_xyz": a.origin.translation.vector.as_slice(),
                        "origin_rpy": [r, p, y],
                        "axis": a.axis.as_slice(),
                    })
                }
            };
            if let (Some(o), serde_json::Value::Object(g)) = (o.as_object_mut(), geometry) {
                o.extend(g);
            }
            o
        })
        .collect();
    let poses: serde_json::Map<String, serde_json::Value> = m
        .poses()
        .iter()
        .map(|(name, q)| (name.clone(), json!(&q.as_slice()[..n])))
        .collect();
    json!({
        "name": m.name(),
        "kind": m.kind(),
        "description": m.description(),
        "assumptions": m.assumptions(),
        "inverse_kinematics": if m.has_closed_form() { "closed-form" } else { "numerical" },
        "joints": joints,
        "poses": poses,
    })
    .to_string()
}

/// The DH table: one row per joint, with its limits.
fn dh_table_text(m: &SerialRobotModel, dh: &[model::DhLink]) -> String {
    let lim = penelope_hal::RobotModel::limits(m);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:>2} {:<14} {:>10} {:>10} {:>8} {:>8}  {:>17}",
        "j", "name", "d (m)", "a (m)", "alpha°", "offset°", "limits (deg)"
    );
    for (j, l) in dh.iter().enumerate() {
        let _ = writeln!(
            s,
            "{:>2} {:<14} {:>10.5} {:>10.5} {:>8.2} {:>8.2}  {:>8.1} {:>8.1}",
            j + 1,
            m.joint_names()[j],
            l.d,
            l.a,
            l.alpha.to_degrees(),
            l.offset.to_degrees(),
            lim.position_min[j].to_degrees(),
            lim.position_max[j].to_degrees()
        );
    }
    s
}

fn chain_dh(joint: &model::ChainJoint) -> Option<model::DhLink> {
    match joint {
        model::ChainJoint::Dh(l) => Some(*l),
        model::ChainJoint::Axis(_) => None,
    }
}

/// The joint table of a chain with axis (URDF) joints: origin, axis, limits.
fn axis_joints_text(m: &SerialRobotModel, joints: &[model::ChainJoint]) -> String {
    let lim = penelope_hal::RobotModel::limits(m);
    let mut s = format!(
        "{:>2} {:<14} {:<9} {:<26} {:<20} {:<22}  {}\n",
        "j", "name", "type", "origin xyz (m)", "origin rpy (deg)", "axis", "limits"
    );
    for (j, joint) in joints.iter().enumerate() {
        let triple = |v: [f64; 3], p: usize| format!("{:.p$} {:.p$} {:.p$}", v[0], v[1], v[2]);
        let (kind, origin, rpy, axis) = match joint {
            model::ChainJoint::Axis(a) => {
                let (r, p, y) = a.origin.rotation.euler_angles();
                let rpy = [r.to_degrees(), p.to_degrees(), y.to_degrees()];
                (
                    a.kind,
                    a.origin.translation.vector.into(),
                    rpy,
                    a.axis.into(),
                )
            }
            model::ChainJoint::Dh(l) => (l.kind, [0.0; 3], [0.0; 3], [0.0, 0.0, 1.0]),
        };
        let (word, scale, unit) = match kind {
            model::JointKind::Revolute => ("revolute", 180.0 / std::f64::consts::PI, "deg"),
            model::JointKind::Prismatic => ("prismatic", 1.0, "m"),
        };
        let _ = writeln!(
            s,
            "{:>2} {:<14} {:<9} {:<26} {:<20} {:<22}  {:.3} {:.3} {unit}",
            j + 1,
            m.joint_names()[j],
            word,
            triple(origin, 5),
            triple(rpy, 2),
            triple(axis, 4),
            lim.position_min[j] * scale,
            lim.position_max[j] * scale,
        );
    }
    let t = m.chain().tool();
    let (r, p, y) = t.rotation.euler_angles();
    let v = t.translation.vector;
    let _ = writeln!(
        s,
        "tool: xyz {:.5} {:.5} {:.5} m, rpy {:.2} {:.2} {:.2} deg",
        v.x,
        v.y,
        v.z,
        r.to_degrees(),
        p.to_degrees(),
        y.to_degrees()
    );
    s
}

fn finite_or_null(x: f64) -> serde_json::Value {
    if x.is_finite() {
        json!(x)
    } else {
        serde_json::Value::Null
    }
}
