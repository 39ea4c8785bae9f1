//! Dynamics of the DH models, each algorithm against another: gravity (composite masses)
//! against the static part of recursive Newton-Euler, the inertia matrix (composite rigid body)
//! against Newton-Euler column by column, symmetry and positive definiteness, and the
//! skew-symmetry of `Mdot - 2C` (energy conservation) for the velocity terms.

use nalgebra::Vector3;
use penelope_drivers::model::{self, SerialRobotModel};
use penelope_hal::{Dynamics, JointVector, Kinematics, RobotModel};
use proptest::prelude::*;

/// A Stanford-type arm (prismatic third joint) with masses, so the prismatic branches of the
/// dynamics are exercised. Masses after the Robotics Toolbox's Stanford model, rounded.
const STANFORD: &str = r#"
name = "stanford"
[units]
angle = "deg"
[[joints]]
d = 0.412
alpha = -90.0
limits = [-170.0, 170.0]
gear_ratio = 20
[joints.dynamics]
mass = 9.29
com = [0.0, 0.0175, -0.1105]
inertia = [0.276, 0.255, 0.071]
motor_inertia = 1e-4
[[joints]]
d = 0.154
alpha = 90.0
limits = [-170.0, 170.0]
gear_ratio = 20
[joints.dynamics]
mass = 5.01
com = [0.0, -0.1054, 0.0]
inertia = [0.108, 0.018, 0.1, 0.001, 0.002, 0.003]
motor_inertia = 1e-4
[[joints]]
type = "prismatic"
theta = -90.0
a = 0.0203
limits = [0.3, 0.8]
gear_ratio = 200
[joints.dynamics]
mass = 4.25
com = [0.0, 0.0, -0.6447]
inertia = [2.51, 2.51, 0.006]
motor_inertia = 1e-6
[[joints]]
alpha = -90.0
limits = [-170.0, 170.0]
[joints.dynamics]
mass = 1.08
com = [0.0, 0.092, -0.054]
inertia = [0.002, 0.001, 0.001]
[[joints]]
alpha = 90.0
limits = [-90.0, 90.0]
[joints.dynamics]
mass = 0.63
com = [0.0, 0.0, 0.0566]
inertia = [0.003, 0.003, 0.0004]
[[joints]]
d = 0.263
limits = [-170.0, 170.0]
[joints.dynamics]
mass = 0.51
com = [0.0, 0.0, 0.1554]
inertia = [0.013, 0.013, 0.0003]
[poses]
nest = [0.0, 0.0, 0.3, 0.0, 0.0, 0.0]
start = [0.0, 45.0, 0.5, 0.0, 30.0, 0.0]
work = [20.0, 60.0, 0.6, 10.0, 40.0, 20.0]
"#;

fn stanford() -> SerialRobotModel {
    model::from_toml_str(STANFORD).unwrap()
}

fn models() -> Vec<SerialRobotModel> {
    vec![
        model::puma560(),
        model::puma200(),
        model::frhc(),
        stanford(),
    ]
}

fn config(m: &SerialRobotModel, u: &[f64; 6]) -> JointVector {
    let l = m.limits();
    let mut q = JointVector::zeros();
    for j in 0..m.joint_count() {
        q[j] = l.position_min[j] + (0.02 + 0.96 * u[j]) * (l.position_max[j] - l.position_min[j]);
    }
    q
}

fn vec6(u: &[f64; 6], scale: f64) -> JointVector {
    JointVector::from_iterator(u.iter().map(|x| scale * (2.0 * x - 1.0)))
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
    fn gravity_is_the_static_part_of_newton_euler(u in unit6()) {
        for m in models() {
            let q = config(&m, &u);
            let z = JointVector::zeros();
            let g = m.gravity(&q);
            let rne = m.inverse_dynamics(&q, &z, &z);
            prop_assert!((g - rne).amax() < 1e-10, "{}: {g:?} vs {rne:?}", m.name());
            // No gravity, no holding torque.
            prop_assert!(m.gravity_with(&q, &Vector3::zeros()).amax() == 0.0);
        }
    }

    #[test]
    fn inertia_is_spd_and_matches_newton_euler_columns(u in unit6()) {
        for m in models() {
            let q = config(&m, &u);
            let mm = m.inertia(&q);
            prop_assert!((mm - mm.transpose()).amax() < 1e-12, "{}: not symmetric", m.name());
            prop_assert!(mm.cholesky().is_some(), "{}: not positive definite", m.name());
            let z = JointVector::zeros();
            let g0 = Vector3::zeros();
            for j in 0..m.joint_count() {
                let mut e = JointVector::zeros();
                e[j] = 1.0;
                let col = m.inverse_dynamics_with(&q, &z, &e, &g0);
                let err = (col - mm.column(j)).amax();
                prop_assert!(err < 1e-10, "{} column {j}: {err}", m.name());
            }
            // Unused joints hold the identity (the matrix stays invertible).
            for j in m.joint_count()..6 {
                prop_assert_eq!(mm[(j, j)], 1.0);
            }
        }
    }

    #[test]
    fn newton_euler_splits_into_m_qdd_plus_c_plus_g(u in unit6(), v in unit6(), w in unit6()) {
        for m in models() {
            let q = config(&m, &u);
            let qd = vec6(&v, 2.0);
            let qdd = vec6(&w, 3.0);
            let z = JointVector::zeros();
            let tau = m.inverse_dynamics(&q, &qd, &qdd);
            let c = m.inverse_dynamics_with(&q, &qd, &z, &Vector3::zeros());
            let want = m.inertia(&q) * qdd + c + m.gravity(&q);
            prop_assert!((tau - want).amax() < 1e-9, "{}", m.name());
            // Energy: qd' C qd = qd' Mdot qd / 2, with Mdot by central differences along qd.
            let h = 1e-6;
            let mdot = (m.inertia(&(q + qd * h)) - m.inertia(&(q - qd * h))) / (2.0 * h);
            let lhs = qd.dot(&c);
            let rhs = 0.5 * qd.dot(&(mdot * qd));
            prop_assert!((lhs - rhs).abs() < 1e-5 * (1.0 + rhs.abs()), "{}: {lhs} vs {rhs}", m.name());
        }
    }
}

#[test]
fn reflected_motor_inertia_is_on_the_diagonal() {
    let m = model::puma560();
    let q = m.named_pose(penelope_hal::NamedPose::Start);
    let mm = m.inertia(&q);
    // The same arm with motor inertia removed differs only on the diagonal, by Jm G².
    let text = model::PUMA560_TOML
        .replace("motor_inertia = 200e-6", "motor_inertia = 0.0")
        .replace("motor_inertia = 33e-6", "motor_inertia = 0.0");
    let bare = model::from_toml_str(&text).unwrap();
    let diff = mm - bare.inertia(&q);
    for i in 0..6 {
        for j in 0..6 {
            let want = if i == j {
                m.link_dynamics(i).unwrap().reflected_motor_inertia()
            } else {
                0.0
            };
            assert!((diff[(i, j)] - want).abs() < 1e-12, "({i}, {j})");
        }
    }
    // Joint 1 of the PUMA 560: Jm G² = 200e-6 * 62.6111² = 0.784 kg·m².
    assert!((diff[(0, 0)] - 200e-6 * 62.6111f64.powi(2)).abs() < 1e-12);
}

#[test]
fn holding_torque_opposes_gravity() {
    // The PUMA 560 with the upper arm horizontal forward: gravity pulls the arm down (negative
    // about joint 2's axis), so the holding torque on joint 2 is positive.
    let m = model::puma560();
    let q =
        JointVector::from_column_slice(&[0.0, 0.0, -core::f64::consts::FRAC_PI_2, 0.0, 0.0, 0.0]);
    assert!(m.gravity(&q)[1] > 20.0);
    // Flipping gravity flips the torque.
    let up = m.gravity_with(&q, &Vector3::new(0.0, 0.0, 9.81));
    assert!((up + m.gravity(&q)).amax() < 1e-12);
}

#[test]
fn the_frhc_holding_limits_cover_its_own_weight() {
    // The assumed link masses must leave the documented force-reflection budget usable: holding
    // the FRHC's own weight at home takes well under its effort limits.
    let m = model::frhc();
    let home = m.named_pose(penelope_hal::NamedPose::Start);
    let g = m.gravity(&home);
    for j in 0..6 {
        assert!(
            g[j].abs() < 0.5 * m.limits().effort_max[j],
            "joint {}: {}",
            j + 1,
            g[j]
        );
    }
}
