//! URDF robots beyond the PUMA: the SCARA fixture (`drivers/robots/scara.urdf`: a prismatic
//! quill, a fixed tool link, a camera fixed off the chain) against hand-derived kinematics and
//! potential energy and against finite differences; and every refused URDF feature with the
//! message that names the element.

use nalgebra::{Matrix3, Rotation3, Vector3};
use penelope_drivers::model::{self, SerialRobotModel, UrdfChain, UrdfError, urdf};
use penelope_hal::{Dynamics, JacobianFrame, JointVector, Kinematics, RobotModel};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const SCARA: &str = include_str!("../robots/scara.urdf");

fn scara() -> SerialRobotModel {
    urdf::model_from_str(SCARA, &UrdfChain::to_tip("tool")).unwrap()
}

fn q3(a: f64, b: f64, c: f64) -> JointVector {
    JointVector::from_column_slice(&[a, b, c, 0.0, 0.0, 0.0])
}

fn rz(a: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), a)
}

/// Hand-derived: the shoulder axis 0.5 m up, links 0.4 and 0.3 m, the quill down by `q3`, the
/// tool 0.1 m below the quill, turned half a turn about x.
fn hand_tool(q: &JointVector) -> (Vector3<f64>, Matrix3<f64>) {
    let (a, b) = (q[0], q[0] + q[1]);
    let p = Vector3::new(
        0.4 * a.cos() + 0.3 * b.cos(),
        0.4 * a.sin() + 0.3 * b.sin(),
        0.5 - q[2] - 0.1,
    );
    let r = rz(b) * Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    (p, *r.matrix())
}

/// Hand-derived centres of mass (kg, world position) of every moving link, the camera and the
/// tool included.
fn hand_masses(q: &JointVector) -> [(f64, Vector3<f64>); 5] {
    let p1 = Vector3::new(0.0, 0.0, 0.5);
    let elbow = p1 + rz(q[0]) * Vector3::new(0.4, 0.0, 0.0);
    let r2 = rz(q[0] + q[1]);
    let quill = elbow + r2 * Vector3::new(0.3, 0.0, 0.0) - Vector3::new(0.0, 0.0, q[2]);
    [
        (2.0, p1 + rz(q[0]) * Vector3::new(0.2, 0.0, 0.0)),
        (1.5, elbow + r2 * Vector3::new(0.15, 0.0, 0.0)),
        (0.2, elbow + r2 * Vector3::new(0.1, 0.05, 0.02)),
        (0.5, quill - Vector3::new(0.0, 0.0, 0.1)),
        (0.3, quill - Vector3::new(0.0, 0.0, 0.12)),
    ]
}

fn potential(q: &JointVector, g: &Vector3<f64>) -> f64 {
    hand_masses(q).iter().map(|(m, c)| -m * g.dot(c)).sum()
}

fn configurations(count: usize) -> Vec<JointVector> {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    (0..count)
        .map(|_| {
            q3(
                rng.random_range(-2.5..2.5),
                rng.random_range(-2.5..2.5),
                rng.random_range(0.0..0.2),
            )
        })
        .collect()
}

#[test]
fn the_scara_chain_folds_fixed_joints_and_keeps_the_limits() {
    let m = scara();
    assert_eq!(m.kind(), "urdf");
    assert_eq!(m.joint_count(), 3);
    assert_eq!(m.joint_names(), ["shoulder", "elbow", "quill"]);
    let l = m.limits();
    assert_eq!((l.position_min[2], l.position_max[2]), (0.0, 0.2));
    assert_eq!((l.velocity_max[0], l.effort_max[1]), (3.0, 20.0));
    // The tool transform is the fixed tool link: 0.1 m down, half a turn about x.
    let tool = m.chain().tool();
    assert!((tool.translation.vector - Vector3::new(0.0, 0.0, -0.1)).norm() < 1e-15);
    assert!((tool.rotation.angle() - std::f64::consts::PI).abs() < 1e-12);
    // <dynamics damping friction> on the shoulder.
    let f = m.friction(&q3(1.0, 0.0, 0.0));
    assert!((f[0] + 0.7).abs() < 1e-12, "{f:?}");
    // The camera (off the chain, fixed to the forearm) is in the forearm's mass.
    assert!((m.link_dynamics(1).unwrap().mass - 1.7).abs() < 1e-12);
    assert!((m.link_dynamics(2).unwrap().mass - 0.8).abs() < 1e-12);
}

#[test]
fn scara_forward_kinematics_is_the_hand_derived_one() {
    let m = scara();
    let mut qs = vec![q3(0.0, 0.0, 0.0), q3(1.0, -0.5, 0.1), q3(-2.0, 2.4, 0.2)];
    qs.extend(configurations(200));
    for q in qs {
        let t = m.forward_matrix(&q);
        let (p, r) = hand_tool(&q);
        let e = (t.fixed_view::<3, 1>(0, 3) - p).abs().max();
        let er = (t.fixed_view::<3, 3>(0, 0) - r).abs().max();
        assert!(
            e < 1e-12 && er < 1e-12,
            "FK off by {e:e} m, {er:e} at {q:?}"
        );
    }
}

#[test]
fn scara_jacobian_is_the_derivative_of_forward_kinematics() {
    let m = scara();
    let h = 1e-6;
    for q in configurations(100) {
        let jac = m.jacobian(&q, JacobianFrame::Base);
        let tool_jac = m.jacobian(&q, JacobianFrame::Tool);
        let (_, r) = hand_tool(&q);
        for j in 0..3 {
            let mut qp = q;
            let mut qm = q;
            qp[j] += h;
            qm[j] -= h;
            let (pp, rp) = hand_tool(&qp);
            let (pm, rm) = hand_tool(&qm);
            let v = (pp - pm) / (2.0 * h);
            let s = (rp - rm) / (2.0 * h) * r.transpose(); // [w]x
            let w = Vector3::new(s[(2, 1)], s[(0, 2)], s[(1, 0)]);
            let col = jac.column(j);
            let e = (col.fixed_rows::<3>(0) - v)
                .abs()
                .max()
                .max((col.fixed_rows::<3>(3) - w).abs().max());
            assert!(e < 1e-7, "column {j} off by {e:e} at {q:?}");
            let tv = r.transpose() * col.fixed_rows::<3>(0);
            let tw = r.transpose() * col.fixed_rows::<3>(3);
            let tc = tool_jac.column(j);
            let e = (tc.fixed_rows::<3>(0) - tv)
                .abs()
                .max()
                .max((tc.fixed_rows::<3>(3) - tw).abs().max());
            assert!(e < 1e-12, "tool-frame column {j} off by {e:e}");
        }
    }
}

#[test]
fn scara_gravity_is_the_gradient_of_the_hand_potential_energy() {
    let m = scara();
    let h = 1e-6;
    // Gravity down: the quill holds the quill and tool, the vertical axes hold nothing.
    let hold = Dynamics::gravity(&m, &q3(0.3, -0.2, 0.1));
    assert!((hold[2] + 0.8 * 9.81).abs() < 1e-12, "{hold:?}");
    assert!(hold[0].abs() < 1e-12 && hold[1].abs() < 1e-12, "{hold:?}");
    // Sideways gravity loads every joint: holding torque = dV/dq.
    let g = Vector3::new(-3.0, 9.0, -9.81);
    for q in configurations(100) {
        let tau = m.gravity_with(&q, &g);
        for j in 0..3 {
            let mut qp = q;
            let mut qm = q;
            qp[j] += h;
            qm[j] -= h;
            let dv = (potential(&qp, &g) - potential(&qm, &g)) / (2.0 * h);
            assert!((tau[j] - dv).abs() < 1e-7, "joint {j}: {} vs {dv}", tau[j]);
        }
    }
}

#[test]
fn scara_inertia_and_newton_euler_agree() {
    let m = scara();
    let zero = JointVector::zeros();
    for q in configurations(50) {
        let mass = m.inertia(&q);
        for i in 0..3 {
            let mut e = JointVector::zeros();
            e[i] = 1.0;
            let col = m.inverse_dynamics_with(&q, &zero, &e, &Vector3::zeros());
            for j in 0..3 {
                assert!((mass[(j, i)] - col[j]).abs() < 1e-12);
            }
        }
        // The quill slides straight down: it carries only its own and the tool's mass.
        assert!((mass[(2, 2)] - 0.8).abs() < 1e-12);
        let static_rne = m.inverse_dynamics(&q, &zero, &zero);
        assert!((static_rne - Dynamics::gravity(&m, &q)).abs().max() < 1e-12);
    }
}

#[test]
fn scara_newton_euler_conserves_energy() {
    // Power balance: qd · (tau - g) = d/dt (qd^T M qd / 2) = qd^T M qdd + qd^T Mdot qd / 2, with
    // Mdot from finite differences of the inertia matrix along qd.
    let m = scara();
    let mut rng = ChaCha8Rng::seed_from_u64(43);
    let h = 1e-6;
    for q in configurations(100) {
        let qd = q3(
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(-0.5..0.5),
        );
        let qdd = q3(
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
            rng.random_range(-1.0..1.0),
        );
        let tau = m.inverse_dynamics(&q, &qd, &qdd) - Dynamics::gravity(&m, &q);
        let mdot = (m.inertia(&(q + qd * h)) - m.inertia(&(q - qd * h))) / (2.0 * h);
        let power = qd.dot(&(m.inertia(&q) * qdd)) + 0.5 * qd.dot(&(mdot * qd));
        assert!(
            (qd.dot(&tau) - power).abs() < 1e-6,
            "{} vs {power}",
            qd.dot(&tau)
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Refused URDFs
// ---------------------------------------------------------------------------------------------

fn link(name: &str) -> String {
    format!("<link name=\"{name}\"/>")
}

fn joint(name: &str, kind: &str, parent: &str, child: &str, extra: &str) -> String {
    format!(
        "<joint name=\"{name}\" type=\"{kind}\"><parent link=\"{parent}\"/><child link=\"{child}\"/>\
         <axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" velocity=\"1\" effort=\"1\"/>{extra}</joint>"
    )
}

fn robot(parts: &[String]) -> String {
    format!("<robot name=\"r\">{}</robot>", parts.concat())
}

/// Two links joined by a revolute joint `j1`, plus `more`.
fn base_arm(more: &[String]) -> String {
    let mut parts = vec![
        link("base"),
        link("arm"),
        joint("j1", "revolute", "base", "arm", ""),
    ];
    parts.extend_from_slice(more);
    robot(&parts)
}

fn refused(text: &str, chain: &UrdfChain) -> (UrdfError, String) {
    let e = urdf::model_from_str(text, chain).unwrap_err();
    let message = e.to_string();
    println!("refused: {message}");
    (e, message)
}

#[test]
fn unsupported_joints_are_refused_by_name() {
    for kind in ["floating", "planar", "spherical"] {
        let text = base_arm(&[link("x"), joint("wobble", kind, "arm", "x", "")]);
        let (e, msg) = refused(&text, &UrdfChain::whole());
        assert!(matches!(e, UrdfError::UnsupportedJoint { .. }), "{e:?}");
        assert!(msg.contains("`wobble`") && msg.contains(kind), "{msg}");
    }
    let text = base_arm(&[
        link("x"),
        joint("follower", "revolute", "arm", "x", "<mimic joint=\"j1\"/>"),
    ]);
    let (e, msg) = refused(&text, &UrdfChain::whole());
    assert!(matches!(e, UrdfError::Mimic { .. }), "{e:?}");
    assert!(msg.contains("`follower`") && msg.contains("mimic") && msg.contains("j1"));
}

#[test]
fn closed_chains_are_refused_by_name() {
    // `arm` has a second parent.
    let text = base_arm(&[link("other"), joint("j2", "revolute", "other", "arm", "")]);
    let (e, msg) = refused(&text, &UrdfChain::whole());
    assert!(matches!(e, UrdfError::TwoParents { .. }), "{e:?}");
    assert!(msg.contains("`arm`") && msg.contains("`j1`") && msg.contains("`j2`"));
    // A loop of joints away from the root.
    let text = base_arm(&[
        link("p"),
        link("q"),
        joint("pq", "revolute", "p", "q", ""),
        joint("qp", "revolute", "q", "p", ""),
    ]);
    let (e, msg) = refused(&text, &UrdfChain::whole());
    assert!(matches!(e, UrdfError::Loop(_)), "{e:?}");
    assert!(msg.contains("p, q") && msg.contains("loop"), "{msg}");
}

#[test]
fn broken_structure_is_refused_by_name() {
    let text = base_arm(&[joint("j2", "revolute", "arm", "hand", "")]);
    let (e, msg) = refused(&text, &UrdfChain::whole());
    assert!(matches!(e, UrdfError::MissingLink { .. }), "{e:?}");
    assert!(
        msg.contains("`j2`") && msg.contains("child link `hand`"),
        "{msg}"
    );

    let text = base_arm(&[link("arm")]);
    let (e, msg) = refused(&text, &UrdfChain::whole());
    assert!(
        matches!(e, UrdfError::Duplicate { what: "link", .. }),
        "{msg}"
    );

    let text = base_arm(&[link("island")]);
    let (_, msg) = refused(&text, &UrdfChain::whole());
    assert!(
        msg.contains("several root links") && msg.contains("island"),
        "{msg}"
    );

    let (_, msg) = refused(&base_arm(&[]), &UrdfChain::to_tip("gripper"));
    assert!(msg.contains("tip link `gripper`"), "{msg}");

    let chain = UrdfChain {
        base: Some("arm".into()),
        tip: Some("base".into()),
    };
    let (e, _) = refused(&base_arm(&[]), &chain);
    assert!(matches!(e, UrdfError::NotBelow { .. }), "{e:?}");

    let text = robot(&[link("a"), link("b"), joint("weld", "fixed", "a", "b", "")]);
    let (e, msg) = refused(&text, &UrdfChain::whole());
    assert!(matches!(e, UrdfError::NoMovingJoint { .. }), "{msg}");
}

#[test]
fn an_ambiguous_tip_lists_the_leaves() {
    let (e, msg) = refused(SCARA, &UrdfChain::whole());
    assert!(matches!(e, UrdfError::AmbiguousTip(_)), "{e:?}");
    assert!(msg.contains("camera, tool"), "{msg}");
}

#[test]
fn too_many_joints_are_refused_with_their_names() {
    let mut parts = vec![link("l0")];
    for k in 1..=7 {
        parts.push(link(&format!("l{k}")));
        let (p, c) = (format!("l{}", k - 1), format!("l{k}"));
        parts.push(joint(&format!("j{k}"), "revolute", &p, &c, ""));
    }
    let (e, msg) = refused(&robot(&parts), &UrdfChain::whole());
    assert!(matches!(e, UrdfError::TooManyJoints { .. }), "{e:?}");
    assert!(msg.contains("7 moving joints") && msg.contains("j7") && msg.contains("at most 6"));
    // The first six make a model.
    let six = UrdfChain::to_tip("l6");
    assert_eq!(
        urdf::model_from_str(&robot(&parts), &six)
            .unwrap()
            .joint_count(),
        6
    );
}

#[test]
fn malformed_xml_and_numbers_are_refused() {
    let (e, msg) = refused(
        "<robot name=\"r\"><link name=\"a\"></robot>",
        &UrdfChain::whole(),
    );
    assert!(matches!(e, UrdfError::Malformed(_)), "{e:?}");
    assert!(msg.starts_with("malformed URDF"), "{msg}");
    let (e, _) = refused("not xml at all", &UrdfChain::whole());
    assert!(matches!(e, UrdfError::Malformed(_)), "{e:?}");

    let zero_axis = robot(&[
        link("a"),
        link("b"),
        "<joint name=\"spin\" type=\"continuous\"><parent link=\"a\"/><child link=\"b\"/>\
         <axis xyz=\"0 0 0\"/></joint>"
            .into(),
    ]);
    let (_, msg) = refused(&zero_axis, &UrdfChain::whole());
    assert!(
        msg.contains("joint `spin`") && msg.contains("axis"),
        "{msg}"
    );

    let inverted = robot(&[
        link("a"),
        link("b"),
        "<joint name=\"j\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>\
         <limit lower=\"1\" upper=\"-1\" velocity=\"1\" effort=\"1\"/></joint>"
            .into(),
    ]);
    let (_, msg) = refused(&inverted, &UrdfChain::whole());
    assert!(
        msg.contains("joint `j`") && msg.contains("lower 1 is above upper -1"),
        "{msg}"
    );

    let no_limit = robot(&[
        link("a"),
        link("b"),
        "<joint name=\"j\" type=\"prismatic\"><parent link=\"a\"/><child link=\"b\"/></joint>"
            .into(),
    ]);
    let (_, msg) = refused(&no_limit, &UrdfChain::whole());
    assert!(
        msg.contains("joint `j`") && msg.contains("lower equals upper"),
        "{msg}"
    );

    let negative_mass = robot(&[
        link("a"),
        "<link name=\"b\"><inertial><mass value=\"-1\"/>\
         <inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial></link>"
            .into(),
        joint("j", "revolute", "a", "b", ""),
    ]);
    let (_, msg) = refused(&negative_mass, &UrdfChain::whole());
    assert!(msg.contains("link `b`") && msg.contains("mass"), "{msg}");

    let indefinite = robot(&[
        link("a"),
        "<link name=\"b\"><inertial><mass value=\"1\"/>\
         <inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"-1\" iyz=\"0\" izz=\"1\"/></inertial></link>"
            .into(),
        joint("j", "revolute", "a", "b", ""),
    ]);
    let (_, msg) = refused(&indefinite, &UrdfChain::whole());
    assert!(
        msg.contains("link `b`") && msg.contains("positive semi-definite"),
        "{msg}"
    );
}

#[test]
fn load_takes_a_urdf_path_and_reports_missing_files() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/puma560.urdf");
    let m = model::load(path).unwrap();
    assert_eq!((m.kind(), m.joint_count()), ("urdf", 6));
    let e = model::load("/nonexistent/robot.urdf").unwrap_err();
    assert!(e.to_string().contains("/nonexistent/robot.urdf"), "{e}");
    // The SCARA needs its tip named.
    let scara = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/scara.urdf");
    assert!(model::load(scara).is_err());
    assert_eq!(
        model::from_urdf_file(scara, Some("tool"))
            .unwrap()
            .joint_count(),
        3
    );
}
