//! A robot answers `Description` and `LinkFrames` from its model: the URDF, frames and joint
//! names of the model, the contact shapes of the simulated board it is mapped onto, and every
//! link frame at given or measured joints.

mod common;

use common::{call, create, creator, lifecycle, map, session};
use penelope_hal::{JointVector, NamedPose, Transition};
use penelope_protocol::proto::{ContactShapeMsg, Method, PoseMsg, Reply, RobotMethod};

fn assert_poses_match(got: &[PoseMsg], expected: &[penelope_hal::Pose]) {
    assert_eq!(got.len(), expected.len());
    for (k, (g, e)) in got.iter().zip(expected).enumerate() {
        let g = g.to_pose().unwrap();
        let dp = (g.translation.vector - e.translation.vector).norm();
        let dr = g.rotation.angle_to(&e.rotation);
        assert!(dp < 1e-12 && dr < 1e-9, "frame {k}: {dp:e} m, {dr:e} rad");
    }
}

#[test]
fn a_robot_describes_itself_and_gives_every_link_frame() {
    let c = creator();
    let (s, _rx) = session(1);
    create(&c, &s, "robot/puma560", "slave", "");
    create(
        &c,
        &s,
        "board/sim",
        "b",
        "axes = 6\n[[shapes]]\nkind = \"plane\"\npoint = [0.6, 0.0, 0.0]\nnormal = [-2.0, 0.0, 0.0]\n\
         [[shapes]]\nkind = \"sphere\"\npoint = [0.0, 0.5, 0.3]\nradius = 0.1\n",
    );
    map(
        &c,
        &s,
        "slave",
        "b",
        &[(0, 0), (1, 1), (2, 2), (3, 3), (4, 4), (5, 5)],
    );
    // A robot on no simulated board has no contacts; before configure it still describes itself.
    create(&c, &s, "robot/frhc", "master", "");
    let model = penelope_drivers::model::puma560();

    let described =
        |robot: &str| match call(&c, &s, (robot, Method::Robot(RobotMethod::Description))) {
            Ok(Reply::RobotDescription(d)) => d,
            other => panic!("expected a description, got {other:?}"),
        };
    let d = described("slave");
    assert_eq!(d.urdf, model.urdf());
    assert_eq!(d.frames, model.link_names());
    assert_eq!(d.joint_names, model.joint_names());
    assert_eq!(
        d.contacts,
        vec![
            ContactShapeMsg::Plane {
                point: [0.6, 0.0, 0.0],
                normal: [-1.0, 0.0, 0.0],
            },
            ContactShapeMsg::Sphere {
                center: [0.0, 0.5, 0.3],
                radius: 0.1,
            },
        ]
    );
    let master = described("master");
    assert!(master.contacts.is_empty());
    assert_eq!(master.frames, penelope_drivers::model::frhc().link_names());

    // Given joints.
    let q = [0.1, -0.4, 0.3, 0.2, -0.5, 0.7];
    let frames = |q: Option<Vec<f64>>| match call(
        &c,
        &s,
        ("slave", Method::Robot(RobotMethod::LinkFrames { q })),
    ) {
        Ok(Reply::Poses(p)) => p,
        other => panic!("expected poses, got {other:?}"),
    };
    let got = frames(Some(q.to_vec()));
    assert_poses_match(
        &got,
        &model.link_frames(&JointVector::from_column_slice(&q)),
    );
    // A wrong joint count is a bad argument, not a crash.
    assert!(
        call(
            &c,
            &s,
            (
                "slave",
                Method::Robot(RobotMethod::LinkFrames {
                    q: Some(vec![0.0; 2])
                })
            )
        )
        .is_err()
    );

    // Measured: the configured robot stands at its start pose on the simulated board.
    lifecycle(&c, &s, "b", Transition::Configure).unwrap();
    lifecycle(&c, &s, "slave", Transition::Configure).unwrap();
    let got = frames(None);
    assert_poses_match(
        &got,
        &model.link_frames(&model.named_pose(NamedPose::Start)),
    );
}
