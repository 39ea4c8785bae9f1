//! Workspace mapping, clutch and the teleop channel.

use core::time::Duration;

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use penelope_hal::{
    CartesianReference, Frame, HybridReference, JointReference, JointVector, Pose, Reference,
    Timestamp, Trajectory, TrajectoryError, Twist, Wrench,
};
use penelope_rt_core::teleop::{
    ChannelConfig, ChannelDirection, MappingConfig, MappingError, ReceiveError, TeleopChannel,
    TeleopConfigError, TeleopSample, VelocityFeedForward, WorkspaceMapping,
};

const DT: f64 = 1e-3;

fn at(k: usize) -> Timestamp {
    Timestamp::from_nanos(1_000_000_000 + k as u64 * 1_000_000)
}

fn pose(x: f64, y: f64, z: f64, r: f64, p: f64, yaw: f64) -> Pose {
    Pose::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r, p, yaw),
    )
}

fn config(scale: f64) -> MappingConfig {
    MappingConfig {
        scale,
        rotation: UnitQuaternion::from_euler_angles(0.2, -0.4, 1.3),
        force_gain: 0.4,
        torque_gain: 0.25,
        negate_wrench: false,
        clutch_fade: Duration::from_millis(100),
    }
}

/// A master hand moving smoothly: a 2 Hz, 5 cm loop with a little wrist rotation.
fn master_at(t: f64) -> Pose {
    let w = 2.0 * std::f64::consts::PI * 2.0;
    pose(
        0.3 + 0.05 * (w * t).sin(),
        0.05 * (1.0 - (w * t).cos()),
        0.1 + 0.02 * (0.5 * w * t).sin(),
        0.2 * (w * t).sin(),
        0.1,
        -0.3 + 0.1 * (w * t).cos(),
    )
}

fn cart(p: Pose) -> Reference {
    Reference::Cartesian(CartesianReference {
        pose: p,
        twist: Twist::default(),
    })
}

fn out_cart(r: Reference) -> CartesianReference {
    match r {
        Reference::Cartesian(c) => c,
        other => panic!("expected Cartesian, got {other:?}"),
    }
}

#[test]
fn mapping_scales_rotates_and_round_trips() {
    let mut m = WorkspaceMapping::new(config(0.5)).unwrap();
    let pm = pose(0.2, 0.1, -0.1, 0.3, 0.2, 0.1);
    let ps = pose(0.5, -0.2, 0.6, -1.0, 0.4, 2.0);
    assert_eq!(m.master_to_slave(&pm), Err(MappingError::NotAnchored));
    m.anchor(&pm, &ps);
    // The anchor maps onto the anchor.
    let s0 = m.master_to_slave(&pm).unwrap();
    assert!((s0.translation.vector - ps.translation.vector).norm() < 1e-15);
    assert!(s0.rotation.angle_to(&ps.rotation) < 1e-12);
    // A master displacement d becomes sigma R_ms d.
    let d = Vector3::new(0.04, -0.02, 0.03);
    let moved = Pose::from_parts((pm.translation.vector + d).into(), pm.rotation);
    let s = m.master_to_slave(&moved).unwrap();
    let expected = config(0.5).rotation * d * 0.5;
    assert!((s.translation.vector - ps.translation.vector - expected).norm() < 1e-15);
    assert!(s.rotation.angle_to(&ps.rotation) < 1e-12);
    // A master rotation by theta about axis a (master base) becomes the same angle, unscaled,
    // about R_ms a (slave base).
    let axis = Vector3::new(1.0, 2.0, -0.5).normalize();
    let turn = UnitQuaternion::from_scaled_axis(axis * 0.7);
    let turned = Pose::from_parts(pm.translation, turn * pm.rotation);
    let s = m.master_to_slave(&turned).unwrap();
    let rel = (s.rotation * ps.rotation.inverse()).scaled_axis();
    assert!((rel - config(0.5).rotation * axis * 0.7).norm() < 1e-12);
    // Round trips both ways over many poses.
    for k in 0..200 {
        let p = master_at(k as f64 * 0.0137);
        let back = m.slave_to_master(&m.master_to_slave(&p).unwrap()).unwrap();
        assert!((back.translation.vector - p.translation.vector).norm() < 1e-14);
        assert!(back.rotation.angle_to(&p.rotation) < 1e-12);
    }
    // Twists map with the same scale and rotation, and back.
    let t = Twist {
        linear: Vector3::new(0.1, 0.2, -0.3),
        angular: Vector3::new(-1.0, 0.5, 0.2),
        frame: Frame::Base,
    };
    let ts = m.twist_to_slave(&t);
    assert!((ts.linear - config(0.5).rotation * t.linear * 0.5).norm() < 1e-15);
    let tb = m.twist_to_master(&ts);
    assert!((tb.to_vector() - t.to_vector()).norm() < 1e-14);
}

#[test]
fn wrenches_map_back_rotated_and_scaled() {
    let mut cfg = config(0.5);
    let m = WorkspaceMapping::new(cfg).unwrap();
    let w = Wrench {
        force: Vector3::new(10.0, -5.0, 2.0),
        torque: Vector3::new(0.4, 0.0, -1.0),
        frame: Frame::Base,
    };
    let wm = m.wrench_to_master(&w);
    let r_sm = cfg.rotation.inverse();
    assert!((wm.force - r_sm * w.force * 0.4).norm() < 1e-12);
    assert!((wm.torque - r_sm * w.torque * 0.25).norm() < 1e-12);
    assert_eq!(wm.frame, Frame::Base);
    let back = m.wrench_to_slave(&wm);
    assert!((back.to_vector() - w.to_vector()).norm() < 1e-12);
    // A sensor with the opposite convention.
    cfg.negate_wrench = true;
    let neg = WorkspaceMapping::new(cfg).unwrap().wrench_to_master(&w);
    assert!((neg.force + wm.force).norm() < 1e-12);
}

#[test]
fn invalid_mapping_configs_are_refused() {
    let mut c = config(0.0);
    assert_eq!(
        WorkspaceMapping::new(c).unwrap_err(),
        TeleopConfigError::OutOfRange { parameter: "scale" }
    );
    c.scale = 1.0;
    c.force_gain = f64::NAN;
    assert_eq!(
        WorkspaceMapping::new(c).unwrap_err(),
        TeleopConfigError::NonFinite {
            parameter: "force_gain"
        }
    );
    let bad = ChannelConfig {
        velocity: VelocityFeedForward::Estimate { cutoff_hz: 0.0 },
        ..Default::default()
    };
    assert!(TeleopChannel::new(bad).is_err());
}

#[test]
fn clutch_holds_fades_and_releases_without_a_jump() {
    let sigma = 0.8;
    let mut m = WorkspaceMapping::new(config(sigma)).unwrap();
    let ps0 = pose(0.5, 0.0, 0.4, 0.0, 1.0, 0.0);
    m.anchor(&master_at(0.0), &ps0);
    let n = 3000;
    let (press, release) = (700, 1900);
    let mut prev: Option<Pose> = None;
    let mut biggest_master_step: f64 = 0.0;
    let mut biggest_slave_step: f64 = 0.0;
    let mut biggest_slave_turn: f64 = 0.0;
    let mut biggest_master_turn: f64 = 0.0;
    for k in 0..n {
        let t = k as f64 * DT;
        let pm = master_at(t);
        let clutch = (press..release).contains(&k);
        let s = m.update(at(k), &pm, clutch).unwrap();
        if k > 0 {
            let pm_prev = master_at(t - DT);
            biggest_master_step = biggest_master_step
                .max((pm.translation.vector - pm_prev.translation.vector).norm());
            biggest_master_turn = biggest_master_turn.max(pm.rotation.angle_to(&pm_prev.rotation));
        }
        if let Some(p) = prev {
            let step = (s.translation.vector - p.translation.vector).norm();
            biggest_slave_step = biggest_slave_step.max(step);
            biggest_slave_turn = biggest_slave_turn.max(s.rotation.angle_to(&p.rotation));
            if clutch && k > press {
                assert_eq!(step, 0.0, "slave moved while clutched at tick {k}");
            }
        }
        prev = Some(s);
        // The force fades out over 100 ms after the press and back in after the release.
        let f = m.force_scale(at(k));
        if k < press {
            assert_eq!(f, 1.0);
        } else if k >= press + 100 && k < release {
            assert_eq!(f, 0.0);
        } else if k >= release + 100 {
            assert_eq!(f, 1.0);
        } else if k == press + 50 || k == release + 50 {
            assert!((f - 0.5).abs() < 1e-9, "tick {k}: {f}");
        }
        assert_eq!(m.is_clutched(), clutch);
    }
    // No step larger than one period's normal motion (sigma times the master's), even across the
    // press and the release where the master had moved away meanwhile.
    assert!(biggest_master_step > 0.0);
    assert!(
        biggest_slave_step <= sigma * biggest_master_step + 1e-12,
        "{biggest_slave_step} > {sigma} * {biggest_master_step}"
    );
    assert!(biggest_slave_turn <= biggest_master_turn + 1e-9);
    // After release the slave follows the master's motion since the release.
    let pm_rel = master_at(release as f64 * DT);
    let pm_end = master_at((n - 1) as f64 * DT);
    let held = m.anchors().unwrap().slave;
    let s_end = m.master_to_slave(&pm_end).unwrap();
    let expected =
        config(sigma).rotation * (pm_end.translation.vector - pm_rel.translation.vector) * sigma;
    assert!((s_end.translation.vector - held.translation.vector - expected).norm() < 1e-12);
}

fn channel(direction: ChannelDirection, velocity: VelocityFeedForward) -> TeleopChannel {
    TeleopChannel::new(ChannelConfig {
        direction,
        mapping: config(0.5),
        velocity,
        max_velocity_gap: Duration::from_millis(50),
    })
    .unwrap()
}

#[test]
fn channel_reports_no_data_then_newest_wins() {
    let mut ch = channel(ChannelDirection::MasterToSlave, VelocityFeedForward::Zero);
    assert_eq!(ch.kind(), "teleop");
    assert_eq!(ch.reference(at(0)), Err(TrajectoryError::NotStarted));
    let slave0 = pose(0.5, 0.1, 0.3, 0.0, 0.5, 0.0);
    ch.start(at(0), &cart(slave0));
    assert_eq!(ch.reference(at(0)), Err(TrajectoryError::NoData));
    assert_eq!(ch.age(at(0)), None);
    assert!(!ch.is_finished(at(1000)));

    // The first sample anchors: the slave reference starts exactly at the slave's pose.
    ch.receive(TeleopSample::new(5, at(10), cart(master_at(0.0))))
        .unwrap();
    let r = out_cart(ch.reference(at(12)).unwrap());
    assert_eq!(r.pose.translation, slave0.translation);
    assert!(r.pose.rotation.angle_to(&slave0.rotation) < 1e-12);
    assert_eq!(ch.age(at(12)), Some(Duration::from_millis(2)));

    // Newer sample moves the reference; an older or duplicate one is dropped.
    ch.receive(TeleopSample::new(7, at(20), cart(master_at(0.05))))
        .unwrap();
    let newer = out_cart(ch.reference(at(21)).unwrap());
    assert_eq!(
        ch.receive(TeleopSample::new(6, at(15), cart(master_at(0.5)))),
        Err(ReceiveError::Stale)
    );
    assert_eq!(
        ch.receive(TeleopSample::new(7, at(22), cart(master_at(0.5)))),
        Err(ReceiveError::Stale)
    );
    assert_eq!(out_cart(ch.reference(at(23)).unwrap()), newer);
    assert_eq!(ch.latest_sequence(), Some(7));
    // Garbage is refused without touching the state.
    let mut nan = master_at(0.1);
    nan.translation.x = f64::NAN;
    assert_eq!(
        ch.receive(TeleopSample::new(8, at(24), cart(nan))),
        Err(ReceiveError::NonFinite)
    );
    assert_eq!(
        ch.receive(TeleopSample::new(
            9,
            at(24),
            Reference::Wrench(Wrench::zero(Frame::Sensor))
        )),
        Err(ReceiveError::UnsupportedFrame)
    );
    assert_eq!(out_cart(ch.reference(at(25)).unwrap()), newer);
    let st = ch.stats();
    assert_eq!((st.accepted, st.stale, st.rejected), (2, 2, 2));
    // The age keeps growing: freshness is the watchdog's call.
    assert_eq!(ch.age(at(520)), Some(Duration::from_millis(500)));
    assert!(ch.reference(at(520)).is_ok());
    // A reset forgets everything (a new session may restart its sequence numbers).
    ch.reset();
    assert_eq!(ch.reference(at(521)), Err(TrajectoryError::NotStarted));
    ch.start(at(521), &cart(slave0));
    ch.receive(TeleopSample::new(0, at(521), cart(master_at(0.0))))
        .unwrap();
}

#[test]
fn slave_channel_follows_the_master_with_a_velocity_estimate_and_clutch() {
    let mut ch = channel(
        ChannelDirection::MasterToSlave,
        VelocityFeedForward::Estimate { cutoff_hz: 50.0 },
    );
    let slave0 = pose(0.5, 0.1, 0.3, 0.0, 0.5, 0.0);
    ch.start(at(0), &cart(slave0));
    let mapping = {
        let mut m = WorkspaceMapping::new(config(0.5)).unwrap();
        m.anchor(&master_at(0.0), &slave0);
        m
    };
    let mut prev: Option<Pose> = None;
    let mut worst_v: f64 = 0.0;
    let mut worst_step: f64 = 0.0;
    for k in 0..1500 {
        let t = k as f64 * DT;
        let clutch = (600..900).contains(&k);
        let mut s = TeleopSample::new(k as u64, at(k), cart(master_at(t)));
        s.clutch = clutch;
        ch.receive(s).unwrap();
        let r = out_cart(ch.reference(at(k)).unwrap());
        if k < 600 {
            // Before the clutch: exactly the mapping of the master pose...
            let expected = mapping.master_to_slave(&master_at(t)).unwrap();
            assert!((r.pose.translation.vector - expected.translation.vector).norm() < 1e-12);
            // ... and a velocity feed-forward close to the true mapped velocity, once the filter
            // has settled (a 50 Hz first-order filter lags a 2 Hz motion by about 4 degrees).
            if k > 100 {
                let h = 1e-6;
                let true_v = (mapping
                    .master_to_slave(&master_at(t + h))
                    .unwrap()
                    .translation
                    .vector
                    - mapping
                        .master_to_slave(&master_at(t - h))
                        .unwrap()
                        .translation
                        .vector)
                    / (2.0 * h);
                worst_v = worst_v.max((r.twist.linear - true_v).norm() / true_v.norm().max(0.05));
            }
        }
        if clutch {
            assert_eq!(r.twist.linear, Vector3::zeros());
        }
        if let Some(p) = prev {
            worst_step = worst_step.max((r.pose.translation.vector - p.translation.vector).norm());
        }
        prev = Some(r.pose);
    }
    assert!(worst_v < 0.1, "velocity estimate off by {worst_v}");
    // 2 Hz, 5 cm loop at sigma 0.5: about 0.5 * 0.63 m/s * 1 ms = 0.3 mm per tick at most.
    assert!(worst_step < 0.5 * 0.7e-3, "step {worst_step}");
    assert!(!ch.mapping().is_clutched());
}

#[test]
fn master_channel_maps_wrenches_back_and_fades_them_with_the_clutch() {
    let mut ch = channel(ChannelDirection::SlaveToMaster, VelocityFeedForward::Zero);
    let master0 = master_at(0.0);
    ch.start(at(0), &cart(master0));
    let w = Wrench {
        force: Vector3::new(0.0, 0.0, -20.0),
        torque: Vector3::new(0.5, 0.0, 0.0),
        frame: Frame::Base,
    };
    let expected = WorkspaceMapping::new(config(0.5))
        .unwrap()
        .wrench_to_master(&w);
    let mut seq = 0;
    let mut send = |ch: &mut TeleopChannel, k: usize| {
        seq += 1;
        ch.receive(TeleopSample::new(seq, at(k), Reference::Wrench(w)))
            .unwrap();
    };
    send(&mut ch, 0);
    let got = |r: Reference| match r {
        Reference::Wrench(w) => w,
        other => panic!("expected a wrench, got {other:?}"),
    };
    let w0 = got(ch.reference(at(0)).unwrap());
    assert!((w0.to_vector() - expected.to_vector()).norm() < 1e-12);
    // Clutch pressed at tick 100, released at 400: fade out over 100 ms, then back in.
    let mut seen = Vec::new();
    for k in 1..700 {
        ch.track_master(at(k), &master_at(k as f64 * DT), (100..400).contains(&k));
        send(&mut ch, k);
        let wk = got(ch.reference(at(k)).unwrap());
        seen.push(wk.force.norm() / expected.force.norm());
    }
    assert!((seen[98] - 1.0).abs() < 1e-12);
    // seen[i] is tick i + 1: 49 ms into the 100 ms fade-out.
    assert!((seen[148] - 0.51).abs() < 1e-9, "{}", seen[148]);
    assert!(seen[250] < 1e-12);
    assert!((seen[600] - 1.0).abs() < 1e-12);
    // Monotone, gentle changes: at most 1/100 of the force per 1 ms tick.
    for win in seen.windows(2) {
        assert!((win[1] - win[0]).abs() <= 0.0100001);
    }
}

#[test]
fn both_sides_agree_on_poses_for_position_error() {
    // The slave maps master poses forward; the master maps slave poses back. With both anchored
    // on the same pair and fed the same master poses and clutch states, a slave that tracks
    // perfectly appears to the master exactly at the master's own pose, before and after
    // a clutch cycle.
    let slave0 = pose(0.5, 0.1, 0.3, 0.0, 0.5, 0.0);
    let mut slave_side = channel(ChannelDirection::MasterToSlave, VelocityFeedForward::Zero);
    let mut master_side = channel(ChannelDirection::SlaveToMaster, VelocityFeedForward::Zero);
    slave_side.start(at(0), &cart(slave0));
    master_side.start(at(0), &cart(master_at(0.0)));
    let mut slave_pose = slave0;
    let mut worst: f64 = 0.0;
    for k in 0..2000 {
        let t = k as f64 * DT;
        let pm = master_at(t);
        let clutch = (500..1200).contains(&k);
        master_side.track_master(at(k), &pm, clutch);
        let mut s = TeleopSample::new(k as u64, at(k), cart(pm));
        s.clutch = clutch;
        slave_side.receive(s).unwrap();
        // The slave tracks its reference perfectly and reports its pose and a contact wrench.
        slave_pose = out_cart(slave_side.reference(at(k)).unwrap()).pose;
        master_side
            .receive(TeleopSample::new(
                k as u64,
                at(k),
                Reference::Hybrid(HybridReference {
                    motion: CartesianReference {
                        pose: slave_pose,
                        twist: Twist::default(),
                    },
                    wrench: Wrench::zero(Frame::Base),
                    force_axes: [false; 6],
                }),
            ))
            .unwrap();
        let back = match master_side.reference(at(k)).unwrap() {
            Reference::Hybrid(h) => h.motion.pose,
            other => panic!("expected hybrid, got {other:?}"),
        };
        if !clutch && !(1200..1300).contains(&k) {
            worst = worst.max((back.translation.vector - pm.translation.vector).norm());
            worst = worst.max(back.rotation.angle_to(&pm.rotation));
        }
    }
    assert!(worst < 1e-12, "disagreement {worst}");
    assert!(slave_pose.translation.vector.norm() > 0.0);
}

#[test]
fn joint_samples_pass_through() {
    let mut ch = channel(
        ChannelDirection::MasterToSlave,
        VelocityFeedForward::FromSample,
    );
    ch.start(at(0), &Reference::Joint(JointReference::default()));
    let j = JointReference {
        position: JointVector::repeat(0.3),
        velocity: JointVector::repeat(-0.1),
        acceleration: JointVector::repeat(0.05),
    };
    ch.receive(TeleopSample::new(1, at(1), Reference::Joint(j)))
        .unwrap();
    assert_eq!(ch.reference(at(2)).unwrap(), Reference::Joint(j));
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    fn any_pose() -> impl Strategy<Value = Pose> {
        (
            proptest::array::uniform3(-2.0..2.0f64),
            proptest::array::uniform3(-3.2..3.2f64),
        )
            .prop_map(|(p, r)| pose(p[0], p[1], p[2], r[0], r[1], r[2]))
    }

    proptest! {
        /// Round trips hold for any scale, rotation and anchors.
        #[test]
        fn mapping_round_trips(
            scale in 0.05..20.0f64,
            rot in proptest::array::uniform3(-3.2..3.2f64),
            pm0 in any_pose(), ps0 in any_pose(), p in any_pose(),
        ) {
            let cfg = MappingConfig {
                scale,
                rotation: UnitQuaternion::from_euler_angles(rot[0], rot[1], rot[2]),
                ..Default::default()
            };
            let mut m = WorkspaceMapping::new(cfg).unwrap();
            m.anchor(&pm0, &ps0);
            let s = m.master_to_slave(&p).unwrap();
            let back = m.slave_to_master(&s).unwrap();
            prop_assert!((back.translation.vector - p.translation.vector).norm() < 1e-9);
            prop_assert!(back.rotation.angle_to(&p.rotation) < 1e-9);
        }

        /// The channel never panics and answers something finite, whatever arrives in whatever
        /// order.
        #[test]
        fn channel_is_total(
            samples in proptest::collection::vec(
                (0u64..50, 0usize..100, any::<bool>(), any_pose(), proptest::array::uniform3(-1e3..1e3f64), 0u8..3),
                1..40),
            slave_side in any::<bool>(),
        ) {
            let direction = if slave_side { ChannelDirection::MasterToSlave } else { ChannelDirection::SlaveToMaster };
            let mut ch = TeleopChannel::new(ChannelConfig { direction, ..Default::default() }).unwrap();
            ch.start(at(0), &cart(pose(0.5, 0.0, 0.3, 0.0, 0.0, 0.0)));
            for (seq, k, clutch, p, f, kind) in samples {
                let w = Wrench { force: Vector3::from(f), torque: Vector3::from(f) * 0.01, frame: Frame::Base };
                let reference = match kind {
                    0 => cart(p),
                    1 => Reference::Wrench(w),
                    _ => Reference::Hybrid(HybridReference {
                        motion: CartesianReference { pose: p, twist: Twist::default() },
                        wrench: w,
                        force_axes: [true; 6],
                    }),
                };
                ch.track_master(at(k), &p, clutch);
                let _ = ch.receive(TeleopSample { clutch, ..TeleopSample::new(seq, at(k), reference) });
                if let Ok(r) = ch.reference(at(k + 1)) {
                    prop_assert!(r.is_finite());
                }
            }
        }
    }
}
