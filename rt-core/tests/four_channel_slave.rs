//! Lawrence's four-channel slave: with only its position channel it is the slave-tracking law,
//! sample for sample; its force channels add exactly `J^T (c3 F_h + c5 F_e)`, with the wrist
//! sensor's reading moved to the tool and turned into the world's wrench on the robot; missing
//! inputs and bad coefficients are typed errors.

#[path = "teleop_model.rs"]
mod model;

use core::time::Duration;

use model::DhArm;
use nalgebra::{Translation3, UnitQuaternion, Vector3, Vector6};
use penelope_hal::{
    CartesianReference, ControlInput, Controller, ControllerError, Frame, HybridReference,
    JointCommand, JointState, JointVector, Kinematics, Pose, Reference, RobotModel, Timestamp,
    Twist, Wrench,
};
use penelope_rt_core::teleop::{
    FourChannelSlave, FourChannelSlaveConfig, SlaveTracking, TrackingConfig, TrackingOutput,
};

const TICKS: usize = 5000;

fn at(k: usize) -> Timestamp {
    Timestamp::from_nanos(1_000_000_000 + k as u64 * 1_000_000)
}

/// Tick `k`: the PUMA moving about its nominal pose, and the master's mapped pose (a loop in
/// space, ahead of the slave) with the operator's wrench beside it.
fn tick(puma: &DhArm, q0: &JointVector, k: usize) -> (JointState, Reference) {
    let t = k as f64 * 1e-3;
    let mut q = *q0;
    let mut qd = JointVector::zeros();
    for j in 0..6 {
        let w = 0.8 + 0.29 * j as f64;
        q[j] += 0.03 * (w * t).sin();
        qd[j] = 0.03 * w * (w * t).cos();
    }
    let state = JointState {
        position: q,
        velocity: qd,
        effort: JointVector::zeros(),
    };
    let here = puma.forward(q0);
    let pose = Pose::from_parts(
        Translation3::from(
            here.translation.vector
                + Vector3::new(
                    0.02 * (2.0 * t).sin(),
                    0.015 * (1.3 * t).cos(),
                    -0.01 * t.sin(),
                ),
        ),
        UnitQuaternion::from_euler_angles(0.02 * t.sin(), -0.01, 0.0) * here.rotation,
    );
    let reference = Reference::Hybrid(HybridReference {
        motion: CartesianReference {
            pose,
            twist: Twist {
                linear: Vector3::new(0.04 * (2.0 * t).cos(), 0.0, -0.01),
                angular: Vector3::zeros(),
                frame: Frame::Base,
            },
        },
        wrench: Wrench {
            force: Vector3::new(
                1.0 + (3.0 * t).sin(),
                -0.5,
                -4.0 * (t - 1.0).clamp(0.0, 1.0),
            ),
            torque: Vector3::new(0.0, 0.05 * t.cos(), 0.01),
            frame: Frame::Base,
        },
        force_axes: [true; 6],
    });
    (state, reference)
}

/// The wrist sensor: 2 cm out along the tool's z, turned 90 degrees about it.
fn mount() -> Pose {
    Pose::from_parts(
        Translation3::new(0.0, 0.0, 0.02),
        UnitQuaternion::from_euler_angles(0.0, 0.0, core::f64::consts::FRAC_PI_2),
    )
}

/// A reading in the sensor frame (the robot pushing on the world).
fn reading() -> Wrench {
    Wrench {
        force: Vector3::new(0.5, -1.0, 12.0),
        torque: Vector3::new(0.02, -0.01, 0.003),
        frame: Frame::Sensor,
    }
}

#[test]
fn with_c1_one_and_no_force_channel_it_is_slave_tracking_sample_for_sample() {
    let puma = DhArm::puma560();
    let q0 = DhArm::puma_nominal();
    let tracking = TrackingConfig {
        ki: [5.0; 6],
        ..TrackingConfig::default()
    };
    let mut classic = SlaveTracking::new(tracking).unwrap();
    let mut general = FourChannelSlave::new(FourChannelSlaveConfig {
        tracking,
        ..FourChannelSlaveConfig::default()
    })
    .unwrap();
    let start = JointState::at_rest(q0);
    classic.activate(at(0), &start, &puma);
    general.activate(at(0), &start, &puma);
    let sensed = reading();
    let mut moving = 0;
    for k in 0..TICKS {
        let (state, reference) = tick(&puma, &q0, k);
        let input = ControlInput {
            now: at(k),
            period: Duration::from_millis(1),
            state: &state,
            reference: &reference,
            wrench: Some(&sensed),
            model: &puma,
        };
        let (a, b) = (
            classic.update(&input).unwrap(),
            general.update(&input).unwrap(),
        );
        assert_eq!(a, b, "tick {k}");
        assert_eq!(classic.port_energy(), general.port_energy(), "tick {k}");
        if let JointCommand::Effort(t) = a
            && (t - penelope_hal::Dynamics::gravity(&puma, &state.position)).norm() > 1.0
        {
            moving += 1;
        }
    }
    // (A run in which the tracking did nothing would compare nothing.)
    assert!(moving > TICKS / 2, "{moving} ticks tracked");
}

#[test]
fn the_force_channels_add_j_transpose_of_c3_hand_plus_c5_contact() {
    let puma = DhArm::puma560();
    let q0 = DhArm::puma_nominal();
    let (state, reference) = tick(&puma, &q0, 2500);
    let Reference::Hybrid(h) = reference else {
        unreachable!()
    };
    let sensed = reading();
    let command = |c1: f64, c3: f64, c5: f64| {
        let mut s = FourChannelSlave::new(FourChannelSlaveConfig {
            c1,
            c3,
            c5,
            max_force: f64::INFINITY,
            max_torque: f64::INFINITY,
            sensor_mount: Some(mount()),
            // Soft enough that no joint meets its effort limit (a clipped sum is not a sum).
            tracking: TrackingConfig {
                kp: [100.0; 6],
                kd: [20.0; 6],
                ..TrackingConfig::default()
            },
        })
        .unwrap();
        s.activate(at(0), &JointState::at_rest(q0), &puma);
        let input = ControlInput {
            now: at(1),
            period: Duration::from_millis(1),
            state: &state,
            reference: &reference,
            wrench: Some(&sensed),
            model: &puma,
        };
        match s.update(&input) {
            Ok(JointCommand::Effort(t)) => (t, s.last_wrench().to_vector()),
            other => panic!("{other:?}"),
        }
    };
    // The contact at the tool, base frame, worked out by hand: the sensor's force and moment in
    // tool axes, the moment moved from the sensor's origin to the tool's, rotated into the base
    // and negated (the world's wrench on the robot).
    let tool = puma.forward(&state.position);
    let (p, r) = (mount().translation.vector, mount().rotation);
    let f_tool = r * sensed.force;
    let m_tool = r * sensed.torque + p.cross(&f_tool);
    let f_e = -(tool.rotation * f_tool);
    let m_e = -(tool.rotation * m_tool);
    let contact = Vector6::new(f_e.x, f_e.y, f_e.z, m_e.x, m_e.y, m_e.z);
    let hand = h.wrench.to_vector();
    let (c3, c5) = (0.5, 0.3);
    let (tracking_only, _) = command(1.0, 0.0, 0.0);
    let (both, added) = command(1.0, c3, c5);
    let expected = hand * c3 + contact * c5;
    assert!((added - expected).norm() < 1e-12, "{added} vs {expected}");
    let w = Wrench {
        force: Vector3::new(expected[0], expected[1], expected[2]),
        torque: Vector3::new(expected[3], expected[4], expected[5]),
        frame: Frame::Base,
    };
    let jt_f = puma.wrench_to_torques(&state.position, &w).unwrap();
    assert!(
        (both - tracking_only - jt_f).norm() < 1e-9,
        "{both} - {tracking_only} vs {jt_f}"
    );
    assert!(
        jt_f.norm() > 0.5,
        "the force channels add something: {jt_f}"
    );
    // c1 = 0: the position channel's feedback is gone, the model terms stay.
    let (slack, _) = command(0.0, 0.0, 0.0);
    let (weighted, _) = command(0.5, 0.0, 0.0);
    assert!((weighted - slack - (tracking_only - slack) * 0.5).norm() < 1e-6);
}

#[test]
fn missing_inputs_and_bad_coefficients_are_typed_errors() {
    let puma = DhArm::puma560();
    let q0 = DhArm::puma_nominal();
    let (state, hybrid) = tick(&puma, &q0, 100);
    let Reference::Hybrid(h) = hybrid else {
        unreachable!()
    };
    let cartesian = Reference::Cartesian(h.motion);
    let sensed = reading();
    let update =
        |config: FourChannelSlaveConfig, reference: &Reference, wrench: Option<&Wrench>| {
            let mut s = FourChannelSlave::new(config).unwrap();
            s.activate(at(0), &JointState::at_rest(q0), &puma);
            s.update(&ControlInput {
                now: at(1),
                period: Duration::from_millis(1),
                state: &state,
                reference,
                wrench,
                model: &puma,
            })
            .map(|_| ())
        };
    let c3 = FourChannelSlaveConfig {
        c3: 1.0,
        ..FourChannelSlaveConfig::default()
    };
    // C3 needs the operator's wrench: a master without a handle sensor sends only its pose.
    assert_eq!(
        update(c3, &cartesian, None),
        Err(ControllerError::MissingInput)
    );
    assert_eq!(update(c3, &hybrid, None), Ok(()));
    // C5 needs a reading, and for a sensor-frame reading the sensor's mount.
    let c5 = FourChannelSlaveConfig {
        c5: 0.5,
        ..FourChannelSlaveConfig::default()
    };
    assert_eq!(
        update(c5, &hybrid, None),
        Err(ControllerError::MissingInput)
    );
    assert_eq!(
        update(c5, &hybrid, Some(&sensed)),
        Err(ControllerError::MissingInput)
    );
    let mounted = FourChannelSlaveConfig {
        sensor_mount: Some(mount()),
        ..c5
    };
    assert_eq!(update(mounted, &hybrid, Some(&sensed)), Ok(()));
    for bad in [
        FourChannelSlaveConfig {
            c5: -1.0,
            ..FourChannelSlaveConfig::default()
        },
        FourChannelSlaveConfig {
            c3: f64::NAN,
            ..FourChannelSlaveConfig::default()
        },
        FourChannelSlaveConfig {
            c1: -0.5,
            ..FourChannelSlaveConfig::default()
        },
        FourChannelSlaveConfig {
            tracking: TrackingConfig {
                output: TrackingOutput::BoardServo,
                ..TrackingConfig::default()
            },
            ..c3
        },
    ] {
        assert!(FourChannelSlave::new(bad).is_err(), "{bad:?}");
    }
}
