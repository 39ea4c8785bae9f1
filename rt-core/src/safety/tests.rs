//! The safety layer's unit tests.

use super::*;
use core::time::Duration;
use nalgebra::Vector3;
use penelope_hal::{Frame, JointLimits};

fn limits() -> JointLimits {
    JointLimits {
        position_min: JointVector::repeat(-1.0),
        position_max: JointVector::repeat(1.0),
        velocity_max: JointVector::repeat(2.0),
        effort_max: JointVector::repeat(10.0),
    }
}

fn ms(x: u64) -> Timestamp {
    Timestamp::from_nanos(x * 1_000_000)
}

#[test]
fn slave_holds_then_faults_on_a_stale_reference_and_needs_rearm() {
    let mut s = Safety::new(SafetyConfig::slave(6, limits())).unwrap();
    let at = JointState::at_rest(JointVector::repeat(0.5));
    assert_eq!(s.supervise(ms(0), &at, None), Action::Off);
    s.activate(ms(0), &at).unwrap();
    assert_eq!(s.supervise(ms(1), &at, None), Action::Hold(at.position));
    assert_eq!(s.supervise(ms(2), &at, Some(ms(2))), Action::Run);
    assert!(s.take_events().contains(SafetyEvent::ReferenceRecovered));
    // The reference stops; after 50 ms it is stale: hold where we are.
    let moved = JointState::at_rest(JointVector::repeat(0.25));
    assert_eq!(s.supervise(ms(52), &moved, Some(ms(2))), Action::Run);
    assert_eq!(
        s.supervise(ms(53), &moved, Some(ms(2))),
        Action::Hold(moved.position)
    );
    assert!(s.take_events().contains(SafetyEvent::ReferenceStale));
    assert_eq!(s.state(), SafetyState::Holding);
    // 550 ms after the last reference: fault, still holding (slave default).
    assert_eq!(
        s.supervise(ms(553), &moved, Some(ms(2))),
        Action::Hold(moved.position)
    );
    assert_eq!(s.state(), SafetyState::Fault);
    assert_eq!(s.fault_cause(), Some(FaultCause::ReferenceTimeout));
    // A fresh reference does not clear a fault; activation is refused until re-armed.
    assert_eq!(
        s.supervise(ms(600), &moved, Some(ms(600))),
        Action::Hold(moved.position)
    );
    assert_eq!(s.activate(ms(600), &moved), Err(ActivateError::Faulted));
    s.rearm().unwrap();
    assert_eq!(s.rearm(), Err(NothingLatched));
    assert_eq!(s.state(), SafetyState::Inactive);
    s.activate(ms(601), &moved).unwrap();
    // A reset does not start motion: fresh references are not followed until the loop finds
    // one that starts where the robot is.
    assert!(s.awaiting_new_motion());
    assert_eq!(
        s.supervise(ms(602), &moved, Some(ms(602))),
        Action::Hold(moved.position)
    );
    s.motion_reanchored();
    assert_eq!(s.supervise(ms(603), &moved, Some(ms(603))), Action::Run);
}

#[test]
fn master_goes_to_zero_force_and_caps_wrenches() {
    let mut s = Safety::new(SafetyConfig::master(6, limits())).unwrap();
    let at = JointState::at_rest(JointVector::zeros());
    s.activate(ms(0), &at).unwrap();
    assert_eq!(s.supervise(ms(1), &at, None), Action::ZeroForce);
    let w = Wrench {
        force: Vector3::new(30.0, 40.0, 0.0),
        torque: Vector3::new(0.0, 0.0, 0.2),
        frame: Frame::Base,
    };
    let Reference::Wrench(capped) = s.limit_reference(Reference::Wrench(w)) else {
        panic!("kind changed")
    };
    assert!((capped.force.norm() - 10.0).abs() < 1e-12);
    assert!((capped.force.x / capped.force.y - 0.75).abs() < 1e-12);
    assert_eq!(capped.torque, w.torque);
    assert!(s.take_events().contains(SafetyEvent::ForceLimited));
    // Fault on a master: amplifiers off.
    s.fault(FaultCause::NonFiniteCommand);
    assert_eq!(s.action(), Action::Off);
}

#[test]
fn limits_nan_and_estop() {
    let mut s = Safety::new(SafetyConfig::slave(3, limits())).unwrap();
    let ok = JointState::at_rest(JointVector::zeros());
    s.activate(ms(0), &ok).unwrap();
    let cmd = s
        .limit_command(JointCommand::Effort(JointVector::new(
            20.0, -20.0, 1.0, 5.0, 5.0, 5.0,
        )))
        .unwrap();
    assert_eq!(
        cmd,
        JointCommand::Effort(JointVector::new(10.0, -10.0, 1.0, 0.0, 0.0, 0.0))
    );
    assert!(s.take_events().contains(SafetyEvent::EffortClamped));
    let mut nan = JointVector::zeros();
    nan[1] = f64::NAN;
    assert_eq!(
        s.limit_command(JointCommand::Position(nan)),
        Err(FaultCause::NonFiniteCommand)
    );
    // Velocity beyond the limit faults.
    let mut fast = ok;
    fast.velocity[2] = -3.0;
    s.supervise(ms(1), &fast, Some(ms(1)));
    assert_eq!(
        s.fault_cause(),
        Some(FaultCause::VelocityLimit { joint: 2 })
    );
    // E-stop overrides a fault, and re-arming is explicit.
    s.estop();
    assert_eq!(s.state(), SafetyState::EStop);
    assert_eq!(s.action(), Action::Off);
    assert_eq!(s.activate(ms(2), &ok), Err(ActivateError::EStopLatched));
    s.rearm().unwrap();
    s.activate(ms(3), &ok).unwrap();
    // A NaN in the measured state faults.
    let mut bad = ok;
    bad.position[0] = f64::NAN;
    s.supervise(ms(4), &bad, Some(ms(4)));
    assert_eq!(s.fault_cause(), Some(FaultCause::NonFiniteState));
    // Position limit.
    s.rearm().unwrap();
    s.activate(ms(5), &ok).unwrap();
    let mut out = ok;
    out.position[1] = 1.5;
    s.supervise(ms(6), &out, Some(ms(6)));
    assert_eq!(
        s.fault_cause(),
        Some(FaultCause::PositionLimit { joint: 1 })
    );
}

#[test]
fn bad_configs_are_refused() {
    let mut c = SafetyConfig::slave(7, limits());
    assert_eq!(c.validate(), Err(SafetyConfigError::JointCount));
    c.joint_count = 6;
    c.limits.position_min[4] = 2.0;
    assert_eq!(c.validate(), Err(SafetyConfigError::Limits { joint: 4 }));
    c.limits = limits();
    c.watchdog = Duration::ZERO;
    assert_eq!(c.validate(), Err(SafetyConfigError::Watchdog));
}

#[test]
fn event_sets() {
    let mut e = EventSet::EMPTY;
    e.insert(SafetyEvent::Faulted);
    e.insert(SafetyEvent::TelemetryDropped);
    assert!(e.contains(SafetyEvent::Faulted));
    assert!(!e.contains(SafetyEvent::Rearmed));
    let names: heapless::Vec<&str, 4> = e.iter().map(|e| e.as_str()).collect();
    assert_eq!(names.as_slice(), &["faulted", "telemetry-dropped"]);
}

#[test]
fn a_mixed_command_is_limited_per_joint_by_what_each_joint_carries() {
    let mut s = Safety::new(SafetyConfig::slave(4, limits())).unwrap();
    s.activate(ms(0), &JointState::at_rest(JointVector::zeros()))
        .unwrap();
    let wrist = JointSet::from_indices(&[2, 3]).unwrap();
    let limited = s
        .limit_command(JointCommand::Mixed {
            effort: JointVector::new(20.0, -3.0, 99.0, 99.0, 7.0, 7.0),
            position: JointVector::new(5.0, 5.0, 0.5, -4.0, 3.0, 3.0),
            position_joints: wrist,
        })
        .unwrap();
    // Torques clamped on joints 0-1, positions on 2-3, nothing past the robot's four joints,
    // and the other kind's value on each joint cleared.
    assert_eq!(
        limited,
        JointCommand::Mixed {
            effort: JointVector::new(10.0, -3.0, 0.0, 0.0, 0.0, 0.0),
            position: JointVector::new(0.0, 0.0, 0.5, -1.0, 0.0, 0.0),
            position_joints: wrist,
        }
    );
    let events = s.take_events();
    assert!(events.contains(SafetyEvent::EffortClamped));
    assert!(events.contains(SafetyEvent::PositionClamped));
    // A NaN only matters on a joint that carries it.
    let mut nan = JointVector::zeros();
    nan[2] = f64::NAN;
    assert!(
        s.limit_command(JointCommand::Mixed {
            effort: nan,
            position: JointVector::zeros(),
            position_joints: wrist,
        })
        .is_ok()
    );
    assert_eq!(
        s.limit_command(JointCommand::Mixed {
            effort: JointVector::zeros(),
            position: nan,
            position_joints: wrist,
        }),
        Err(FaultCause::NonFiniteCommand)
    );
}
