//! Lawrence's four-channel master: the classical master laws are its special cases, sample for
//! sample (the same torques, to the last bit, on every tick of a run through contact-like
//! references with a moving master).

#[path = "teleop_model.rs"]
mod model;

use core::time::Duration;

use model::DhArm;
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use penelope_hal::{
    CartesianReference, ControlInput, Controller, ControllerError, Frame, HybridReference,
    JointCommand, JointState, JointVector, Kinematics, Pose, Reference, Timestamp, Twist, Wrench,
};
use penelope_rt_core::teleop::{
    ForceDisplay, ForceDisplayConfig, FourChannelConfig, FourChannelMaster, ImpedanceConfig,
    PositionErrorMaster,
};

const TICKS: usize = 5000;

fn at(k: usize) -> Timestamp {
    Timestamp::from_nanos(1_000_000_000 + k as u64 * 1_000_000)
}

/// Tick `k` of a run: the master moving on a loop, and the slave's sample as it reaches the
/// master (a pose lagging and offset from the master's, a wrench that rises in "contact" and
/// carries noise-like wiggles, sometimes expressed in the tool frame).
fn tick(frhc: &DhArm, q0: &JointVector, k: usize) -> (JointState, Reference) {
    let t = k as f64 * 1e-3;
    let mut q = *q0;
    let mut qd = JointVector::zeros();
    for j in 0..6 {
        let w = 1.0 + 0.37 * j as f64;
        q[j] += 0.05 * (w * t).sin();
        qd[j] = 0.05 * w * (w * t).cos();
    }
    let state = JointState {
        position: q,
        velocity: qd,
        effort: JointVector::zeros(),
    };
    let lag = frhc.forward(&{
        let mut ql = q;
        ql[0] -= 0.01 * (t * 3.0).sin();
        ql
    });
    let pose = Pose::from_parts(
        Translation3::from(lag.translation.vector + Vector3::new(0.002, -0.001, 0.003 * t.sin())),
        UnitQuaternion::from_euler_angles(0.01 * t.cos(), 0.0, 0.02) * lag.rotation,
    );
    let contact = (t - 1.5).clamp(0.0, 1.0) * 6.0;
    let wrench = Wrench {
        force: Vector3::new(
            0.3 * (17.0 * t).sin(),
            -0.2 * (11.0 * t).cos(),
            contact + 0.1 * (29.0 * t).sin(),
        ),
        torque: Vector3::new(0.01 * (7.0 * t).sin(), 0.02, -0.015 * (5.0 * t).cos()),
        frame: if k % 997 < 300 {
            Frame::Tool
        } else {
            Frame::Base
        },
    };
    let reference = Reference::Hybrid(HybridReference {
        motion: CartesianReference {
            pose,
            twist: Twist {
                linear: Vector3::new(0.01 * t.cos(), 0.0, -0.02),
                angular: Vector3::zeros(),
                frame: Frame::Base,
            },
        },
        wrench,
        force_axes: [true; 6],
    });
    (state, reference)
}

/// Runs `a` and `b` on the same ticks; every command must be identical.
fn same_commands(a: &mut dyn Controller, b: &mut dyn Controller) -> usize {
    let frhc = DhArm::frhc();
    let q0 = DhArm::frhc_home();
    let start = JointState::at_rest(q0);
    a.activate(at(0), &start, &frhc);
    b.activate(at(0), &start, &frhc);
    let mut nonzero = 0;
    for k in 0..TICKS {
        let (state, reference) = tick(&frhc, &q0, k);
        let input = ControlInput {
            now: at(k),
            period: Duration::from_millis(1),
            state: &state,
            reference: &reference,
            wrench: None,
            model: &frhc,
        };
        let (ca, cb) = (a.update(&input).unwrap(), b.update(&input).unwrap());
        assert_eq!(ca, cb, "tick {k}");
        assert_eq!(a.port_energy(), b.port_energy(), "tick {k}");
        if let JointCommand::Effort(t) = ca
            && (t - frhc_gravity(&frhc, &state)).norm() > 1e-3
        {
            nonzero += 1;
        }
    }
    nonzero
}

fn frhc_gravity(frhc: &DhArm, state: &JointState) -> JointVector {
    penelope_hal::Dynamics::gravity(frhc, &state.position)
}

#[test]
fn with_c2_one_it_is_the_force_display_sample_for_sample() {
    let display = ForceDisplayConfig::default();
    let mut classic = ForceDisplay::new(display).unwrap();
    let mut general = FourChannelMaster::new(FourChannelConfig::force_position(display)).unwrap();
    let active = same_commands(&mut classic, &mut general);
    // (A run that displayed nothing would compare nothing.)
    assert!(active > TICKS / 2, "{active} ticks displayed a force");
}

#[test]
fn with_c4_one_it_is_the_position_error_master_sample_for_sample() {
    let spring = ImpedanceConfig::master();
    let mut classic = PositionErrorMaster::new(spring).unwrap();
    let mut general = FourChannelMaster::new(FourChannelConfig::position_error(spring)).unwrap();
    let active = same_commands(&mut classic, &mut general);
    assert!(active > TICKS / 2, "{active} ticks displayed a force");
}

/// Both channels at once are neither law: the command differs from each, and it is their sum
/// (uncapped here) less the local damping.
#[test]
fn both_channels_add_and_c6_feeds_the_operator_wrench_back() {
    let frhc = DhArm::frhc();
    let q0 = DhArm::frhc_home();
    let (state, reference) = tick(&frhc, &q0, 2500);
    let display = ForceDisplayConfig {
        filter_cutoff_hz: 0.0,
        force_deadband: 0.0,
        torque_deadband: 0.0,
        max_force: f64::INFINITY,
        max_torque: f64::INFINITY,
        ..ForceDisplayConfig::default()
    };
    let spring = ImpedanceConfig {
        max_force: f64::INFINITY,
        max_torque: f64::INFINITY,
        ..ImpedanceConfig::master()
    };
    let wrench_of = |config: FourChannelConfig, hand: Option<&Wrench>| {
        let mut m = FourChannelMaster::new(config).unwrap();
        m.activate(at(0), &JointState::at_rest(q0), &frhc);
        let input = ControlInput {
            now: at(1),
            period: Duration::from_millis(1),
            state: &state,
            reference: &reference,
            wrench: hand,
            model: &frhc,
        };
        m.update(&input).map(|_| m.last_wrench().to_vector())
    };
    let force = FourChannelConfig {
        spring,
        ..FourChannelConfig::force_position(display)
    };
    let both = FourChannelConfig { c4: 1.0, ..force };
    let position = FourChannelConfig {
        display,
        ..FourChannelConfig::position_error(spring)
    };
    let (f_force, f_both) = (
        wrench_of(force, None).unwrap(),
        wrench_of(both, None).unwrap(),
    );
    let f_position = wrench_of(
        FourChannelConfig {
            display: ForceDisplayConfig {
                damping: [0.0; 6],
                ..display
            },
            ..position
        },
        None,
    )
    .unwrap();
    // both = force channel (with the local damping) + position channel.
    assert!(
        (f_both - (f_force + f_position)).norm() < 1e-9,
        "{f_both} vs {f_force} + {f_position}"
    );
    assert!((f_both - f_force).norm() > 0.1 && (f_both - f_position).norm() > 0.1);
    // C6 without a wrench on the handle is a missing input, not a silent zero.
    let c6 = FourChannelConfig { c6: 0.5, ..force };
    assert_eq!(wrench_of(c6, None), Err(ControllerError::MissingInput));
    let hand = Wrench {
        force: Vector3::new(2.0, 0.0, 0.0),
        torque: Vector3::zeros(),
        frame: Frame::Base,
    };
    let f_c6 = wrench_of(c6, Some(&hand)).unwrap();
    assert!((f_c6 - f_force - hand.to_vector() * 0.5).norm() < 1e-9);
    // A coefficient that is not a number is refused.
    assert!(
        FourChannelMaster::new(FourChannelConfig {
            c2: f64::NAN,
            ..force
        })
        .is_err()
    );
}
