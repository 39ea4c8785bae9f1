//! Control laws: impedance, slave tracking, force display, position-error master, passivity.
//!
//! The plants are the test models of `teleop_model.rs` (PUMA 560 parameters from the reference,
//! the FRHC working model), integrated at 4 kHz under a 1 kHz controller.

#[path = "teleop_model.rs"]
mod model;

use core::time::Duration;

use model::DhArm;
use nalgebra::{Translation3, UnitQuaternion, Vector3, Vector6};
use penelope_hal::{
    CartesianReference, ControlInput, Controller, ControllerError, Frame, HybridReference,
    JacobianFrame, JointCommand, JointReference, JointState, JointVector, Kinematics,
    KinematicsError, Pose, Reference, RobotModel, Timestamp, Trajectory, Twist, Wrench,
};
use penelope_hal::{Dynamics, InverseKinematics};
use penelope_rt_core::teleop::{
    CartesianImpedance, ChannelConfig, ChannelDirection, ForceDisplay, ForceDisplayConfig,
    ImpedanceConfig, MappingConfig, PassivityObserver, PositionErrorMaster, SlaveTracking,
    TeleopChannel, TeleopSample, TrackingConfig,
};
use penelope_rt_core::trajectory::{CartesianLimits, Trapezoidal};

const PERIOD: Duration = Duration::from_millis(1);
const DT: f64 = 1e-3;

fn at(k: usize) -> Timestamp {
    Timestamp::from_nanos(1_000_000_000 + k as u64 * 1_000_000)
}

fn cart(pose: Pose, twist: Twist) -> Reference {
    Reference::Cartesian(CartesianReference { pose, twist })
}

fn still(pose: Pose) -> Reference {
    cart(pose, Twist::default())
}

fn input<'a>(
    k: usize,
    state: &'a JointState,
    reference: &'a Reference,
    model: &'a dyn RobotModel,
) -> ControlInput<'a> {
    ControlInput {
        now: at(k),
        period: PERIOD,
        state,
        reference,
        wrench: None,
        model,
    }
}

fn effort(c: JointCommand) -> JointVector {
    match c {
        JointCommand::Effort(t) => t,
        other => panic!("expected torques, got {other:?}"),
    }
}

fn shifted(p: &Pose, d: Vector3<f64>) -> Pose {
    Pose::from_parts((p.translation.vector + d).into(), p.rotation)
}

fn puma_q() -> JointVector {
    let mut q = DhArm::puma_nominal();
    q[0] = 0.2;
    q[3] = 0.3;
    q
}

#[test]
fn impedance_with_zero_error_commands_gravity_only() {
    let arm = DhArm::puma560();
    let q = puma_q();
    let state = JointState::at_rest(q);
    let r = still(arm.forward(&q));
    let mut imp = CartesianImpedance::new(ImpedanceConfig::default()).unwrap();
    assert_eq!(imp.kind(), "cartesian-impedance");
    imp.activate(at(0), &state, &arm);
    let tau = effort(imp.update(&input(0, &state, &r, &arm)).unwrap());
    assert!((tau - arm.gravity(&q)).norm() < 1e-9, "{tau}");
    let mut no_g = CartesianImpedance::new(ImpedanceConfig {
        gravity_compensation: false,
        ..Default::default()
    })
    .unwrap();
    no_g.activate(at(0), &state, &arm);
    assert!(effort(no_g.update(&input(0, &state, &r, &arm)).unwrap()).norm() < 1e-9);
}

#[test]
fn impedance_pulls_toward_the_reference_and_hybrid_axes_take_the_wrench() {
    let arm = DhArm::puma560();
    let q = puma_q();
    let state = JointState::at_rest(q);
    let pose = arm.forward(&q);
    let mut imp = CartesianImpedance::new(ImpedanceConfig::default()).unwrap();
    imp.activate(at(0), &state, &arm);
    // 1 cm along x at 2000 N/m: 20 N along x, and tau = J^T F + g.
    let r = still(shifted(&pose, Vector3::new(0.01, 0.0, 0.0)));
    let tau = effort(imp.update(&input(0, &state, &r, &arm)).unwrap());
    let f = imp.last_wrench();
    assert!((f.force - Vector3::new(20.0, 0.0, 0.0)).norm() < 1e-9);
    assert!(f.torque.norm() < 1e-9);
    let jt_f = arm.jacobian(&q, JacobianFrame::Base).transpose() * f.to_vector();
    assert!((tau - jt_f - arm.gravity(&q)).norm() < 1e-9);
    // Hybrid, base frame: z is force-controlled at -5 N, x stays a spring.
    let h = Reference::Hybrid(HybridReference {
        motion: CartesianReference {
            pose: shifted(&pose, Vector3::new(0.01, 0.0, 0.02)),
            twist: Twist::default(),
        },
        wrench: Wrench {
            force: Vector3::new(0.0, 0.0, -5.0),
            torque: Vector3::zeros(),
            frame: Frame::Base,
        },
        force_axes: [false, false, true, false, false, false],
    });
    imp.update(&input(1, &state, &h, &arm)).unwrap();
    let f = imp.last_wrench();
    assert!((f.force - Vector3::new(20.0, 0.0, -5.0)).norm() < 1e-9);
    // Hybrid, tool frame: the tool z component is the wrench's.
    let h = Reference::Hybrid(HybridReference {
        motion: CartesianReference {
            pose: shifted(&pose, Vector3::new(0.01, -0.01, 0.02)),
            twist: Twist::default(),
        },
        wrench: Wrench {
            force: Vector3::new(0.0, 0.0, 3.0),
            torque: Vector3::zeros(),
            frame: Frame::Tool,
        },
        force_axes: [false, false, true, false, false, false],
    });
    imp.update(&input(2, &state, &h, &arm)).unwrap();
    let f_tool = pose.rotation.inverse() * imp.last_wrench().force;
    assert!((f_tool.z - 3.0).abs() < 1e-9, "{f_tool}");
}

#[test]
fn every_controller_starts_without_a_jump() {
    let puma = DhArm::puma560();
    let frhc = DhArm::frhc();
    let qp = puma_q();
    let qm = DhArm::frhc_home();
    let ps = JointState::at_rest(qp);
    let pm = JointState::at_rest(qm);
    let rs = still(puma.forward(&qp));
    let rm = still(frhc.forward(&qm));
    let gp = puma.gravity(&qp);
    let gm = frhc.gravity(&qm);

    let mut imp = CartesianImpedance::new(ImpedanceConfig::default()).unwrap();
    imp.activate(at(0), &ps, &puma);
    assert!((effort(imp.update(&input(0, &ps, &rs, &puma)).unwrap()) - gp).norm() < 1e-9);

    let mut trk = SlaveTracking::new(TrackingConfig::default()).unwrap();
    trk.activate(at(0), &ps, &puma);
    assert!((effort(trk.update(&input(0, &ps, &rs, &puma)).unwrap()) - gp).norm() < 1e-6);

    let mut pem = PositionErrorMaster::new(ImpedanceConfig::master()).unwrap();
    pem.activate(at(0), &pm, &frhc);
    assert!((effort(pem.update(&input(0, &pm, &rm, &frhc)).unwrap()) - gm).norm() < 1e-9);

    // The force display starts from zero and fades a sudden 8 N in through its filter.
    let mut fd = ForceDisplay::new(ForceDisplayConfig::default()).unwrap();
    fd.activate(at(0), &pm, &frhc);
    let w = Reference::Wrench(Wrench {
        force: Vector3::new(8.0, 0.0, 0.0),
        torque: Vector3::zeros(),
        frame: Frame::Base,
    });
    let mut last = 0.0;
    for k in 0..200 {
        fd.update(&input(k, &pm, &w, &frhc)).unwrap();
        let shown = fd.last_wrench().force.x;
        assert!(shown >= last - 1e-12);
        if k == 0 {
            assert!(shown < 0.2 * 8.0, "first tick shows {shown} N");
        }
        assert!(shown - last < 0.2 * 8.0);
        last = shown;
    }
    assert!(
        (last - 7.8).abs() < 1e-3,
        "settles at 8 N minus the 0.2 N band: {last}"
    );

    // Re-activation while moving: the slave tracker takes the measured motion as its reference.
    let mut moving = ps;
    moving.velocity = JointVector::from_column_slice(&[0.2, -0.1, 0.3, 0.0, 0.1, 0.0]);
    let v = puma.jacobian(&qp, JacobianFrame::Base) * moving.velocity;
    let twist = Twist {
        linear: v.fixed_rows::<3>(0).into(),
        angular: v.fixed_rows::<3>(3).into(),
        frame: Frame::Base,
    };
    let r = cart(puma.forward(&qp), twist);
    trk.activate(at(10), &moving, &puma);
    let tau = effort(trk.update(&input(10, &moving, &r, &puma)).unwrap());
    let bias = puma.inverse_dynamics(&qp, &moving.velocity, &JointVector::zeros())
        - puma.friction(&moving.velocity);
    // Only the DLS damping (lambda = 0.01) separates J^+ J qd from qd.
    assert!((tau - bias).norm() < 0.5, "{}", tau - bias);
}

#[test]
fn force_display_caps_the_whole_wrench_and_keeps_its_direction() {
    let frhc = DhArm::frhc();
    let q = DhArm::frhc_home();
    let state = JointState::at_rest(q);
    let cfg = ForceDisplayConfig {
        force_deadband: 0.0,
        torque_deadband: 0.0,
        damping: [0.0; 6],
        filter_cutoff_hz: 0.0,
        ..Default::default()
    };
    let mut fd = ForceDisplay::new(cfg).unwrap();
    assert_eq!(fd.kind(), "force-display");
    fd.activate(at(0), &state, &frhc);
    // Force-limited: 50 N along (1, 2, 3) with 0.2 N·m: everything scaled by 10/50.
    let dir = Vector3::new(1.0, 2.0, 3.0).normalize();
    let w = Wrench {
        force: dir * 50.0,
        torque: Vector3::new(0.0, 0.0, 0.2),
        frame: Frame::Base,
    };
    let tau = effort(
        fd.update(&input(0, &state, &Reference::Wrench(w), &frhc))
            .unwrap(),
    );
    let shown = *fd.last_wrench();
    assert!((shown.force.norm() - 10.0).abs() < 1e-9);
    assert!(shown.force.normalize().cross(&dir).norm() < 1e-12);
    assert!((shown.torque - Vector3::new(0.0, 0.0, 0.04)).norm() < 1e-12);
    assert!((fd.saturation() - 0.2).abs() < 1e-12);
    let jt_f = frhc.jacobian(&q, JacobianFrame::Base).transpose() * shown.to_vector();
    assert!((tau - jt_f - frhc.gravity(&q)).norm() < 1e-9);
    // Torque-limited: 2 N·m against a 0.5 N·m cap scales the 1 N force by a quarter too.
    let w = Wrench {
        force: Vector3::new(0.0, 1.0, 0.0),
        torque: Vector3::new(2.0, 0.0, 0.0),
        frame: Frame::Base,
    };
    fd.update(&input(1, &state, &Reference::Wrench(w), &frhc))
        .unwrap();
    let shown = fd.last_wrench();
    assert!((shown.torque - Vector3::new(0.5, 0.0, 0.0)).norm() < 1e-12);
    assert!((shown.force - Vector3::new(0.0, 0.25, 0.0)).norm() < 1e-12);
}

#[test]
fn force_display_dead_band_and_damping() {
    let frhc = DhArm::frhc();
    let q = DhArm::frhc_home();
    let state = JointState::at_rest(q);
    let mut fd = ForceDisplay::new(ForceDisplayConfig::default()).unwrap();
    fd.activate(at(0), &state, &frhc);
    let small = Reference::Wrench(Wrench {
        force: Vector3::new(0.1, -0.1, 0.05),
        torque: Vector3::new(0.005, 0.0, 0.0),
        frame: Frame::Base,
    });
    for k in 0..300 {
        let tau = effort(fd.update(&input(k, &state, &small, &frhc)).unwrap());
        assert!((tau - frhc.gravity(&q)).norm() < 1e-12);
    }
    // Moving with nothing to display: the added damping opposes the motion.
    let mut moving = state;
    moving.velocity = JointVector::from_column_slice(&[0.5, -0.3, 0.2, 0.0, 0.0, 0.0]);
    let zero = Reference::Wrench(Wrench::zero(Frame::Base));
    fd.activate(at(0), &moving, &frhc);
    fd.update(&input(0, &moving, &zero, &frhc)).unwrap();
    let v = frhc.jacobian(&q, JacobianFrame::Base) * moving.velocity;
    let f = fd.last_wrench().to_vector();
    assert!(f.dot(&v) < 0.0);
    assert!((f.fixed_rows::<3>(0) + v.fixed_rows::<3>(0) * 2.0).norm() < 1e-12);
    // The damper takes energy from the operator: the observer sees a passive port.
    assert!(fd.passivity().energy() > 0.0);
}

#[test]
fn force_display_shows_zero_at_once_when_the_slave_sends_no_wrench() {
    let frhc = DhArm::frhc();
    let q = DhArm::frhc_home();
    let state = JointState::at_rest(q);
    let mut fd = ForceDisplay::new(ForceDisplayConfig::default()).unwrap();
    fd.activate(at(0), &state, &frhc);
    let motion = CartesianReference {
        pose: frhc.forward(&q),
        twist: Twist::default(),
    };
    let pushing = Wrench {
        force: Vector3::new(0.0, 0.0, 4.0),
        torque: Vector3::zeros(),
        frame: Frame::Base,
    };
    let hybrid = |wrench, force_axes| {
        Reference::Hybrid(HybridReference {
            motion,
            wrench,
            force_axes,
        })
    };
    let contact = hybrid(pushing, [true; 6]);
    for k in 0..300 {
        fd.update(&input(k, &state, &contact, &frhc)).unwrap();
    }
    assert!(
        (fd.last_wrench().force.z - 4.0 + 0.2).abs() < 0.01,
        "{:?}",
        fd.last_wrench()
    );
    // A zero wrench fades through the 30 Hz filter: most of the force is still shown.
    let mut fading = fd;
    fading
        .update(&input(
            300,
            &state,
            &hybrid(Wrench::zero(Frame::Base), [true; 6]),
            &frhc,
        ))
        .unwrap();
    assert!(fading.last_wrench().force.z > 2.5);
    // No wrench at all (no force axis: the slave's sensor failed): zero at the next tick, and
    // gravity alone on the motors.
    let none = hybrid(pushing, [false; 6]);
    let tau = effort(fd.update(&input(300, &state, &none, &frhc)).unwrap());
    assert_eq!(fd.last_wrench().force.norm(), 0.0);
    assert!((tau - frhc.gravity(&q)).norm() < 1e-12);
    // When the wrench comes back, it fades in from zero (no jump to what was shown before).
    fd.update(&input(301, &state, &contact, &frhc)).unwrap();
    let back = fd.last_wrench().force.z;
    assert!(back > 0.0 && back < 1.0, "{back}");
}

#[test]
fn position_error_master_springs_toward_the_slave_and_is_capped() {
    let frhc = DhArm::frhc();
    let q = DhArm::frhc_home();
    let state = JointState::at_rest(q);
    let pose = frhc.forward(&q);
    let mut pem = PositionErrorMaster::new(ImpedanceConfig::master()).unwrap();
    assert_eq!(pem.kind(), "position-error-master");
    pem.activate(at(0), &state, &frhc);
    let r = still(shifted(&pose, Vector3::new(0.0, 0.005, 0.0)));
    pem.update(&input(0, &state, &r, &frhc)).unwrap();
    assert!((pem.last_wrench().force - Vector3::new(0.0, 5.0, 0.0)).norm() < 1e-9);
    // The slave's samples come as hybrid references (its pose and its sensed wrench): the
    // spring follows the pose, the wrench is not this law's to show (it once replaced the
    // spring, every axis being a force axis, and position-error displayed the slave's force).
    let Reference::Cartesian(motion) = r else {
        unreachable!()
    };
    let hybrid = Reference::Hybrid(penelope_hal::HybridReference {
        motion,
        wrench: Wrench {
            force: Vector3::new(7.0, 0.0, 0.0),
            torque: Vector3::zeros(),
            frame: Frame::Base,
        },
        force_axes: [true; 6],
    });
    pem.update(&input(0, &state, &hybrid, &frhc)).unwrap();
    assert!((pem.last_wrench().force - Vector3::new(0.0, 5.0, 0.0)).norm() < 1e-9);
    let far = still(shifted(&pose, Vector3::new(0.0, 0.1, -0.1)));
    let tau = effort(pem.update(&input(1, &state, &far, &frhc)).unwrap());
    let f = pem.last_wrench().force;
    assert!((f.norm() - 10.0).abs() < 1e-9);
    assert!(
        f.normalize()
            .cross(&Vector3::new(0.0, 1.0, -1.0).normalize())
            .norm()
            < 1e-12
    );
    // Within the FRHC's joint torque envelope (plus its gravity load).
    let g = frhc.gravity(&q);
    for j in 0..6 {
        assert!(
            (tau[j] - g[j]).abs() <= frhc.limits.effort_max[j] * 1.5,
            "joint {j}"
        );
    }
}

#[test]
fn controllers_refuse_what_they_cannot_follow() {
    let puma = DhArm::puma560();
    let q = puma_q();
    let state = JointState::at_rest(q);
    let w = Reference::Wrench(Wrench::zero(Frame::Base));
    let j = Reference::Joint(JointReference::default());
    let c = still(puma.forward(&q));
    let mut imp = CartesianImpedance::new(ImpedanceConfig::default()).unwrap();
    let mut trk = SlaveTracking::new(TrackingConfig::default()).unwrap();
    let mut fd = ForceDisplay::new(ForceDisplayConfig::default()).unwrap();
    let mut pem = PositionErrorMaster::new(ImpedanceConfig::master()).unwrap();
    imp.activate(at(0), &state, &puma);
    trk.activate(at(0), &state, &puma);
    fd.activate(at(0), &state, &puma);
    pem.activate(at(0), &state, &puma);
    let unsupported = Err(ControllerError::UnsupportedReference);
    assert_eq!(imp.update(&input(0, &state, &w, &puma)), unsupported);
    assert_eq!(imp.update(&input(0, &state, &j, &puma)), unsupported);
    assert_eq!(trk.update(&input(0, &state, &w, &puma)), unsupported);
    assert_eq!(fd.update(&input(0, &state, &c, &puma)), unsupported);
    assert_eq!(pem.update(&input(0, &state, &w, &puma)), unsupported);
    let sensor = Reference::Wrench(Wrench::zero(Frame::Sensor));
    assert_eq!(fd.update(&input(0, &state, &sensor, &puma)), unsupported);
    let mut nan = state;
    nan.velocity[2] = f64::NAN;
    let non_finite = Err(ControllerError::NonFinite);
    assert_eq!(imp.update(&input(0, &nan, &c, &puma)), non_finite);
    assert_eq!(trk.update(&input(0, &nan, &c, &puma)), non_finite);
    assert_eq!(fd.update(&input(0, &nan, &w, &puma)), non_finite);
    assert_eq!(pem.update(&input(0, &nan, &c, &puma)), non_finite);
    // Bad configurations are typed errors.
    assert!(
        CartesianImpedance::new(ImpedanceConfig {
            stiffness: [-1.0; 6],
            ..Default::default()
        })
        .is_err()
    );
    assert!(
        SlaveTracking::new(TrackingConfig {
            friction_compensation: 1.5,
            ..Default::default()
        })
        .is_err()
    );
    assert!(
        ForceDisplay::new(ForceDisplayConfig {
            max_force: f64::NAN,
            ..Default::default()
        })
        .is_err()
    );
}

/// A small deterministic generator for random states.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
    fn vec(&mut self, scale: f64) -> JointVector {
        JointVector::from_fn(|_, _| self.next() * scale)
    }
}

#[test]
fn commands_stay_finite_and_bounded_over_random_states() {
    let puma = DhArm::puma560();
    let frhc = DhArm::frhc();
    let mut rng = Lcg(7);
    let mut trk = SlaveTracking::new(TrackingConfig::default()).unwrap();
    let mut fd = ForceDisplay::new(ForceDisplayConfig::default()).unwrap();
    let mut pem = PositionErrorMaster::new(ImpedanceConfig::master()).unwrap();
    let mut imp = CartesianImpedance::new(ImpedanceConfig::default()).unwrap();
    for k in 0..300 {
        let sp = JointState {
            position: puma_q() + rng.vec(0.3),
            velocity: rng.vec(3.0),
            effort: JointVector::zeros(),
        };
        let sm = JointState {
            position: DhArm::frhc_home() + rng.vec(0.3),
            velocity: rng.vec(3.0),
            effort: JointVector::zeros(),
        };
        if k % 50 == 0 {
            trk.activate(at(k), &sp, &puma);
            fd.activate(at(k), &sm, &frhc);
            pem.activate(at(k), &sm, &frhc);
            imp.activate(at(k), &sp, &puma);
        }
        let target = shifted(
            &puma.forward(&(puma_q() + rng.vec(0.3))),
            Vector3::new(rng.next(), rng.next(), rng.next()) * 0.05,
        );
        let twist = Twist {
            linear: Vector3::new(rng.next(), rng.next(), rng.next()),
            angular: Vector3::new(rng.next(), rng.next(), rng.next()),
            frame: Frame::Base,
        };
        let r = cart(target, twist);
        let tau = effort(trk.update(&input(k, &sp, &r, &puma)).unwrap());
        for j in 0..6 {
            assert!(tau[j].is_finite() && tau[j].abs() <= puma.limits.effort_max[j] + 1e-9);
        }
        assert!(
            effort(imp.update(&input(k, &sp, &r, &puma)).unwrap())
                .iter()
                .all(|x| x.is_finite())
        );
        let w = Reference::Wrench(Wrench {
            force: Vector3::new(rng.next(), rng.next(), rng.next()) * 1000.0,
            torque: Vector3::new(rng.next(), rng.next(), rng.next()) * 100.0,
            frame: Frame::Base,
        });
        fd.update(&input(k, &sm, &w, &frhc)).unwrap();
        let shown = fd.last_wrench();
        assert!(shown.force.norm() <= 10.0 + 1e-9 && shown.torque.norm() <= 0.5 + 1e-9);
        let rm = still(shifted(
            &frhc.forward(&DhArm::frhc_home()),
            Vector3::new(rng.next(), rng.next(), rng.next()) * 0.2,
        ));
        pem.update(&input(k, &sm, &rm, &frhc)).unwrap();
        let shown = pem.last_wrench();
        assert!(shown.force.norm() <= 10.0 + 1e-9 && shown.torque.norm() <= 0.5 + 1e-9);
    }
}

#[test]
fn passivity_observer_signs() {
    let dt = 1e-3;
    let w = 2.0 * std::f64::consts::PI;
    let v = |k: usize| (w * k as f64 * dt).cos() * 0.1;
    let mut damper = PassivityObserver::new();
    let mut active = PassivityObserver::new();
    let mut spring = PassivityObserver::new();
    let mut x = 0.0;
    let mut prev = 0.0;
    for k in 0..2000 {
        let vk = v(k);
        damper.observe_scalar(dt, 5.0 * vk, vk);
        active.observe_scalar(dt, -5.0 * vk, vk);
        spring.observe_scalar(dt, 100.0 * x, vk);
        x += vk * dt;
        assert!(damper.energy() >= prev);
        prev = damper.energy();
    }
    assert!(damper.is_passive(0.0) && damper.energy() > 0.04);
    assert!(!active.is_passive(0.0) && active.energy() < -0.04);
    // A spring stores and returns: about zero after whole cycles.
    assert!(spring.energy().abs() < 1e-3, "{}", spring.energy());
    assert_eq!(damper.samples(), 2000);
    // NaN does not poison the observer.
    damper.observe_scalar(dt, f64::NAN, 1.0);
    assert!(damper.energy().is_finite());
}

/// The master moves along x kinematically (the state is set, not simulated) while the display
/// shows a virtual wall `F = -k x` delayed by 50 ms: the delay makes the wall active, and the
/// display's observer catches it. (The two-port controller that then keeps it passive is tested
/// in rt-core's passivity unit tests and, on the running channel, in the supervisor's.)
fn delayed_wall() -> (f64, f64) {
    let frhc = DhArm::frhc();
    let q0 = DhArm::frhc_home();
    let p0 = frhc.forward(&q0);
    let cfg = ForceDisplayConfig {
        force_deadband: 0.0,
        damping: [0.0; 6],
        filter_cutoff_hz: 0.0,
        ..Default::default()
    };
    let mut fd = ForceDisplay::new(cfg).unwrap();
    let mut state = JointState::at_rest(q0);
    fd.activate(at(0), &state, &frhc);
    let (amp, w, k_wall, delay) = (0.03, 2.0 * std::f64::consts::PI * 2.0, 300.0, 50);
    let x = |k: usize| amp * (w * k as f64 * DT).sin();
    let mut q = q0;
    let mut min_e: f64 = 0.0;
    for k in 0..2000 {
        let target = shifted(&p0, Vector3::new(x(k), 0.0, 0.0));
        q = frhc.inverse_near(&target, &q).unwrap();
        let v = Vector6::new(amp * w * (w * k as f64 * DT).cos(), 0.0, 0.0, 0.0, 0.0, 0.0);
        let jac = frhc.jacobian(&q, JacobianFrame::Base);
        state.position = q;
        state.velocity = jac.fixed_columns::<6>(0).lu().solve(&v).unwrap();
        let x_seen = if k >= delay { x(k - delay) } else { 0.0 };
        let wall = Reference::Wrench(Wrench {
            force: Vector3::new(-k_wall * x_seen, 0.0, 0.0),
            torque: Vector3::zeros(),
            frame: Frame::Base,
        });
        fd.update(&input(k, &state, &wall, &frhc)).unwrap();
        min_e = min_e.min(fd.passivity().energy());
    }
    (fd.passivity().energy(), min_e)
}

#[test]
fn a_delayed_wall_is_caught_by_the_observer() {
    let (e, min_e) = delayed_wall();
    assert!(e < -0.01, "delayed wall should be active: E = {e}");
    assert!(min_e <= e);
}

#[test]
fn slave_tracking_converges_on_a_trapezoidal_move() {
    // The plant qdd = M^-1 (tau - h), without friction (see the tracking tests for friction).
    let mut plant = DhArm::puma560();
    plant.friction_scale = 0.0;
    let q0 = puma_q();
    let mut state = JointState::at_rest(q0);
    let p0 = plant.forward(&q0);
    let goal = Pose::from_parts(
        Translation3::from(p0.translation.vector + Vector3::new(0.05, -0.03, 0.04)),
        UnitQuaternion::from_euler_angles(0.1, -0.05, 0.1) * p0.rotation,
    );
    let mut traj = Trapezoidal::cartesian(goal, CartesianLimits::default()).unwrap();
    traj.start(at(0), &still(p0));
    let mut trk = SlaveTracking::new(TrackingConfig::default()).unwrap();
    trk.activate(at(0), &state, &plant);
    let mut worst: f64 = 0.0;
    for k in 0..2500 {
        let r = traj.reference(at(k)).unwrap();
        let tau = effort(trk.update(&input(k, &state, &r, &plant)).unwrap());
        let Reference::Cartesian(c) = r else {
            unreachable!()
        };
        worst = worst.max((plant.position(&state.position) - c.pose.translation.vector).norm());
        plant.step(&mut state, &tau, DT, 4);
    }
    let end = plant.forward(&state.position);
    let err = (end.translation.vector - goal.translation.vector).norm();
    assert!(err < 1e-4, "final error {err} m");
    assert!(end.rotation.angle_to(&goal.rotation) < 1e-3);
    assert!(worst < 1e-3, "worst tracking error {worst} m");
    assert_eq!(trk.ik_failures(), 0);
}

/// The slave follows a master moving on a loop of `amp` metres at `freq` Hz, through a
/// `MasterToSlave` channel at 1 kHz, on a PUMA plant with friction and torque limits. Returns
/// (RMS, max) position error after the first second, m.
fn track_master(freq: f64, amp: f64, seconds: f64, controller_model: &DhArm) -> (f64, f64) {
    let plant = DhArm::puma560();
    let q0 = puma_q();
    let mut state = JointState::at_rest(q0);
    let master0 = Pose::from_parts(
        Translation3::new(0.0, 0.25, 0.1),
        UnitQuaternion::from_euler_angles(0.0, 0.3, 0.0),
    );
    let w = 2.0 * std::f64::consts::PI * freq;
    let master = |t: f64| {
        // Fade the loop in over the first half second so the motion starts at rest.
        let s = (t / 0.5).min(1.0);
        let e = s * s * (3.0 - 2.0 * s);
        let d = Vector3::new(0.3 * (w * t).sin(), (w * t).sin(), 1.0 - (w * t).cos()) * (amp * e);
        let rot = UnitQuaternion::from_euler_angles(0.05 * e * (w * t).sin(), 0.0, 0.0);
        Pose::from_parts(
            (master0.translation.vector + d).into(),
            rot * master0.rotation,
        )
    };
    let mut channel = TeleopChannel::new(ChannelConfig {
        direction: ChannelDirection::MasterToSlave,
        mapping: MappingConfig::default(),
        ..Default::default()
    })
    .unwrap();
    channel.start(at(0), &still(plant.forward(&q0)));
    let mut trk = SlaveTracking::new(TrackingConfig::default()).unwrap();
    trk.activate(at(0), &state, controller_model);
    let n = (seconds / DT) as usize;
    let (mut sum2, mut count, mut worst) = (0.0, 0usize, 0.0_f64);
    for k in 0..n {
        let t = k as f64 * DT;
        channel
            .receive(TeleopSample::new(k as u64, at(k), still(master(t))))
            .unwrap();
        let r = channel.reference(at(k)).unwrap();
        let tau = effort(trk.update(&input(k, &state, &r, controller_model)).unwrap());
        let Reference::Cartesian(c) = r else {
            unreachable!()
        };
        let e = (plant.position(&state.position) - c.pose.translation.vector).norm();
        if t >= 1.0 {
            sum2 += e * e;
            count += 1;
            worst = worst.max(e);
        }
        plant.step(&mut state, &tau, DT, 4);
    }
    assert_eq!(trk.ik_failures(), 0);
    ((sum2 / count as f64).sqrt(), worst)
}

#[test]
fn slave_tracking_follows_the_master_within_2_mm_rms() {
    let exact = DhArm::puma560();
    for (freq, seconds, amp) in [
        (0.2, 6.0, 0.03),
        (1.0, 4.0, 0.03),
        (2.0, 3.0, 0.03),
        (2.0, 3.0, 0.05),
    ] {
        let (rms, max) = track_master(freq, amp, seconds, &exact);
        println!(
            "exact model, {freq} Hz, {} cm: RMS {:.3} mm, max {:.3} mm",
            amp * 100.0,
            rms * 1e3,
            max * 1e3
        );
        assert!(rms < 2e-3, "{freq} Hz: RMS {rms} m");
    }
}

#[test]
fn slave_tracking_tolerates_model_error() {
    // The controller's model: masses 15 % low, friction 30 % low.
    let mut wrong = DhArm::puma560();
    wrong.mass_scale = 0.85;
    wrong.friction_scale = 0.7;
    let (rms, max) = track_master(2.0, 0.05, 3.0, &wrong);
    println!(
        "mismatched model, 2 Hz, 5 cm: RMS {:.3} mm, max {:.3} mm",
        rms * 1e3,
        max * 1e3
    );
    assert!(rms < 2e-3, "RMS {rms} m");
}

#[test]
fn slave_tracking_holds_on_unreachable_references() {
    let puma = DhArm::puma560();
    let q = puma_q();
    let state = JointState::at_rest(q);
    let far = still(shifted(&puma.forward(&q), Vector3::new(3.0, 0.0, 0.0)));
    let mut trk = SlaveTracking::new(TrackingConfig::default()).unwrap();
    trk.activate(at(0), &state, &puma);
    let tau = effort(trk.update(&input(0, &state, &far, &puma)).unwrap());
    assert_eq!(trk.ik_failures(), 1);
    assert!((tau - puma.gravity(&q)).norm() < 1e-6, "holds where it is");
    assert_eq!(trk.joint_reference(), &q);
    let mut strict = SlaveTracking::new(TrackingConfig {
        hold_on_ik_failure: false,
        ..Default::default()
    })
    .unwrap();
    strict.activate(at(0), &state, &puma);
    assert!(matches!(
        strict.update(&input(0, &state, &far, &puma)),
        Err(ControllerError::Kinematics(
            KinematicsError::Unreachable | KinematicsError::Singular
        ))
    ));
}

#[test]
fn position_error_pair_couples_master_and_slave() {
    // Position-error on the PUMA side: a CartesianImpedance toward the mapped master pose pulls
    // a (frictionless) slave plant to the master's displacement.
    let mut plant = DhArm::puma560();
    plant.friction_scale = 0.0;
    let q0 = puma_q();
    let mut state = JointState::at_rest(q0);
    let p0 = plant.forward(&q0);
    let mut imp = CartesianImpedance::new(ImpedanceConfig {
        ramp_in: Duration::from_millis(100),
        ..Default::default()
    })
    .unwrap();
    imp.activate(at(0), &state, &plant);
    let goal = shifted(&p0, Vector3::new(0.0, 0.01, 0.005));
    let r = still(goal);
    let first = effort(imp.update(&input(0, &state, &r, &plant)).unwrap());
    // The stiffness ramps in: the first tick is the gravity torque.
    assert!((first - plant.gravity(&q0)).norm() < 1e-9);
    for k in 0..3000 {
        let tau = effort(imp.update(&input(k, &state, &r, &plant)).unwrap());
        plant.step(&mut state, &tau, DT, 4);
    }
    let err = (plant.position(&state.position) - goal.translation.vector).norm();
    assert!(err < 2e-4, "impedance settles near the goal: {err} m");
}
