//! Kinematics of the DH models: the analytic Jacobian against finite differences of forward
//! kinematics, `fk(ik(T)) = T` on every branch, 2π-equivalents inside the limits, branch
//! continuity, and the numerical solver on chains without a closed form.

use nalgebra::{Matrix3, Vector3};
use penelope_drivers::model::{self, SerialRobotModel};
use penelope_hal::{
    IkSolutions, InverseKinematics, JacobianFrame, JointVector, Kinematics, KinematicsError,
    NamedPose, Pose, RobotModel,
};
use proptest::prelude::*;

/// A 6R arm without a closed form here: a PUMA with a shoulder offset a1 = 0.15 m, an offset
/// wrist (a5 = 0.02 m) and a tool.
const OFFSET_ARM: &str = r#"
name = "offset-arm"
[units]
angle = "deg"
[tool]
xyz = [0.0, 0.0, 0.08]
[[joints]]
d = 0.5
a = 0.15
alpha = 90.0
limits = [-170.0, 170.0]
[[joints]]
a = 0.43
limits = [-100.0, 200.0]
[[joints]]
d = 0.15
a = 0.02
alpha = -90.0
limits = [-225.0, 45.0]
[[joints]]
d = 0.43
alpha = 90.0
limits = [-180.0, 180.0]
[[joints]]
a = 0.02
alpha = -90.0
limits = [-120.0, 120.0]
[[joints]]
d = 0.05
limits = [-270.0, 270.0]
[poses]
nest = [0.0, 90.0, -180.0, 0.0, -90.0, 0.0]
start = [0.0, 45.0, -150.0, 0.0, 45.0, 0.0]
work = [30.0, 30.0, -120.0, 20.0, -30.0, 10.0]
"#;

/// The Stanford arm (a prismatic third joint), after the Robotics Toolbox's model.
const STANFORD: &str = r#"
name = "stanford"
[units]
angle = "deg"
[[joints]]
d = 0.412
alpha = -90.0
limits = [-170.0, 170.0]
[[joints]]
d = 0.154
alpha = 90.0
limits = [-170.0, 170.0]
[[joints]]
type = "prismatic"
theta = -90.0
a = 0.0203
limits = [0.3, 0.8]
[[joints]]
alpha = -90.0
limits = [-170.0, 170.0]
[[joints]]
alpha = 90.0
limits = [-90.0, 90.0]
[[joints]]
d = 0.263
limits = [-170.0, 170.0]
[poses]
nest = [0.0, 0.0, 0.3, 0.0, 0.0, 0.0]
start = [0.0, 45.0, 0.5, 0.0, 30.0, 0.0]
work = [20.0, 60.0, 0.6, 10.0, 40.0, 20.0]
"#;

fn models() -> Vec<SerialRobotModel> {
    vec![
        model::puma560(),
        model::puma200(),
        model::frhc(),
        model::from_toml_str(OFFSET_ARM).unwrap(),
        model::from_toml_str(STANFORD).unwrap(),
    ]
}

/// A configuration inside the limits from unit fractions.
fn config_in_limits(m: &SerialRobotModel, u: &[f64; 6]) -> JointVector {
    let l = m.limits();
    let mut q = JointVector::zeros();
    for j in 0..m.joint_count() {
        let (lo, hi) = (l.position_min[j], l.position_max[j]);
        q[j] = lo + (0.02 + 0.96 * u[j]) * (hi - lo);
    }
    q
}

/// Largest entry of the difference of the homogeneous matrices (the quaternion angle is not
/// accurate below about 1e-8).
fn pose_distance(a: &Pose, b: &Pose) -> f64 {
    (a.to_homogeneous() - b.to_homogeneous()).amax()
}

fn skew_vector(m: &Matrix3<f64>) -> Vector3<f64> {
    Vector3::new(
        m[(2, 1)] - m[(1, 2)],
        m[(0, 2)] - m[(2, 0)],
        m[(1, 0)] - m[(0, 1)],
    ) * 0.5
}

/// The Jacobian by central differences of `forward`, rows [v; w] in the world frame.
fn numeric_jacobian(m: &SerialRobotModel, q: &JointVector) -> nalgebra::SMatrix<f64, 6, 6> {
    let h = 1e-6;
    let mut jac = nalgebra::SMatrix::<f64, 6, 6>::zeros();
    let r0 = m.forward(q).rotation.to_rotation_matrix().into_inner();
    for j in 0..m.joint_count() {
        let mut qp = *q;
        let mut qm = *q;
        qp[j] += h;
        qm[j] -= h;
        let tp = m.forward(&qp);
        let tm = m.forward(&qm);
        let dp = (tp.translation.vector - tm.translation.vector) / (2.0 * h);
        let rp = tp.rotation.to_rotation_matrix().into_inner();
        let rm = tm.rotation.to_rotation_matrix().into_inner();
        let w = skew_vector(&(((rp - rm) / (2.0 * h)) * r0.transpose()));
        for k in 0..3 {
            jac[(k, j)] = dp[k];
            jac[(k + 3, j)] = w[k];
        }
    }
    jac
}

fn unit6() -> impl Strategy<Value = [f64; 6]> {
    prop::array::uniform6(0.0..1.0f64)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 200,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn analytic_jacobian_equals_finite_differences(u in unit6()) {
        for m in models() {
            let q = config_in_limits(&m, &u);
            let j = m.jacobian(&q, JacobianFrame::Base);
            let jn = numeric_jacobian(&m, &q);
            let err = (j - jn).abs().max();
            prop_assert!(err < 1e-7, "{}: |J - J_fd| = {err} at {q:?}", m.name());
            // The tool-frame Jacobian is the base one with both halves rotated into the tool.
            let r = m.forward(&q).rotation.to_rotation_matrix().into_inner();
            let jt = m.jacobian(&q, JacobianFrame::Tool);
            for c in 0..6 {
                let v = Vector3::new(j[(0, c)], j[(1, c)], j[(2, c)]);
                let w = Vector3::new(j[(3, c)], j[(4, c)], j[(5, c)]);
                let (vt, wt) = (r.transpose() * v, r.transpose() * w);
                for k in 0..3 {
                    prop_assert!((jt[(k, c)] - vt[k]).abs() < 1e-12);
                    prop_assert!((jt[(k + 3, c)] - wt[k]).abs() < 1e-12);
                }
            }
            // One pass gives the same as two calls.
            let (pose, jb) = m.forward_and_jacobian(&q, JacobianFrame::Base);
            prop_assert_eq!(pose, m.forward(&q));
            prop_assert_eq!(jb, j);
        }
    }

    #[test]
    fn every_closed_form_branch_reaches_the_pose(u in unit6()) {
        for m in [model::puma560(), model::puma200(), model::frhc()] {
            prop_assert!(m.has_closed_form(), "{}", m.name());
            let q = config_in_limits(&m, &u);
            let target = m.forward(&q);
            let mut sols = IkSolutions::new();
            prop_assert_eq!(m.inverse_all(&target, &mut sols), Ok(8));
            let mut names: Vec<&str> = sols.iter().map(|s| s.branch).collect();
            names.sort_unstable();
            names.dedup();
            prop_assert_eq!(names.len(), 8, "branch names must be distinct");
            let mut found_original = false;
            for s in &sols {
                let err = pose_distance(&m.forward(&s.q), &target);
                prop_assert!(err < 1e-9, "{} {}: fk(ik(T)) off by {err}", m.name(), s.branch);
                prop_assert_eq!(s.within_limits, m.limits().contains_position(&s.q, 6));
                let same = (0..6).all(|j| {
                    let d = (s.q[j] - q[j]).rem_euclid(core::f64::consts::TAU);
                    d.min(core::f64::consts::TAU - d) < 1e-6
                });
                found_original |= same;
            }
            // Away from the wrist singularity the configuration we started from is one branch.
            let wrist = (q[4] + m.chain().link(4).unwrap().offset).sin().abs();
            if wrist > 1e-3 {
                prop_assert!(found_original, "{}: {q:?} not among the branches", m.name());
            }
            // Tracking: from the original configuration as seed, inverse_near returns it.
            if wrist > 1e-3 {
                let near = m.inverse_near(&target, &q).unwrap();
                prop_assert!((near - q).amax() < 1e-6, "{}: near {near:?} vs {q:?}", m.name());
            }
        }
    }

    #[test]
    fn numerical_inverse_reaches_the_pose_from_a_nearby_seed(u in unit6(), du in unit6()) {
        for m in models() {
            let q = config_in_limits(&m, &u);
            // The property holds away from singularities: near one (an arm stretched, a wrist
            // aligned) damped least squares slows down by design and may run out of iterations.
            let sv = m.jacobian(&q, JacobianFrame::Base).svd(false, false).singular_values;
            if sv.iter().take(m.joint_count()).fold(f64::INFINITY, |a, &b| a.min(b)) < 0.02 {
                continue;
            }
            let target = m.forward(&q);
            let mut seed = q;
            for j in 0..m.joint_count() {
                seed[j] += 0.3 * (du[j] - 0.5);
            }
            let sol = m.inverse_numerical(&target, &seed);
            prop_assert!(sol.is_ok(), "{}: {sol:?} from {seed:?} to {q:?}", m.name());
            let sol = sol.unwrap();
            let err = pose_distance(&m.forward(&sol), &target);
            prop_assert!(err < 1e-8, "{}: DLS error {err}", m.name());
        }
    }
}

#[test]
fn numerical_models_return_numerical_branches() {
    for text in [OFFSET_ARM, STANFORD] {
        let m = model::from_toml_str(text).unwrap();
        assert!(!m.has_closed_form());
        let q = m.named_pose(NamedPose::Work);
        let target = m.forward(&q);
        let mut sols = IkSolutions::new();
        let n = m.inverse_all(&target, &mut sols).unwrap();
        assert!(n >= 1);
        for s in &sols {
            assert_eq!(s.branch, "numerical");
            assert!(pose_distance(&m.forward(&s.q), &target) < 1e-8);
        }
        // The seeds include the work pose itself, so its configuration is found.
        assert!(sols.iter().any(|s| (s.q - q).amax() < 1e-6), "{}", m.name());
        let near = m.inverse_near(&target, &q).unwrap();
        assert!((near - q).amax() < 1e-9);
    }
}

#[test]
fn the_frhc_can_be_forced_to_the_numerical_solver() {
    let text = model::FRHC_TOML.replace(
        "inverse_kinematics = \"auto\"",
        "inverse_kinematics = \"numerical\"",
    );
    let m = model::from_toml_str(&text).unwrap();
    assert!(!m.has_closed_form());
    let home = m.named_pose(NamedPose::Start);
    let mut target = m.forward(&home);
    target.translation.vector += Vector3::new(0.1, -0.1, 0.1); // a corner of the 30 cm cube
    let q = m.inverse_near(&target, &home).unwrap();
    assert!(pose_distance(&m.forward(&q), &target) < 1e-9);
    assert!(m.limits().contains_position(&q, 6));
}

#[test]
fn the_frhc_reaches_a_30_cm_cube_around_home() {
    let m = model::frhc();
    let home = m.named_pose(NamedPose::Start);
    let t0 = m.forward(&home);
    // Grip 0.25 m in front of the shoulder (which is at the origin).
    assert!((t0.translation.vector - Vector3::new(0.25, 0.0, 0.0)).norm() < 1e-12);
    for corner in 0..8 {
        let s = |bit: usize| if corner & bit != 0 { 0.15 } else { -0.15 };
        let mut target = t0;
        target.translation.vector += Vector3::new(s(1), s(2), s(4));
        let q = m.inverse_near(&target, &home).unwrap();
        assert!(
            pose_distance(&m.forward(&q), &target) < 1e-9,
            "corner {corner}"
        );
    }
}

#[test]
fn joint_limits_pick_the_2pi_equivalent() {
    let m = model::puma560();
    // q6 = 250 deg is inside the PUMA 560's +-266 deg; the solver's principal value is -110 deg.
    let mut q = m.named_pose(NamedPose::Start);
    q[5] = 250f64.to_radians();
    let target = m.forward(&q);
    let mut sols = IkSolutions::new();
    m.inverse_all(&target, &mut sols).unwrap();
    let s = sols
        .iter()
        .find(|s| (0..5).all(|j| (s.q[j] - q[j]).abs() < 1e-9))
        .unwrap();
    assert!(s.within_limits);
    // Both -110 and 250 are inside the limits: inverse_all picks the one nearest zero ...
    assert!((s.q[5] - (-110f64).to_radians()).abs() < 1e-9, "{}", s.q[5]);
    // ... and inverse_near the one nearest the seed.
    let near = m.inverse_near(&target, &q).unwrap();
    assert!((near[5] - q[5]).abs() < 1e-9);
    // A joint-1 angle of 200 deg is outside +-160 in every equivalent: that branch is flagged.
    let mut q = m.named_pose(NamedPose::Start);
    q[0] = 200f64.to_radians();
    let target = m.forward(&q);
    m.inverse_all(&target, &mut sols).unwrap();
    assert!(sols.iter().any(|s| !s.within_limits));
    assert!(sols.iter().any(|s| s.within_limits));
}

#[test]
fn wrist_singularity_keeps_the_seed_wrist_angle() {
    let m = model::puma560();
    let q = JointVector::from_column_slice(&[0.2, 0.6, -2.5, 0.7, 0.0, -0.3]);
    let target = m.forward(&q);
    let near = m.inverse_near(&target, &q).unwrap();
    assert!(pose_distance(&m.forward(&near), &target) < 1e-9);
    assert!((near - q).amax() < 1e-9, "{near:?}");
    let mut sols = IkSolutions::new();
    assert_eq!(m.inverse_all(&target, &mut sols), Ok(8));
    for s in &sols {
        assert!(
            pose_distance(&m.forward(&s.q), &target) < 1e-9,
            "{}",
            s.branch
        );
    }
}

#[test]
fn bad_targets_are_typed_errors() {
    let m = model::puma560();
    let mut sols = IkSolutions::new();
    let mut far = m.forward(&m.named_pose(NamedPose::Start));
    far.translation.vector.x = 5.0;
    assert_eq!(
        m.inverse_all(&far, &mut sols),
        Err(KinematicsError::Unreachable)
    );
    assert!(sols.is_empty());
    let mut nan = far;
    nan.translation.vector.y = f64::NAN;
    assert_eq!(
        m.inverse_all(&nan, &mut sols),
        Err(KinematicsError::NonFinite)
    );
    let seed = JointVector::repeat(f64::NAN);
    assert_eq!(
        m.inverse_near(&m.forward(&JointVector::zeros()), &seed),
        Err(KinematicsError::NonFinite)
    );
    // Unreachable for the numerical solver is NoConvergence, in bounded time.
    let arm = model::from_toml_str(OFFSET_ARM).unwrap();
    assert_eq!(
        arm.inverse_all(&far, &mut sols),
        Err(KinematicsError::NoConvergence)
    );
    // Inside the column around the waist axis closer than the shoulder offset.
    let mut inner = m.forward(&JointVector::zeros());
    inner.translation.vector = Vector3::new(0.01, 0.0, 1.0);
    assert_eq!(
        m.inverse_all(&inner, &mut sols),
        Err(KinematicsError::Unreachable)
    );
}

#[test]
fn the_pedestal_is_a_parameter() {
    let with = model::puma560();
    let without = model::puma560_with_pedestal(0.0).unwrap();
    let q = with.named_pose(NamedPose::Work);
    let dz = with.forward(&q).translation.vector - without.forward(&q).translation.vector;
    assert!((dz - Vector3::new(0.0, 0.0, 0.67183)).norm() < 1e-12);
    // Closed form still applies, and reaches the pose.
    let target = without.forward(&q);
    let mut sols = IkSolutions::new();
    assert_eq!(without.inverse_all(&target, &mut sols), Ok(8));
    assert!(puma_branch_reaches(&without, &target, &sols));
    assert!(model::puma560_with_pedestal(f64::NAN).is_err());
}

fn puma_branch_reaches(m: &SerialRobotModel, target: &Pose, sols: &IkSolutions) -> bool {
    sols.iter()
        .all(|s| pose_distance(&m.forward(&s.q), target) < 1e-9)
}

#[test]
fn the_puma200_flange_is_the_tool_transform() {
    let m = model::puma200();
    assert!(m.has_closed_form());
    let tool = m.chain().tool();
    assert!((tool.translation.vector - Vector3::new(0.0, 0.0, 2.5 * 0.0254)).norm() < 1e-15);
    // At zero angles: d1 = 13 in up, a2 + d4 = 8 in forward / 8 + 2.5 in up, lateral -5 in.
    let t = m.forward(&JointVector::zeros());
    let inch = 0.0254;
    let want = Vector3::new(8.0 * inch, 5.0 * inch, (13.0 + 8.0 + 2.5) * inch);
    assert!(
        (t.translation.vector - want).norm() < 1e-12,
        "{:?}",
        t.translation.vector
    );
}
