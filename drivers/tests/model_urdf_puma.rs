//! The PUMA 560 as a URDF (`drivers/robots/puma560.urdf`), written from its DH table and
//! dynamics, against the DH model: forward kinematics, the Jacobian in both frames, gravity,
//! the inertia matrix and recursive Newton-Euler agree within 1e-9 over seeded random
//! configurations.
//!
//! The URDF is generated here ([`puma560_urdf`]) and the committed file must equal the
//! generator's output; `PENELOPE_WRITE_URDF=1 cargo test -p penelope-drivers --test
//! model_urdf_puma` rewrites it.
//!
//! How DH becomes URDF: standard DH `A_j = Rz(q_j) · S_j` with `S_j = Tz(d_j) Tx(a_j) Rx(alpha_j)`.
//! URDF joint `j` rotates about the z axis of its joint frame, placed at `S_{j-1}` in link `j-1`
//! (`S_0` = the identity), so URDF link `j`'s frame is the DH frame `j-1` turned by `q_j`, and DH
//! frame `j` is `S_j` in it. Each link's inertial therefore sits at `S_j` composed with the DH
//! centre of mass (`<origin xyz = S_j · com, rpy = (alpha_j, 0, 0)>`, the inertia tensor unchanged,
//! as it is given in the DH frame). The last `S_6` (and the DH tool) is a fixed joint to a tool
//! link.

use nalgebra::{Rotation3, Vector3};
use penelope_drivers::model::{self, ChainJoint, RobotFile, SerialRobotModel, UrdfChain};
use penelope_hal::{Dynamics, JacobianFrame, JointVector, Kinematics, RobotModel};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const COMMITTED: &str = include_str!("../robots/puma560.urdf");
const PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/puma560.urdf");

/// A number as URDF text: the shortest decimal that reads back to the same `f64`, with rounding
/// noise of `cos(pi/2)` (below 1e-15) written as 0.
fn num(x: f64) -> String {
    if x.abs() < 1e-15 {
        "0".into()
    } else {
        format!("{x}")
    }
}

fn triple(v: [f64; 3]) -> String {
    format!("{} {} {}", num(v[0]), num(v[1]), num(v[2]))
}

/// The URDF of a DH model with zero joint offsets, revolute joints and an identity base.
fn puma560_urdf(m: &SerialRobotModel) -> String {
    let chain = m.chain();
    let n = chain.joint_count();
    let mut out = String::new();
    out.push_str(
        "<?xml version=\"1.0\"?>\n\
         <!-- The PUMA 560 of Corke's Robotics Toolbox (standard DH, with pedestal; dynamics after\n\
         \x20    Armstrong, Khatib and Burdick 1986 as reconciled by Corke and Armstrong-Helouvry 1994),\n\
         \x20    written from drivers/robots/puma560.toml by drivers/tests/model_urdf_puma.rs (do not edit\n\
         \x20    by hand: regenerate with PENELOPE_WRITE_URDF=1).\n\
         \x20    URDF link j's frame is DH frame j-1 turned by q_j; DH frame j is at origin (a_j, 0, d_j),\n\
         \x20    rpy (alpha_j, 0, 0) in it, which is where each inertial sits.\n\
         \x20    URDF has no rotor inertia, gears or motor friction: those stay in the DH file. -->\n",
    );
    out.push_str("<robot name=\"puma560\">\n  <link name=\"base_link\"/>\n");
    let mut prev = [0.0f64; 3]; // (a, d, alpha) of the previous row: S_{j-1}
    for j in 0..n {
        let l = chain.link(j).expect("a DH row");
        assert_eq!(l.offset, 0.0, "the generator assumes zero offsets");
        let d = m.link_dynamics(j).unwrap();
        let lim = m.limits();
        let s_rot = Rotation3::from_axis_angle(&Vector3::x_axis(), l.alpha);
        let com = Vector3::new(l.a, 0.0, l.d) + s_rot * d.com;
        let i = d.inertia;
        let name = &m.joint_names()[j];
        out.push_str(&format!(
            "  <joint name=\"{name}\" type=\"revolute\">\n\
             \x20   <parent link=\"{parent}\"/>\n\
             \x20   <child link=\"link{k}\"/>\n\
             \x20   <origin xyz=\"{xyz}\" rpy=\"{rpy}\"/>\n\
             \x20   <axis xyz=\"0 0 1\"/>\n\
             \x20   <limit lower=\"{lo}\" upper=\"{hi}\" velocity=\"{v}\" effort=\"{e}\"/>\n\
             \x20 </joint>\n\
             \x20 <link name=\"link{k}\">\n\
             \x20   <inertial>\n\
             \x20     <origin xyz=\"{cxyz}\" rpy=\"{crpy}\"/>\n\
             \x20     <mass value=\"{mass}\"/>\n\
             \x20     <inertia ixx=\"{ixx}\" ixy=\"{ixy}\" ixz=\"{ixz}\" iyy=\"{iyy}\" iyz=\"{iyz}\" izz=\"{izz}\"/>\n\
             \x20   </inertial>\n\
             \x20 </link>\n",
            parent = if j == 0 {
                "base_link".to_string()
            } else {
                format!("link{j}")
            },
            k = j + 1,
            xyz = triple([prev[0], 0.0, prev[1]]),
            rpy = triple([prev[2], 0.0, 0.0]),
            lo = num(lim.position_min[j]),
            hi = num(lim.position_max[j]),
            v = num(lim.velocity_max[j]),
            e = num(lim.effort_max[j]),
            cxyz = triple(com.into()),
            crpy = triple([l.alpha, 0.0, 0.0]),
            mass = num(d.mass),
            ixx = num(i[(0, 0)]),
            ixy = num(i[(0, 1)]),
            ixz = num(i[(0, 2)]),
            iyy = num(i[(1, 1)]),
            iyz = num(i[(1, 2)]),
            izz = num(i[(2, 2)]),
        ));
        prev = [l.a, l.d, l.alpha];
    }
    // The last S_6 and the DH tool transform: a fixed joint to the tool link.
    let tool = m.chain().tool();
    let s6 = nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(prev[0], 0.0, prev[1]),
        nalgebra::UnitQuaternion::from_axis_angle(&Vector3::x_axis(), prev[2]),
    ) * tool;
    let (r, p, y) = s6.rotation.euler_angles();
    out.push_str(&format!(
        "  <joint name=\"tool\" type=\"fixed\">\n\
         \x20   <parent link=\"link{n}\"/>\n\
         \x20   <child link=\"tool0\"/>\n\
         \x20   <origin xyz=\"{}\" rpy=\"{}\"/>\n\
         \x20 </joint>\n\
         \x20 <link name=\"tool0\"/>\n</robot>\n",
        triple(s6.translation.vector.into()),
        triple([r, p, y]),
    ));
    out
}

#[test]
fn the_committed_urdf_is_the_generated_one() {
    let text = puma560_urdf(&model::puma560());
    if std::env::var_os("PENELOPE_WRITE_URDF").is_some() {
        std::fs::write(PATH, &text).unwrap();
        return;
    }
    assert_eq!(
        COMMITTED, text,
        "drivers/robots/puma560.urdf differs from the generator; regenerate with \
         PENELOPE_WRITE_URDF=1"
    );
}

fn urdf_puma() -> SerialRobotModel {
    model::urdf::model_from_str(COMMITTED, &UrdfChain::whole()).unwrap()
}

/// The DH model without rotor inertia (URDF has none).
fn dh_puma_without_rotors() -> SerialRobotModel {
    let mut spec = RobotFile::parse(model::PUMA560_TOML)
        .unwrap()
        .to_spec()
        .unwrap();
    for d in &mut spec.dynamics {
        d.motor_inertia = 0.0;
    }
    SerialRobotModel::new("puma560", spec).unwrap()
}

fn configurations(count: usize) -> Vec<JointVector> {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    (0..count)
        .map(|_| JointVector::from_fn(|_, _| rng.random_range(-3.5..3.5)))
        .collect()
}

fn max_diff<const R: usize, const C: usize>(
    a: &nalgebra::SMatrix<f64, R, C>,
    b: &nalgebra::SMatrix<f64, R, C>,
) -> f64 {
    (a - b).abs().max()
}

#[test]
fn the_urdf_is_a_chain_of_six_axis_joints_with_the_limits() {
    let u = urdf_puma();
    let d = model::puma560();
    assert_eq!(u.kind(), "urdf");
    assert_eq!(u.joint_count(), 6);
    assert!(matches!(u.chain().joint(0), Some(ChainJoint::Axis(_))));
    assert!(
        !u.has_closed_form(),
        "an axis chain takes the numerical solver"
    );
    assert_eq!(u.joint_names(), d.joint_names());
    let (lu, ld) = (u.limits(), d.limits());
    for j in 0..6 {
        assert_eq!(lu.position_min[j], ld.position_min[j]);
        assert_eq!(lu.position_max[j], ld.position_max[j]);
        assert_eq!(lu.velocity_max[j], ld.velocity_max[j]);
        assert_eq!(lu.effort_max[j], ld.effort_max[j]);
    }
}

#[test]
fn kinematics_equal_the_dh_model() {
    let (u, d) = (urdf_puma(), model::puma560());
    let mut largest = [0.0f64; 3];
    for q in configurations(500) {
        let e = max_diff(&u.forward_matrix(&q), &d.forward_matrix(&q));
        assert!(e < 1e-9, "FK differs by {e:e} at {q:?}");
        largest[0] = largest[0].max(e);
        for (k, frame) in [JacobianFrame::Base, JacobianFrame::Tool]
            .into_iter()
            .enumerate()
        {
            let e = max_diff(&u.jacobian(&q, frame), &d.jacobian(&q, frame));
            assert!(e < 1e-9, "{frame:?} Jacobian differs by {e:e} at {q:?}");
            largest[1 + k] = largest[1 + k].max(e);
        }
    }
    println!(
        "largest differences over 500 configurations: FK {:.1e}, Jacobian base {:.1e}, tool {:.1e}",
        largest[0], largest[1], largest[2]
    );
}

#[test]
fn dynamics_equal_the_dh_model() {
    let (u, d) = (urdf_puma(), dh_puma_without_rotors());
    let full = model::puma560();
    let mut rng = ChaCha8Rng::seed_from_u64(18);
    let mut largest = [0.0f64; 4];
    for q in configurations(500) {
        let qd = JointVector::from_fn(|_, _| rng.random_range(-2.0..2.0));
        let qdd = JointVector::from_fn(|_, _| rng.random_range(-5.0..5.0));
        let e = max_diff(&u.gravity(&q), &Dynamics::gravity(&d, &q));
        assert!(e < 1e-9, "gravity differs by {e:e} at {q:?}");
        largest[0] = largest[0].max(e);
        // Gravity does not involve the rotors: the full DH model agrees too.
        let e = max_diff(&u.gravity(&q), &Dynamics::gravity(&full, &q));
        assert!(e < 1e-9, "gravity differs from the full model by {e:e}");
        let e = max_diff(&u.inertia(&q), &d.inertia(&q));
        assert!(e < 1e-9, "inertia differs by {e:e} at {q:?}");
        largest[1] = largest[1].max(e);
        let tu = u.inverse_dynamics(&q, &qd, &qdd);
        let e = max_diff(&tu, &d.inverse_dynamics(&q, &qd, &qdd));
        assert!(e < 1e-9, "RNE differs by {e:e} at {q:?}");
        largest[2] = largest[2].max(e);
        // Against the full model the difference is exactly the reflected rotor inertia.
        let rotors = JointVector::from_fn(|j, _| {
            full.link_dynamics(j).unwrap().reflected_motor_inertia() * qdd[j]
        });
        let e = max_diff(&(tu + rotors), &full.inverse_dynamics(&q, &qd, &qdd));
        assert!(e < 1e-9, "RNE + Jm G² qdd differs by {e:e}");
        largest[3] = largest[3].max(e);
    }
    println!(
        "largest differences over 500 configurations: gravity {:.1e} N·m, inertia {:.1e} kg·m², \
         RNE {:.1e} N·m, RNE + rotors vs the full model {:.1e} N·m",
        largest[0], largest[1], largest[2], largest[3]
    );
}

#[test]
fn numerical_ik_on_the_urdf_reaches_dh_poses() {
    let (u, d) = (urdf_puma(), model::puma560());
    let work = d.pose("work").unwrap();
    for q in configurations(20) {
        // Targets near the work pose, seeded from it, so one branch is followed.
        let target_q = work + (q - work) * 0.1;
        let target = d.forward(&target_q);
        let sol = u.inverse_numerical(&target, &work).unwrap();
        let reached = d.forward(&sol);
        assert!((reached.translation.vector - target.translation.vector).norm() < 1e-8);
        assert!(reached.rotation.angle_to(&target.rotation) < 1e-8);
    }
}
