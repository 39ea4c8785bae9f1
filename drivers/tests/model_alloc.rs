//! Kinematics and dynamics calls allocate nothing: a counting global allocator around every
//! real-time call of every built-in model, a numerical one, and two URDF robots (the PUMA 560's
//! URDF and the SCARA with its prismatic quill and fixed tool).

use penelope_testkit::alloc::{CountingAllocator, allocations};

use penelope_drivers::model;
use penelope_hal::{
    Dynamics, IkSolutions, InverseKinematics, JacobianFrame, JointVector, Kinematics, NamedPose,
    RobotModel, Wrench,
};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

const NUMERICAL_FRHC: &str = "inverse_kinematics = \"numerical\"";

#[test]
fn no_call_allocates() {
    let frhc_text = model::FRHC_TOML.replace("inverse_kinematics = \"auto\"", NUMERICAL_FRHC);
    let models = [
        model::puma560(),
        model::puma200(),
        model::frhc(),
        model::from_toml_str(&frhc_text).unwrap(),
        model::urdf::model_from_str(
            include_str!("../robots/puma560.urdf"),
            &model::UrdfChain::whole(),
        )
        .unwrap(),
        model::urdf::model_from_str(
            include_str!("../robots/scara.urdf"),
            &model::UrdfChain::to_tip("tool"),
        )
        .unwrap(),
    ];
    assert_eq!(models[4].kind(), "urdf");
    // The counter does see this thread's allocations.
    let before = allocations();
    let probe = std::hint::black_box(vec![1.0_f64; 4]);
    assert!(allocations() > before);
    let mut sink = probe[0];
    let mut sols = IkSolutions::new();
    let qd = JointVector::from_column_slice(&[0.1, -0.2, 0.3, -0.4, 0.5, -0.6]);
    for m in &models {
        // Away from the named poses (a URDF's are all one configuration), inside the limits.
        let mut q = m.named_pose(NamedPose::Work);
        for j in 0..m.joint_count() {
            q[j] += 0.05;
        }
        let seed = m.named_pose(NamedPose::Start);
        let target = m.forward(&q);
        let before = allocations();
        for _ in 0..10 {
            sink += m.forward(&q).translation.vector.x;
            sink += m.jacobian(&q, JacobianFrame::Base)[(0, 0)];
            sink += m.jacobian(&q, JacobianFrame::Tool)[(0, 0)];
            sink += m.forward_and_jacobian(&q, JacobianFrame::Base).1[(1, 1)];
            sink += m.forward_matrix(&q)[(0, 3)];
            sink += m.inverse_all(&target, &mut sols).unwrap() as f64;
            sink += m.inverse_near(&target, &seed).unwrap()[0];
            sink += m.inverse_numerical(&target, &seed).unwrap()[0];
            sink += m.gravity(&q)[1];
            sink += m.inertia(&q)[(1, 1)];
            sink += m.inverse_dynamics(&q, &qd, &qd)[2];
            sink += m.friction(&qd)[0];
            sink += m
                .wrench_to_torques(&q, &Wrench::zero(penelope_hal::Frame::Base))
                .unwrap()[0];
            sink += m.jacobian_damped_inverse(&q, 0.01)[(0, 0)];
        }
        let after = allocations();
        assert_eq!(
            after - before,
            0,
            "{} allocated {} times",
            m.name(),
            after - before
        );
    }
    assert!(sink.is_finite());
}
