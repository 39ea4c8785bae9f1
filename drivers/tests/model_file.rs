//! The DH file format and the robot objects built from it: the built-in files, units, errors for
//! malformed files (never a panic), and the hal `Robot` implementation.

use core::f64::consts::TAU;

use penelope_drivers::model::{self, DhRobot, FileError, ModelError};
use penelope_hal::{JointState, JointVector, Kinematics, NamedPose, Robot, RobotModel};
use proptest::prelude::*;

const SMALL: &str = r#"
name = "two-link"
[units]
length = "mm"
angle = "deg"
[base]
xyz = [100.0, 0.0, 0.0]
rpy = [0.0, 0.0, 90.0]
[[joints]]
a = 300.0
limits = [-90.0, 90.0]
[[joints]]
a = 200.0
[poses]
nest = [0.0, 0.0]
start = [10.0, 20.0]
work = [30.0, -40.0]
"#;

#[test]
fn built_ins_are_found_by_name_and_agree_with_their_files() {
    for name in model::BUILT_IN {
        let m = model::by_name(name).unwrap();
        assert_eq!(m.kind(), name);
        assert_eq!(m.name(), name);
        assert_eq!(m.joint_count(), 6);
        assert!(!m.description().is_empty());
        assert!(m.has_closed_form(), "{name}");
        // A file with the same text gives the same model (kind aside).
        let text = match name {
            "puma560" => model::PUMA560_TOML,
            "puma200" => model::PUMA200_TOML,
            _ => model::FRHC_TOML,
        };
        let from_text = model::from_toml_str(text).unwrap();
        assert_eq!(from_text.kind(), "dh");
        assert_eq!(from_text.chain(), m.chain());
        // Every named pose is inside the limits.
        for (pose, q) in m.poses() {
            assert!(m.limits().contains_position(q, 6), "{name} {pose}");
        }
    }
    assert!(model::by_name("puma 560").is_none());
    // The PUMA 200 and FRHC say what is assumed.
    assert!(!model::puma200().assumptions().is_empty());
    assert!(!model::frhc().assumptions().is_empty());
}

#[test]
fn units_are_converted_to_si() {
    let m = model::from_toml_str(SMALL).unwrap();
    assert_eq!(m.joint_count(), 2);
    // Base at x = 0.1 m, rotated 90 deg about z: the arm stretched along x points along +y.
    let t = m.forward(&JointVector::zeros());
    let p = t.translation.vector;
    assert!(
        (p - nalgebra::Vector3::new(0.1, 0.5, 0.0)).norm() < 1e-12,
        "{p:?}"
    );
    assert!((m.limits().position_max[0] - core::f64::consts::FRAC_PI_2).abs() < 1e-15);
    assert!((m.named_pose(NamedPose::Work)[1] + 40f64.to_radians()).abs() < 1e-15);
    // No limits given: unbounded.
    assert_eq!(m.limits().position_max[1], f64::INFINITY);
    // No dynamics given: massless, no holding torque.
    assert_eq!(
        penelope_hal::Dynamics::gravity(&m, &JointVector::zeros()).amax(),
        0.0
    );
}

#[test]
fn loading_from_a_path() {
    let dir = std::env::temp_dir().join(format!("penelope-model-file-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("arm.toml");
    std::fs::write(&path, SMALL).unwrap();
    let m = model::load(path.to_str().unwrap()).unwrap();
    assert_eq!(m.name(), "two-link");
    assert_eq!(m.kind(), "dh");
    let missing = model::load(dir.join("nope.toml").to_str().unwrap());
    assert!(matches!(missing, Err(FileError::Io { .. })));
    std::fs::remove_dir_all(&dir).unwrap();
}

fn error_of(text: &str) -> String {
    match model::from_toml_str(text) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn malformed_files_are_clear_errors() {
    // A typo in a key.
    let e = error_of(&SMALL.replace("limits = [-90.0, 90.0]", "limit = [-90.0, 90.0]"));
    assert!(e.contains("limit"), "{e}");
    // A missing named pose.
    let e = error_of(&SMALL.replace("work = [30.0, -40.0]", ""));
    assert!(e.contains("work"), "{e}");
    // A pose of the wrong length.
    let e = error_of(&SMALL.replace("work = [30.0, -40.0]", "work = [30.0]"));
    assert!(e.contains("work") && e.contains("2 joints"), "{e}");
    // Limits the wrong way round.
    let e = error_of(&SMALL.replace("[-90.0, 90.0]", "[90.0, -90.0]"));
    assert!(e.contains("joint 1"), "{e}");
    // NaN in the table.
    let e = error_of(&SMALL.replace("a = 200.0", "a = nan"));
    assert!(e.contains("non-finite"), "{e}");
    // Bad inertia length, negative mass.
    let e = error_of(&SMALL.replace(
        "a = 200.0",
        "a = 200.0\n[joints.dynamics]\nmass = 1.0\ninertia = [1.0, 2.0]",
    ));
    assert!(e.contains("inertia"), "{e}");
    let e = error_of(&SMALL.replace("a = 200.0", "a = 200.0\n[joints.dynamics]\nmass = -1.0"));
    assert!(e.contains("mass"), "{e}");
    // Too many joints.
    let mut seven = SMALL.to_string();
    for _ in 0..5 {
        seven = seven.replacen("[poses]", "[[joints]]\na = 0.1\n[poses]", 1);
    }
    let e = error_of(&seven);
    assert!(e.contains("1 to 6"), "{e}");
    // Not TOML at all.
    assert!(matches!(
        model::from_toml_str("name = "),
        Err(FileError::Parse(_))
    ));
    // Zero encoder counts.
    let e = error_of(&SMALL.replace("a = 200.0", "a = 200.0\nencoder_counts_per_rev = 0"));
    assert!(e.contains("counts"), "{e}");
}

#[test]
fn a_spec_with_mismatched_lists_is_rejected() {
    let mut spec = model::RobotFile::parse(SMALL).unwrap().to_spec().unwrap();
    spec.dynamics.pop();
    assert!(matches!(
        model::SerialRobotModel::new("dh", spec),
        Err(ModelError::Length {
            what: "dynamics",
            expected: 2,
            got: 1
        })
    ));
}

#[test]
fn robot_scales_encoder_counts_and_keeps_its_state() {
    let mut r = DhRobot::new(model::puma560());
    assert_eq!(r.kind(), "puma560");
    // 1000 counts per motor turn through a -62.6111 gear.
    let cpr = 1000.0 * -62.6111 / TAU;
    assert!((r.counts_per_radian(0) - cpr).abs() < 1e-9);
    assert!((r.counts_to_radians(0, 9965) - 9965.0 / cpr).abs() < 1e-15);
    for j in 0..6 {
        let rad = 0.123 * (j as f64 + 1.0);
        let counts = r.radians_to_counts(j, rad);
        assert!((r.counts_to_radians(j, counts) - rad).abs() <= 0.5 / r.counts_per_radian(j).abs());
    }
    // Starts at rest at `start`; stores what it is given.
    assert_eq!(r.joint_state().position, r.named_pose(NamedPose::Start));
    let state = JointState::at_rest(r.named_pose(NamedPose::Work));
    r.set_joint_state(state);
    assert_eq!(r.joint_state(), &state);
    assert_eq!(r.limits(), r.model().limits());
    assert_eq!(DhRobot::new(model::frhc()).kind(), "frhc");
    let nest = r.named_pose(NamedPose::Nest);
    assert_eq!(Some(nest), r.model().pose("nest"));
    assert!(r.model().pose("qn").is_some());
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 300,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Arbitrary text never panics the loader.
    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,200}") {
        let _ = model::from_toml_str(&text);
    }

    /// Arbitrary numbers in a valid file give a model or an error, never a panic, and a model
    /// always computes finite kinematics and dynamics at its start pose.
    #[test]
    fn arbitrary_numbers_never_panic(
        a in prop::num::f64::ANY,
        d in prop::num::f64::ANY,
        m in prop::num::f64::ANY,
        lo in -400.0..400.0f64,
    ) {
        let text = format!(
            "name = \"x\"\n[[joints]]\na = {a:?}\nd = {d:?}\nlimits = [{lo:?}, 400.0]\n[joints.dynamics]\nmass = {m:?}\n[poses]\nnest = [0.0]\nstart = [0.0]\nwork = [0.0]\n"
        ).replace("NaN", "nan");
        if let Ok(model) = model::from_toml_str(&text) {
            let q = model.named_pose(NamedPose::Start);
            let t = model.forward(&q);
            prop_assert!(t.translation.vector.iter().all(|x| x.is_finite()));
            let _ = penelope_hal::Dynamics::gravity(&model, &q);
        }
    }
}
