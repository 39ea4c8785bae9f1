//! Trajectories: continuity, endpoint exactness, limits, and feed-forward = derivative.

use core::time::Duration;

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use penelope_hal::{
    CartesianReference, Frame, JointReference, JointVector, Pose, Reference, Timestamp, Trajectory,
    TrajectoryError, Twist, Wrench,
};
use penelope_rt_core::trajectory::{
    CartesianLimits, CubicSpline, Goal, Ramp, SplineEnds, Step, TrajectoryConfigError, Trapezoidal,
    Waypoint,
};

const T0: Timestamp = Timestamp::from_nanos(5_000_000_000);
const DT: f64 = 1e-3;

fn at(t: f64) -> Timestamp {
    T0 + Duration::from_secs_f64(t)
}

fn joint_from(q: JointVector) -> Reference {
    Reference::Joint(JointReference {
        position: q,
        ..Default::default()
    })
}

fn cart_from(p: Pose) -> Reference {
    Reference::Cartesian(CartesianReference {
        pose: p,
        twist: Twist::default(),
    })
}

fn joint(r: &Reference) -> JointReference {
    match r {
        Reference::Joint(j) => *j,
        other => panic!("expected a joint reference, got {other:?}"),
    }
}

fn cart(r: &Reference) -> CartesianReference {
    match r {
        Reference::Cartesian(c) => *c,
        other => panic!("expected a Cartesian reference, got {other:?}"),
    }
}

fn pose(x: f64, y: f64, z: f64, r: f64, p: f64, yaw: f64) -> Pose {
    Pose::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r, p, yaw),
    )
}

/// Samples a joint trajectory every `DT` from 0 to `t_end`.
fn sample_joint(traj: &mut dyn Trajectory, t_end: f64) -> Vec<JointReference> {
    let n = (t_end / DT).round() as usize;
    (0..=n)
        .map(|i| joint(&traj.reference(at(i as f64 * DT)).unwrap()))
        .collect()
}

/// Checks that velocity is the central difference of position and acceleration that of velocity,
/// away from the profile's corners (where the acceleration itself steps). Returns how many
/// samples were checked and skipped.
fn check_derivatives(s: &[JointReference], acc_tol: f64) -> (usize, usize) {
    let (mut checked, mut skipped) = (0, 0);
    for i in 1..s.len() - 1 {
        let v_num = (s[i + 1].position - s[i - 1].position) / (2.0 * DT);
        let a_num = (s[i + 1].velocity - s[i - 1].velocity) / (2.0 * DT);
        // A central difference that straddles a corner of the acceleration is not comparable.
        // (A velocity step, as at a ramp's end, shows as a large second difference.)
        let corner =
            (s[i + 1].acceleration - 2.0 * s[i].acceleration + s[i - 1].acceleration).norm() > 1e-9
                || (s[i + 1].velocity - 2.0 * s[i].velocity + s[i - 1].velocity).norm() > 1e-2;
        if corner {
            skipped += 1;
            continue;
        }
        checked += 1;
        assert!(
            (v_num - s[i].velocity).norm() < 1e-5,
            "velocity at {i}: {} vs numerical {}",
            s[i].velocity,
            v_num
        );
        assert!(
            (a_num - s[i].acceleration).norm() < acc_tol,
            "acceleration at {i}: {} vs numerical {}",
            s[i].acceleration,
            a_num
        );
    }
    (checked, skipped)
}

#[test]
fn trapezoidal_joint_respects_limits_and_is_synchronised() {
    let q0 = JointVector::from_column_slice(&[0.1, -0.2, 0.3, 0.0, 1.0, -1.0]);
    let q1 = JointVector::from_column_slice(&[1.1, 0.3, 0.3, -0.5, 1.2, 2.0]);
    let vmax = JointVector::from_column_slice(&[1.0, 1.0, 1.0, 2.0, 2.0, 2.0]);
    let amax = JointVector::from_column_slice(&[2.0, 4.0, 4.0, 8.0, 8.0, 3.0]);
    let mut tr = Trapezoidal::joint(q1, vmax, amax).unwrap();
    assert_eq!(tr.reference(T0), Err(TrajectoryError::NotStarted));
    tr.start(T0, &joint_from(q0));
    let dur = tr.duration().unwrap().as_secs_f64();
    // Joint 6 travels 3 rad at 2 rad/s, 3 rad/s²: the slowest axis, 3/2 + 2/3 s.
    assert!(
        (dur - (3.0 / 2.0 + 2.0 / 3.0)).abs() < 1e-9,
        "duration {dur}"
    );
    let s = sample_joint(&mut tr, dur + 0.2);
    // Starts exactly at the start, at rest.
    assert_eq!(s[0].position, q0);
    assert_eq!(s[0].velocity, JointVector::zeros());
    for r in &s {
        let frac0 = (r.position[5] - q0[5]) / (q1[5] - q0[5]);
        for j in 0..6 {
            assert!(r.velocity[j].abs() <= vmax[j] + 1e-9, "joint {j} speed");
            assert!(r.acceleration[j].abs() <= amax[j] + 1e-9, "joint {j} accel");
            // Straight line in joint space: every axis at the same fraction of its travel.
            if q1[j] != q0[j] {
                let frac = (r.position[j] - q0[j]) / (q1[j] - q0[j]);
                assert!((frac - frac0).abs() < 1e-9);
            }
        }
    }
    // Continuity: no step larger than the top speed times the period.
    for w in s.windows(2) {
        let step = w[1].position - w[0].position;
        for j in 0..6 {
            assert!(step[j].abs() <= vmax[j] * DT + 1e-9);
        }
    }
    let (checked, skipped) = check_derivatives(&s, 1e-6);
    assert!(
        checked > 2000 && skipped <= 8,
        "{checked} checked, {skipped} skipped"
    );
    // Exact goal afterwards, at rest, and finished.
    let end = joint(&tr.reference(at(dur + 10.0)).unwrap());
    assert_eq!(end.position, q1);
    assert_eq!(end.velocity, JointVector::zeros());
    assert!(tr.is_finished(at(dur + 1e-6)));
    assert!(!tr.is_finished(at(dur - 1e-3)));
}

#[test]
fn trapezoidal_short_move_is_triangular_and_zero_move_is_instant() {
    let q0 = JointVector::zeros();
    let mut q1 = q0;
    q1[0] = 0.01;
    let lim = JointVector::repeat(1.0);
    let mut tr = Trapezoidal::joint(q1, lim, lim).unwrap();
    tr.start(T0, &joint_from(q0));
    // 0.01 rad at 1 rad/s² never reaches 1 rad/s: 2 sqrt(0.01) = 0.2 s.
    assert!((tr.duration().unwrap().as_secs_f64() - 0.2).abs() < 1e-9);
    let peak = sample_joint(&mut tr, 0.3)
        .iter()
        .map(|r| r.velocity[0])
        .fold(0.0, f64::max);
    assert!((peak - 0.1).abs() < 2e-3, "peak {peak}");

    let mut still = Trapezoidal::joint(q0, lim, lim).unwrap();
    still.start(T0, &joint_from(q0));
    assert!(still.is_finished(T0));
    assert_eq!(joint(&still.reference(T0).unwrap()).position, q0);
}

#[test]
fn trapezoidal_cartesian_moves_straight_with_slerp_and_bounded_speeds() {
    let p0 = pose(0.4, 0.1, 0.3, 0.1, 0.2, -0.3);
    let p1 = pose(0.5, -0.05, 0.35, -0.4, 0.5, 0.9);
    let lim = CartesianLimits {
        linear_velocity: 0.2,
        linear_acceleration: 1.0,
        angular_velocity: 0.8,
        angular_acceleration: 2.0,
    };
    let mut tr = Trapezoidal::cartesian(p1, lim).unwrap();
    tr.start(T0, &cart_from(p0));
    let dur = tr.duration().unwrap().as_secs_f64();
    let n = (dur / DT) as usize + 50;
    let s: Vec<CartesianReference> = (0..=n)
        .map(|i| cart(&tr.reference(at(i as f64 * DT)).unwrap()))
        .collect();
    assert_eq!(s[0].pose.translation, p0.translation);
    assert!(s[0].pose.rotation.angle_to(&p0.rotation) < 1e-12);
    let dp = p1.translation.vector - p0.translation.vector;
    let mut peak_w: f64 = 0.0;
    for (i, r) in s.iter().enumerate() {
        assert!(r.twist.linear.norm() <= lim.linear_velocity + 1e-9);
        assert!(r.twist.angular.norm() <= lim.angular_velocity + 1e-9);
        peak_w = peak_w.max(r.twist.angular.norm());
        assert_eq!(r.twist.frame, Frame::Base);
        // On the straight line, and the orientation on the slerp arc at the same parameter.
        let x = r.pose.translation.vector - p0.translation.vector;
        let sp = x.dot(&dp) / dp.norm_squared();
        assert!((x - dp * sp).norm() < 1e-12);
        let slerp = p0.rotation.slerp(&p1.rotation, sp);
        assert!(r.pose.rotation.angle_to(&slerp) < 1e-9, "sample {i}");
        // Twist = numerical derivative of the pose, away from the profile's corners.
        let corner = |k: usize| {
            (s[k + 1].twist.to_vector() - 2.0 * s[k].twist.to_vector() + s[k - 1].twist.to_vector())
                .norm()
                > 1e-9
        };
        if i > 0 && i + 1 < s.len() && !corner(i) {
            let v_num =
                (s[i + 1].pose.translation.vector - s[i - 1].pose.translation.vector) / (2.0 * DT);
            let w_num = (s[i + 1].pose.rotation * s[i - 1].pose.rotation.inverse()).scaled_axis()
                / (2.0 * DT);
            assert!((v_num - r.twist.linear).norm() < 1e-5);
            assert!((w_num - r.twist.angular).norm() < 1e-5);
        }
    }
    // The rotation is the slow part here: it reaches its limit.
    assert!(peak_w > 0.99 * lim.angular_velocity, "peak {peak_w}");
    let end = cart(&tr.reference(at(dur + 1.0)).unwrap());
    assert_eq!(end.pose, p1);
    assert_eq!(end.twist.linear, Vector3::zeros());
}

#[test]
fn ramp_has_constant_speed_and_exact_ends() {
    let q0 = JointVector::repeat(0.5);
    let q1 = JointVector::from_column_slice(&[1.5, 0.5, -0.5, 0.5, 0.5, 0.0]);
    let mut r = Ramp::joint(q1, Duration::from_secs(2)).unwrap();
    r.start(T0, &joint_from(q0));
    let s = sample_joint(&mut r, 2.5);
    assert_eq!(s[0].position, q0);
    let v = (q1 - q0) / 2.0;
    for x in &s[..1999] {
        assert!((x.velocity - v).norm() < 1e-12);
        assert_eq!(x.acceleration, JointVector::zeros());
    }
    assert!((s[1000].position - (q0 + q1) / 2.0).norm() < 1e-9);
    let (checked, _) = check_derivatives(&s, 1e-6);
    assert!(checked > 2000);
    assert_eq!(joint(&r.reference(at(2.0)).unwrap()).position, q1);
    assert!(r.is_finished(at(2.0)));

    // Cartesian ramp: half-way pose is the slerp midpoint.
    let p0 = pose(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let p1 = pose(0.1, 0.2, 0.3, 0.0, 0.0, 1.0);
    let mut rc = Ramp::cartesian(p1, Duration::from_secs(1)).unwrap();
    rc.start(T0, &cart_from(p0));
    let mid = cart(&rc.reference(at(0.5)).unwrap());
    assert!((mid.pose.translation.vector - Vector3::new(0.05, 0.1, 0.15)).norm() < 1e-12);
    assert!((mid.pose.rotation.angle() - 0.5).abs() < 1e-12);
    assert!((mid.twist.angular - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-12);
}

#[test]
fn step_holds_then_jumps() {
    let q0 = JointVector::repeat(0.1);
    let q1 = JointVector::repeat(-0.2);
    let mut st = Step::joint(q1)
        .unwrap()
        .with_delay(Duration::from_millis(100));
    st.start(T0, &joint_from(q0));
    assert_eq!(joint(&st.reference(at(0.05)).unwrap()).position, q0);
    assert!(!st.is_finished(at(0.05)));
    assert_eq!(joint(&st.reference(at(0.1)).unwrap()).position, q1);
    assert!(st.is_finished(at(0.1)));
}

#[test]
fn wrong_start_kind_leaves_the_trajectory_unstarted() {
    let mut tr = Ramp::joint(JointVector::zeros(), Duration::from_secs(1)).unwrap();
    tr.start(T0, &cart_from(Pose::identity()));
    assert_eq!(tr.reference(T0), Err(TrajectoryError::NotStarted));
    assert!(!tr.is_started());
    let mut c = Trapezoidal::cartesian(Pose::identity(), CartesianLimits::default()).unwrap();
    c.start(T0, &Reference::Wrench(Wrench::zero(Frame::Base)));
    assert_eq!(c.reference(T0), Err(TrajectoryError::NotStarted));
    // A non-finite start is refused too.
    let mut bad = JointVector::zeros();
    bad[2] = f64::NAN;
    tr.start(T0, &joint_from(bad));
    assert_eq!(tr.reference(T0), Err(TrajectoryError::NotStarted));
    assert!(!tr.is_finished(at(100.0)));
}

#[test]
fn configuration_errors_are_typed() {
    let mut nan = JointVector::zeros();
    nan[0] = f64::NAN;
    assert_eq!(
        Step::joint(nan).unwrap_err(),
        TrajectoryConfigError::NonFinite
    );
    let ones = JointVector::repeat(1.0);
    let mut zero_limit = ones;
    zero_limit[3] = 0.0;
    assert_eq!(
        Trapezoidal::joint(ones, zero_limit, ones).unwrap_err(),
        TrajectoryConfigError::NotPositive
    );
    let lim = CartesianLimits {
        angular_acceleration: f64::INFINITY,
        ..Default::default()
    };
    assert_eq!(
        Trapezoidal::cartesian(Pose::identity(), lim).unwrap_err(),
        TrajectoryConfigError::NonFinite
    );
    let w = |t: u64, g: Goal| Waypoint {
        at: Duration::from_millis(t),
        goal: g,
    };
    let j = Goal::Joint(ones);
    let c = Goal::Cartesian(Pose::identity());
    assert_eq!(
        CubicSpline::<4>::new(&[], SplineEnds::Clamped).unwrap_err(),
        TrajectoryConfigError::NoWaypoints
    );
    assert_eq!(
        CubicSpline::<2>::new(&[w(1, j), w(2, j), w(3, j)], SplineEnds::Clamped).unwrap_err(),
        TrajectoryConfigError::TooManyWaypoints
    );
    assert_eq!(
        CubicSpline::<4>::new(&[w(2, j), w(2, j)], SplineEnds::Clamped).unwrap_err(),
        TrajectoryConfigError::TimesNotIncreasing
    );
    assert_eq!(
        CubicSpline::<4>::new(&[w(0, j)], SplineEnds::Clamped).unwrap_err(),
        TrajectoryConfigError::TimesNotIncreasing
    );
    assert_eq!(
        CubicSpline::<4>::new(&[w(1, j), w(2, c)], SplineEnds::Clamped).unwrap_err(),
        TrajectoryConfigError::MixedSpaces
    );
}

fn joint_spline_waypoints() -> [Waypoint; 4] {
    let q = |a: [f64; 6]| Goal::Joint(JointVector::from_column_slice(&a));
    [
        Waypoint {
            at: Duration::from_millis(500),
            goal: q([0.5, 0.2, -0.1, 0.0, 0.3, 0.0]),
        },
        Waypoint {
            at: Duration::from_millis(1200),
            goal: q([0.8, -0.3, 0.4, 0.1, 0.0, 1.0]),
        },
        Waypoint {
            at: Duration::from_millis(1500),
            goal: q([0.7, -0.2, 0.4, 0.5, -0.2, 1.2]),
        },
        Waypoint {
            at: Duration::from_millis(2500),
            goal: q([0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        },
    ]
}

#[test]
fn clamped_spline_passes_through_waypoints_smoothly() {
    let wps = joint_spline_waypoints();
    let mut sp = CubicSpline::<8>::new(&wps, SplineEnds::Clamped).unwrap();
    assert_eq!(sp.len(), 4);
    // Start while moving: the spline takes over the start velocity, so nothing jumps.
    let q0 = JointVector::from_column_slice(&[0.1, 0.0, 0.0, 0.0, 0.0, -0.2]);
    let v0 = JointVector::from_column_slice(&[0.3, -0.1, 0.0, 0.2, 0.0, 0.5]);
    sp.start(
        T0,
        &Reference::Joint(JointReference {
            position: q0,
            velocity: v0,
            acceleration: JointVector::zeros(),
        }),
    );
    let s = sample_joint(&mut sp, 3.0);
    assert_eq!(s[0].position, q0);
    assert!((s[0].velocity - v0).norm() < 1e-12);
    for w in &wps {
        let r = joint(&sp.reference(T0 + w.at).unwrap());
        let Goal::Joint(q) = w.goal else {
            unreachable!()
        };
        assert!((r.position - q).norm() < 1e-12, "at {:?}", w.at);
    }
    // C²: position, velocity and acceleration continuous across every interior knot.
    for w in &wps[..3] {
        let before = joint(
            &sp.reference(T0 + (w.at - Duration::from_nanos(100)))
                .unwrap(),
        );
        let after = joint(&sp.reference(T0 + w.at + Duration::from_nanos(100)).unwrap());
        assert!((before.position - after.position).norm() < 1e-5);
        assert!((before.velocity - after.velocity).norm() < 1e-4);
        assert!(
            (before.acceleration - after.acceleration).norm() < 1e-3,
            "{} vs {}",
            before.acceleration,
            after.acceleration
        );
    }
    // Cubic per segment: the central differences match but for rounding, except where the pair
    // straddles a knot.
    let (checked, _) = check_derivatives(&s, 1e-4);
    assert!(checked > 2400, "{checked}");
    // Ends at rest on the last waypoint and holds it.
    let end = joint(&sp.reference(at(2.5 - 1e-6)).unwrap());
    assert!(end.velocity.norm() < 1e-4, "{}", end.velocity);
    let hold = joint(&sp.reference(at(4.0)).unwrap());
    assert_eq!(hold.position, JointVector::zeros());
    assert_eq!(hold.velocity, JointVector::zeros());
    assert!(sp.is_finished(at(2.5)));
    assert!(!sp.is_finished(at(2.4)));
}

#[test]
fn natural_spline_has_zero_end_accelerations() {
    let wps = joint_spline_waypoints();
    let mut sp = CubicSpline::<4>::new(&wps, SplineEnds::Natural).unwrap();
    sp.start(T0, &joint_from(JointVector::zeros()));
    let a0 = joint(&sp.reference(T0).unwrap()).acceleration;
    let an = joint(&sp.reference(at(2.5 - 1e-9)).unwrap()).acceleration;
    assert!(a0.norm() < 1e-9, "{a0}");
    assert!(an.norm() < 1e-6, "{an}");
    // Sample up to just before the end: the velocity steps to zero when the goal is held.
    let s = sample_joint(&mut sp, 2.499);
    let (checked, _) = check_derivatives(&s, 1e-4);
    assert!(checked > 2400);
}

#[test]
fn cartesian_spline_through_orientations_past_half_a_turn() {
    // Waypoints turning about z by 0.9 pi, 1.8 pi (past pi from the start) and 2.2 pi.
    let rz = |a: f64| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a);
    let pi = core::f64::consts::PI;
    let p = |x: f64, a: f64| Pose::from_parts(Translation3::new(x, 0.1, 0.2), rz(a));
    let wps = [
        Waypoint {
            at: Duration::from_secs(1),
            goal: Goal::Cartesian(p(0.1, 0.9 * pi)),
        },
        Waypoint {
            at: Duration::from_secs(2),
            goal: Goal::Cartesian(p(0.2, 1.8 * pi)),
        },
        Waypoint {
            at: Duration::from_secs(3),
            goal: Goal::Cartesian(p(0.1, 2.2 * pi)),
        },
    ];
    let mut sp = CubicSpline::<3>::new(&wps, SplineEnds::Clamped).unwrap();
    sp.start(T0, &cart_from(p(0.0, 0.0)));
    let n = 3100;
    let s: Vec<CartesianReference> = (0..=n)
        .map(|i| cart(&sp.reference(at(i as f64 * DT)).unwrap()))
        .collect();
    for w in &wps {
        let r = cart(&sp.reference(T0 + w.at).unwrap());
        let Goal::Cartesian(g) = w.goal else {
            unreachable!()
        };
        assert!(r.pose.rotation.angle_to(&g.rotation) < 1e-9);
        assert!((r.pose.translation.vector - g.translation.vector).norm() < 1e-12);
    }
    // Turning the long way round without wrapping: the angular velocity about z stays positive
    // in the middle of the motion, and is the derivative of the orientation throughout.
    for i in 1..n - 101 {
        let w_num =
            (s[i + 1].pose.rotation * s[i - 1].pose.rotation.inverse()).scaled_axis() / (2.0 * DT);
        assert!((w_num - s[i].twist.angular).norm() < 1e-4, "sample {i}");
        let v_num =
            (s[i + 1].pose.translation.vector - s[i - 1].pose.translation.vector) / (2.0 * DT);
        assert!((v_num - s[i].twist.linear).norm() < 1e-4);
        if (200..2800).contains(&i) {
            assert!(s[i].twist.angular.z > 0.0, "sample {i}");
        }
    }
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    fn finite_reference(r: &Reference) -> bool {
        r.is_finite()
    }

    proptest! {
        /// Whatever the goal, limits and sampling times, a trapezoid starts where it was told,
        /// never panics, stays finite and within its limits, and ends exactly on the goal.
        #[test]
        fn trapezoid_is_total(
            start in proptest::array::uniform6(-1e3..1e3f64),
            goal in proptest::array::uniform6(-1e3..1e3f64),
            vmax in proptest::array::uniform6(1e-6..1e6f64),
            amax in proptest::array::uniform6(1e-6..1e6f64),
            times in proptest::collection::vec(0.0..1e7f64, 1..20),
        ) {
            let q0 = JointVector::from_column_slice(&start);
            let q1 = JointVector::from_column_slice(&goal);
            let v = JointVector::from_column_slice(&vmax);
            let a = JointVector::from_column_slice(&amax);
            let mut tr = Trapezoidal::joint(q1, v, a).unwrap();
            tr.start(T0, &joint_from(q0));
            prop_assert_eq!(joint(&tr.reference(T0).unwrap()).position, q0);
            for t in times {
                let r = tr.reference(at(t)).unwrap();
                prop_assert!(finite_reference(&r));
                let j = joint(&r);
                for i in 0..6 {
                    prop_assert!(j.velocity[i].abs() <= v[i] * (1.0 + 1e-9));
                    prop_assert!(j.acceleration[i].abs() <= a[i] * (1.0 + 1e-9));
                }
            }
            let end = tr.duration().unwrap();
            prop_assert_eq!(joint(&tr.reference(T0 + end + Duration::from_secs(1)).unwrap()).position, q1);
        }

        /// Splines through random waypoints pass through them and never panic.
        #[test]
        fn spline_is_total(
            points in proptest::collection::vec(
                (1u64..2_000, proptest::array::uniform6(-10.0..10.0f64)), 1..8),
            natural in any::<bool>(),
            times in proptest::collection::vec(0.0..20.0f64, 1..20),
        ) {
            let mut t = 0;
            let wps: Vec<Waypoint> = points
                .iter()
                .map(|(dt, q)| {
                    t += dt;
                    Waypoint {
                        at: Duration::from_millis(t),
                        goal: Goal::Joint(JointVector::from_column_slice(q)),
                    }
                })
                .collect();
            let ends = if natural { SplineEnds::Natural } else { SplineEnds::Clamped };
            let mut sp = CubicSpline::<8>::new(&wps, ends).unwrap();
            sp.start(T0, &joint_from(JointVector::zeros()));
            for s in times {
                prop_assert!(finite_reference(&sp.reference(at(s)).unwrap()));
            }
            for w in &wps {
                let Goal::Joint(q) = w.goal else { unreachable!() };
                let r = joint(&sp.reference(T0 + w.at).unwrap());
                prop_assert!((r.position - q).norm() < 1e-6 * (1.0 + q.norm()));
            }
        }
    }
}
