//! The PUMA 560 model against Corke's Robotics Toolbox for Python, version 1.5.0
//! (`roboticstoolbox.models.DH.Puma560`).
//!
//! Every number below was printed by that toolbox (numpy 2.4, Python 3.11) in a run of
//! `scripts/bench-kinematics --reference`, which installs it into `target/rtb-venv` (the exact
//! Python calls are in `scripts/bench_kinematics.py`): `fkine(qn)`, `fkine(q)`, `jacob0(q)`,
//! `jacobe(q)`, `gravload(qn)`, `gravload(q)`, `inertia(qn)`, `inertia(q)`,
//! `nofriction(True, True).rne(q, qd, qdd)`, `friction(qd)` and `ikine_a(fkine(q), config)` for
//! the eight configurations, with `q = [0.3, -0.4, 0.7, -1.1, 0.9, 0.5]`,
//! `qd = [0.2, -0.5, 0.3, 1.0, -0.7, 0.4]`, `qdd = [1.0, 0.5, -0.8, 0.3, 0.2, -1.5]` and
//! `qn = [0, pi/4, -pi, 0, pi/4, 0]`.

// The numbers are quoted verbatim as the toolbox printed them (17 significant digits).
#![allow(clippy::excessive_precision)]

use penelope_drivers::model;
use penelope_hal::{
    Dynamics, IkSolutions, InverseKinematics, JacobianFrame, JointVector, Kinematics,
};

const Q: [f64; 6] = [0.3, -0.4, 0.7, -1.1, 0.9, 0.5];
const QD: [f64; 6] = [0.2, -0.5, 0.3, 1.0, -0.7, 0.4];
const QDD: [f64; 6] = [1.0, 0.5, -0.8, 0.3, 0.2, -1.5];

fn qn() -> JointVector {
    use core::f64::consts::PI;
    JointVector::from_column_slice(&[0.0, PI / 4.0, -PI, 0.0, PI / 4.0, 0.0])
}

fn v(x: [f64; 6]) -> JointVector {
    JointVector::from_column_slice(&x)
}

fn assert_close(what: &str, got: &[f64], want: &[f64], tol: f64) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= tol,
            "{what}[{i}]: got {g}, toolbox {w} (tolerance {tol})"
        );
    }
}

/// Row-major flattening of a matrix.
fn rows<const R: usize, const C: usize>(m: &nalgebra::SMatrix<f64, R, C>) -> Vec<f64> {
    (0..R)
        .flat_map(|r| (0..C).map(move |c| m[(r, c)]))
        .collect()
}

#[test]
fn forward_kinematics_matches_the_toolbox() {
    let p = model::puma560();
    let t = p.forward_matrix(&qn());
    #[rustfmt::skip]
    let want_qn = [
        -1.0146536357569526e-17, 6.1232339957367660e-17, 1.0, 5.9630314857461564e-01,
        -6.1232339957367660e-17, 1.0, -6.1232339957367673e-17, -1.5005000000000002e-01,
        -1.0, -6.1232339957367660e-17, 1.0146536357569529e-17, 6.5747573234191292e-01,
        0.0, 0.0, 0.0, 1.0,
    ];
    assert_close("fkine(qn)", &rows(&t), &want_qn, 1e-12);
    #[rustfmt::skip]
    let want_q = [
        0.5011159012783651, 0.5003309157956538, -0.70608202652741, 0.320914481013126,
        -0.12624945729978512, 0.8494595683724846, 0.5123275477972483, -0.057794595808770735,
        0.8561214446662821, -0.1675930082059347, 0.48884420379401433, 0.9221925159907867,
        0.0, 0.0, 0.0, 1.0,
    ];
    assert_close("fkine(q)", &rows(&p.forward_matrix(&v(Q))), &want_q, 1e-12);
    // The quaternion pose agrees with the matrix.
    let pose = p.forward(&v(Q));
    assert_close("pose", &rows(&pose.to_homogeneous()), &want_q, 1e-12);
}

#[test]
fn jacobians_match_the_toolbox() {
    let p = model::puma560();
    #[rustfmt::skip]
    let j0 = [
        5.7794595808770721e-02, -2.3918044703529148e-01, -3.9982108036395925e-01, 0.0, 0.0, 0.0,
        3.2091448101312592e-01, -7.3987182465850149e-02, -1.2367915351465500e-01, 0.0, 0.0, 0.0,
        -2.2463541287781516e-18, 2.8950184270332918e-01, -1.0821229450711665e-01, 0.0, 0.0, 0.0,
        2.5133573377939225e-16, 2.9552020666133949e-01, 2.9552020666133949e-01, -2.8232123669751741e-01, -6.7932944775041704e-01, -7.0608202652741003e-01,
        5.2363546085697731e-18, -9.5533648912560609e-01, -9.5533648912560609e-01, -8.7332192545160808e-02, -6.8494369017017753e-01, 5.1232754779724832e-01,
        1.0000000000000002e+00, 1.6671130314612305e-16, 1.6671130314612305e-16, 9.5533648912560620e-01, -2.6336978322346222e-01, 4.8884420379401433e-01,
    ];
    assert_close(
        "jacob0(q)",
        &rows(&p.jacobian(&v(Q), JacobianFrame::Base)),
        &j0,
        1e-12,
    );
    #[rustfmt::skip]
    let je = [
        -1.1553488099818415e-02, 1.3733245215792628e-01, -2.7738514093023886e-01, 0.0, 0.0, 0.0,
        3.0152029957493182e-01, -2.3103697688793087e-01, -2.8696766369282628e-01, 0.0, 0.0, 0.0,
        1.2360560377909208e-01, 2.7249664078046287e-01, 1.6604328828890544e-01, 0.0, 0.0, 0.0,
        8.5612144466628193e-01, 2.6870058799785584e-01, 2.6870058799785584e-01, 6.8743403614855536e-01, -4.7942553860420301e-01, 0.0,
        -1.6759300820593465e-01, -6.6366182606813340e-01, -6.6366182606813340e-01, -3.7554692555132207e-01, -8.7758256189037276e-01, 0.0,
        4.8884420379401428e-01, -6.9810670719419210e-01, -6.9810670719419210e-01, 6.2160996827066439e-01, 6.1232339957367660e-17, 1.0,
    ];
    assert_close(
        "jacobe(q)",
        &rows(&p.jacobian(&v(Q), JacobianFrame::Tool)),
        &je,
        1e-12,
    );
}

#[test]
fn gravity_load_matches_the_toolbox() {
    let p = model::puma560();
    let want_qn = [
        -1.6153297672624904e-15,
        3.1639880378357120e+01,
        6.0351380230105125e+00,
        8.3476125765386017e-18,
        2.8252800000000002e-02,
        0.0,
    ];
    assert_close("gravload(qn)", p.gravity(&qn()).as_slice(), &want_qn, 1e-10);
    let want_q = [
        1.9798442485613602e-15,
        3.2333310305302803e+01,
        -2.3609826434403018e+00,
        -5.8286836872703425e-03,
        -2.3496882398362878e-02,
        0.0,
    ];
    assert_close("gravload(q)", p.gravity(&v(Q)).as_slice(), &want_q, 1e-10);
}

#[test]
fn inertia_matches_the_toolbox() {
    let p = model::puma560();
    #[rustfmt::skip]
    let m_qn = [
        3.6593754121527899e+00, -4.0436124604151863e-01, 1.0061364777978392e-01, -2.5169558280306028e-03, 0.0, 0.0,
        -4.0436124604151868e-01, 4.4137419336357899e+00, 3.5089066495641474e-01, 0.0, 2.3595130678948930e-03, 0.0,
        1.0061364777978390e-01, 3.5089066495641474e-01, 9.3784157521503952e-01, 0.0, 1.4801663885198014e-03, 0.0,
        -2.5169558280306102e-03, 0.0, 0.0, 1.9253170612368001e-01, 0.0, 2.8284271247461906e-05,
        0.0, 2.3595130678948925e-03, 1.4801663885198012e-03, 0.0, 1.7134845165700002e-01, 0.0,
        0.0, 0.0, 0.0, 2.8284271247461906e-05, 0.0, 1.9410450566800005e-01,
    ];
    assert_close("inertia(qn)", &rows(&p.inertia(&qn())), &m_qn, 1e-12);
    #[rustfmt::skip]
    let m_q = [
        3.5317495697235932e+00, 1.1390230351191064e-01, -1.3273455412895302e-01, 1.1139952746800266e-03, 2.7639799452777779e-04, 1.9553768151760570e-05,
        1.1390230351191072e-01, 3.9527481339476571e+00, 1.2021903568750043e-01, 3.9660130565767886e-04, -3.7482122042432968e-04, -2.7924268287767686e-05,
        -1.3273455412895302e-01, 1.2021903568750035e-01, 9.3749211636534358e-01, 9.5588168117140520e-04, 5.9612564466892813e-04, -2.7924268287767686e-05,
        1.1139952746800257e-03, 3.9660130565767545e-04, 9.5588168117140108e-04, 1.9255467171141158e-01, 0.0, 2.4864398730826579e-05,
        2.7639799452777784e-04, -3.7482122042432973e-04, 5.9612564466892824e-04, 0.0, 1.7134845165700002e-01, 0.0,
        1.9553768151760581e-05, -2.7924268287767682e-05, -2.7924268287767682e-05, 2.4864398730826579e-05, 0.0, 1.9410450566800005e-01,
    ];
    assert_close("inertia(q)", &rows(&p.inertia(&v(Q))), &m_q, 1e-12);
}

#[test]
fn newton_euler_and_friction_match_the_toolbox() {
    let p = model::puma560();
    let want = [
        3.4504370795158419e+00,
        3.4378621787277410e+01,
        -3.1000601143275470e+00,
        5.2416970763978818e-02,
        1.0137653130805110e-02,
        -2.9110153588076937e-01,
    ];
    let tau = p.inverse_dynamics(&v(Q), &v(QD), &v(QDD));
    assert_close("rne(q, qd, qdd)", tau.as_slice(), &want, 1e-10);
    let want_f = [
        -25.891748853590162,
        12.403299320912499,
        -8.28335939711166,
        -1.263252909697152,
        1.34198161465478,
        -0.39000586130928,
    ];
    assert_close(
        "friction(qd)",
        p.friction(&v(QD)).as_slice(),
        &want_f,
        1e-10,
    );
}

#[test]
fn closed_form_branches_match_the_toolbox_ikine_a() {
    // ikine_a(fkine(q), config) for each configuration (l/r, u/d, n/f).
    #[rustfmt::skip]
    let toolbox: [(&str, [f64; 6]); 8] = [
        ("left-up-noflip", [2.485225746994196, 1.3155399799169487, 0.6999999999999997, 0.36155783731978164, -3.0708357797286734, -2.5735306895577037]),
        ("left-up-flip", [2.485225746994196, 1.3155399799169487, 0.6999999999999997, -2.7800348162700117, 3.0708357797286734, 0.5680619640320892]),
        ("left-down-noflip", [2.485225746994196, -2.7415926535897928, 2.5355484862859594, 0.033174603930660115, -0.8540850790974407, -2.9560576056610093]),
        ("left-down-flip", [2.485225746994196, -2.7415926535897928, 2.5355484862859594, -3.108418049659133, 0.8540850790974406, 0.1855350479287839]),
        ("right-up-noflip", [0.2999999999999998, 1.8260526736728444, 2.5355484862859594, 1.951377300846576, -2.2906436815765248, 1.73154435920995]),
        ("right-up-flip", [0.2999999999999998, 1.8260526736728444, 2.5355484862859594, -1.190215352743217, 2.2906436815765248, -1.4100482943798431]),
        ("right-down-noflip", [0.2999999999999998, -0.39999999999999947, 0.6999999999999997, 2.041592653589793, -0.8999999999999998, -2.6415926535897927]),
        ("right-down-flip", [0.2999999999999998, -0.39999999999999947, 0.6999999999999997, -1.1000000000000003, 0.8999999999999997, 0.5000000000000007]),
    ];
    let p = model::puma560();
    let target = p.forward(&v(Q));
    let mut sols = IkSolutions::new();
    assert_eq!(p.inverse_all(&target, &mut sols), Ok(8));
    for (name, want) in toolbox {
        let s = sols
            .iter()
            .find(|s| s.branch == name)
            .unwrap_or_else(|| panic!("branch {name} missing"));
        // Ours are the 2π-equivalents inside the limits; compare modulo 2π.
        for (j, w) in want.iter().enumerate() {
            let d = (s.q[j] - w).rem_euclid(core::f64::consts::TAU);
            let d = d.min(core::f64::consts::TAU - d);
            assert!(
                d < 1e-9,
                "{name} joint {}: got {}, toolbox {w}",
                j + 1,
                s.q[j]
            );
        }
    }
}
