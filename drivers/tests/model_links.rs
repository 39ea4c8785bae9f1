//! Every link frame of a robot and its URDF description (`link_names`, `link_frames`, `urdf`):
//! the last frame is forward kinematics (DH and URDF robots); a DH robot's generated URDF, read
//! back by our own URDF loader, puts every link where `link_frames` does at random joint
//! angles; a URDF robot's description is its own text and its own link names.

use penelope_drivers::model::{self, SerialRobotModel, UrdfChain, urdf};
use penelope_hal::{JointVector, Kinematics, Pose, RobotModel};
use proptest::prelude::*;

const SCARA: &str = include_str!("../robots/scara.urdf");
const PUMA_URDF: &str = include_str!("../robots/puma560.urdf");

fn dh_models() -> Vec<SerialRobotModel> {
    vec![model::puma560(), model::puma200(), model::frhc()]
}

fn urdf_models() -> Vec<SerialRobotModel> {
    vec![
        urdf::model_from_str(SCARA, &UrdfChain::to_tip("tool")).unwrap(),
        urdf::model_from_str(PUMA_URDF, &UrdfChain::whole()).unwrap(),
    ]
}

/// Largest position difference (m) and rotation angle (rad) between two poses.
fn pose_error(a: &Pose, b: &Pose) -> (f64, f64) {
    (
        (a.translation.vector - b.translation.vector).norm(),
        a.rotation.angle_to(&b.rotation),
    )
}

/// A configuration inside the limits (the middle of an unbounded range is zero), from `u` in
/// [0, 1] per joint.
fn config(m: &SerialRobotModel, u: &[f64; 6]) -> JointVector {
    let l = m.limits();
    let mut q = JointVector::zeros();
    for j in 0..m.joint_count() {
        let lo = l.position_min[j].max(-std::f64::consts::PI);
        let hi = l.position_max[j].min(std::f64::consts::PI);
        q[j] = lo + (hi - lo) * u[j];
    }
    q
}

fn assert_same_frames(a: &[Pose], b: &[Pose], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: frame count");
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        let (dp, dr) = pose_error(x, y);
        assert!(
            dp < 1e-9 && dr < 1e-9,
            "{what}: frame {k} differs by {dp:e} m, {dr:e} rad"
        );
    }
}

#[test]
fn the_last_frame_is_forward_kinematics_and_the_root_is_the_identity() {
    let u = [0.3, 0.7, 0.45, 0.2, 0.9, 0.6];
    for m in dh_models().into_iter().chain(urdf_models()) {
        let names = m.link_names();
        for q in [m.named_pose(penelope_hal::NamedPose::Start), config(&m, &u)] {
            let frames = m.link_frames(&q);
            assert_eq!(frames.len(), names.len(), "{}", m.name());
            let (dp, dr) = pose_error(&frames[0], &Pose::identity());
            assert!(
                dp == 0.0 && dr == 0.0,
                "{}: root is not the identity",
                m.name()
            );
            let (dp, dr) = pose_error(frames.last().unwrap(), &m.forward(&q));
            assert!(
                dp < 1e-12 && dr < 1e-9,
                "{}: last frame is {dp:e} m, {dr:e} rad from forward kinematics",
                m.name()
            );
        }
    }
}

#[test]
fn dh_robots_name_base_link_then_link1_to_linkn_then_tool() {
    for m in dh_models() {
        let n = m.joint_count();
        let mut expected = vec!["base_link".to_string()];
        expected.extend((1..=n).map(|j| format!("link{j}")));
        expected.push("tool".into());
        assert_eq!(m.link_names(), expected, "{}", m.name());
    }
}

#[test]
fn a_dh_frame_turns_with_its_own_joint_only() {
    // linkj's z axis is joint j's axis: turning joint j moves frames j+1.. but not linkj's
    // origin, and leaves frames before it alone.
    let m = model::puma560();
    let q0 = m.named_pose(penelope_hal::NamedPose::Start);
    let before = m.link_frames(&q0);
    for j in 0..m.joint_count() {
        let mut q = q0;
        q[j] += 0.4;
        let after = m.link_frames(&q);
        for k in 0..=j {
            let (dp, dr) = pose_error(&before[k], &after[k]);
            assert!(dp < 1e-12 && dr < 1e-12, "joint {j} moved frame {k}");
        }
        let (dp, _) = pose_error(&before[j + 1], &after[j + 1]);
        assert!(dp < 1e-12, "joint {j} moved the origin of its own link");
        let (_, dr) = pose_error(&before[j + 1], &after[j + 1]);
        assert!((dr - 0.4).abs() < 1e-9, "joint {j} turned its link by {dr}");
    }
}

#[test]
fn a_urdf_robot_describes_itself_with_its_own_text_and_links() {
    let scara = urdf::model_from_str(SCARA, &UrdfChain::to_tip("tool")).unwrap();
    assert_eq!(scara.urdf(), SCARA);
    let names = scara.link_names();
    assert_eq!(names.first().map(String::as_str), Some("base_link"));
    assert_eq!(names.last().map(String::as_str), Some("tool"));
    // Every link of the file, the camera off the chain included, once.
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(
        sorted,
        [
            "base_link",
            "camera",
            "column",
            "forearm",
            "quill",
            "tool",
            "upper_arm"
        ]
    );
    // The camera is fixed to the forearm: it follows the elbow.
    let camera = names.iter().position(|n| n == "camera").unwrap();
    let q = JointVector::from_column_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let mut q2 = q;
    q2[1] = 0.5;
    let (dp, _) = pose_error(
        &scara.link_frames(&q)[camera],
        &scara.link_frames(&q2)[camera],
    );
    assert!(dp > 1e-3, "the camera did not follow the elbow");
}

#[test]
fn the_generated_urdf_is_well_formed_and_names_every_frame() {
    for m in dh_models() {
        let text = m.urdf();
        let robot = urdf::parse(&text).unwrap_or_else(|e| panic!("{}: {e}\n{text}", m.name()));
        let links: Vec<String> = robot.links.iter().map(|l| l.name.clone()).collect();
        assert_eq!(links, m.link_names(), "{}", m.name());
        let moving: Vec<String> = robot
            .joints
            .iter()
            .filter(|j| j.joint_type != urdf_rs_joint_fixed())
            .map(|j| j.name.clone())
            .collect();
        assert_eq!(moving, m.joint_names(), "{}", m.name());
        assert!(
            robot.links.iter().all(|l| !l.visual.is_empty()),
            "{}: a link without geometry",
            m.name()
        );
    }
}

fn urdf_rs_joint_fixed() -> urdf_rs::JointType {
    urdf_rs::JointType::Fixed
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 200,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// A URDF viewer doing forward kinematics on the generated URDF (here: our own URDF loader)
    /// puts every link where `link_frames` does.
    #[test]
    fn the_generated_urdf_read_back_gives_the_same_frames(u in prop::array::uniform6(0.0f64..=1.0)) {
        for m in dh_models() {
            let back = urdf::model_from_str(&m.urdf(), &UrdfChain::whole())
                .unwrap_or_else(|e| panic!("{}: {e}", m.name()));
            prop_assert_eq!(back.link_names(), m.link_names());
            prop_assert_eq!(back.joint_count(), m.joint_count());
            let q = config(&m, &u);
            assert_same_frames(&back.link_frames(&q), &m.link_frames(&q), m.name());
            let (dp, dr) = pose_error(&back.forward(&q), &m.forward(&q));
            prop_assert!(dp < 1e-9 && dr < 1e-9, "{}: forward differs by {dp:e} m, {dr:e} rad", m.name());
            // The limits survive the trip.
            for j in 0..m.joint_count() {
                prop_assert_eq!(back.limits().position_min[j], m.limits().position_min[j]);
                prop_assert_eq!(back.limits().position_max[j], m.limits().position_max[j]);
            }
        }
    }
}
