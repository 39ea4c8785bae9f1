//! The control path of robots built from URDF allocates nothing: `robot/urdf` objects (the
//! SCARA with its prismatic quill, following a joint spline under a PID with gravity
//! compensation and acceleration feed-forward; the PUMA 560's URDF, following a square of tool
//! waypoints through the communication task's numerical inverse kinematics, with gains soft
//! enough for its rotor-less wrist), built by the
//! creator exactly as `activate` builds them and stepped on a simulated clock for 20,000
//! control ticks each, with a counting allocator around the ticks.
//!
//! The counting allocator counts the allocations of this test's thread (where the loops are
//! stepped); this binary holds this one test only.

use penelope_hal::{Timestamp, Transition};
use penelope_protocol::proto::{ControllerMethod, JointAxis, Method, Reply, RobotMethod};
use penelope_rt_core::safety::SafetyState;
use penelope_runtime::objects::{Creator, CreatorConfig, DetachedLoop};
use penelope_testkit::alloc::{CountingAllocator, allocations};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

fn call(c: &Creator, object: &str, method: Method) -> Reply {
    c.call_object(object, method)
        .unwrap_or_else(|e| panic!("{object}: {e}"))
}

fn urdf(file: &str) -> String {
    format!("{}/../drivers/robots/{file}", env!("CARGO_MANIFEST_DIR"))
}

/// A creator with `robot/urdf` `arm` (configuration `config`) on a simulated board of `axes`
/// axes, configured, the spline `path` (its `waypoints` text) and the controller `ctl` of
/// `law` following it.
fn urdf_loop(
    config: &str,
    axes: u8,
    waypoints: impl Fn(&Creator) -> String,
    law: &str,
) -> DetachedLoop {
    let mut cc = CreatorConfig::new("urdf-alloc");
    cc.rt.priority = None;
    cc.robot_files = vec![format!("{}/../drivers/robots", env!("CARGO_MANIFEST_DIR")).into()];
    let c = Creator::new(cc);
    c.create("robot/urdf", "arm", config).unwrap();
    c.create("board/sim", "sim", &format!("axes = {axes}"))
        .unwrap();
    call(
        &c,
        "arm",
        Method::Robot(RobotMethod::MapJoints {
            board: "sim".into(),
            joints: (0..axes).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    call(&c, "sim", Method::Transition(Transition::Configure));
    call(&c, "arm", Method::Transition(Transition::Configure));
    c.create("trajectory/spline", "path", &waypoints(&c))
        .unwrap();
    call(&c, "path", Method::Transition(Transition::Configure));
    c.create("controller/joint-pid", "ctl", law).unwrap();
    for m in [
        ControllerMethod::SetRobot {
            robot: "arm".into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: "path".into(),
        },
    ] {
        call(&c, "ctl", Method::Controller(m));
    }
    call(&c, "ctl", Method::Transition(Transition::Configure));
    c.detach_loop("ctl").expect("the loop builds")
}

#[test]
fn twenty_thousand_ticks_of_urdf_robots_allocate_nothing() {
    // The SCARA along a joint spline: every joint moves, the quill up and down.
    let scara = urdf_loop(
        &format!("file = {:?}\ntip = \"tool\"", urdf("scara.urdf")),
        3,
        |_| {
            "[[waypoints]]\nat_s = 3.0\nq = [0.6, -0.8, 0.15]\n\
             [[waypoints]]\nat_s = 6.0\nq = [-0.4, 0.9, 0.05]\n\
             [[waypoints]]\nat_s = 9.0\nq = [0.2, 0.3, 0.12]\n\
             [[waypoints]]\nat_s = 12.0\nq = [0.0, 0.0, 0.1]\n"
                .into()
        },
        "acceleration_feedforward = true",
    );
    run_counted(scara);

    // The PUMA's URDF along tool waypoints from its start pose (the zero configuration, a wrist
    // singularity): numerical inverse kinematics in the communication task, gravity
    // compensation on the URDF's inertials.
    let puma = urdf_loop(
        &format!("file = {:?}", urdf("puma560.urdf")),
        6,
        |c| {
            let p = match call(
                c,
                "arm",
                Method::Robot(RobotMethod::ForwardKinematics { q: None }),
            ) {
                Reply::Pose(p) => p.position,
                other => panic!("fk answered {other:?}"),
            };
            let mut w = String::new();
            for (i, (dy, dz)) in [(0.03, 0.0), (0.03, -0.03), (0.0, -0.03), (0.0, 0.0)]
                .iter()
                .cycle()
                .take(8)
                .enumerate()
            {
                w.push_str(&format!(
                    "[[waypoints]]\nat_s = {}\nposition = [{}, {}, {}]\n",
                    2 + 2 * i,
                    p[0],
                    p[1] + dy,
                    p[2] + dz
                ));
            }
            w
        },
        // URDF has no rotor inertia: the bare wrist (1e-4 kg·m² at the flange) needs far softer
        // gains than the defaults scaled from the torque limits, which suit the DH model's
        // reflected rotor inertia.
        "kp = [2000.0, 2000.0, 1000.0, 5.0, 5.0, 1.0]\nkd = [100.0, 100.0, 50.0, 0.1, 0.1, 0.02]",
    );
    run_counted(puma);
}

/// Steps a detached loop 1,000 ticks, then counts allocations over 20,000 more; checks that it
/// ran without a fault and published references.
fn run_counted(mut d: DetachedLoop) {
    let mut step = |i: u64| {
        let now = Timestamp::from_nanos((i + 1) * 1_000_000);
        if i.is_multiple_of(2) {
            d.comm.tick(now);
        }
        d.control.tick(now);
        while d.telemetry.pop().is_some() {}
    };
    for i in 0..1000 {
        step(i);
    }
    let before = allocations();
    for i in 1000..21_000 {
        step(i);
    }
    let after = allocations();
    assert_eq!(
        after - before,
        0,
        "allocated or freed {} times",
        after - before
    );
    let last = *d.control.control_loop().last_sample();
    assert_eq!(last.state, SafetyState::Running, "fault: {:?}", last.fault);
    assert_eq!(d.comm.ik_failures(), 0);
    assert!(d.comm.published() > 9_000);
}
