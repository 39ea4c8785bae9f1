//! How fast a wrist sensor's fault reaches the master's hand, measured on a run's records:
//! shared by the one-node (`demo_galil_netft.rs`) and the two-node (`sensor_fault_two_nodes.rs`)
//! tests.

use std::time::Duration;

use penelope_hal::Timestamp;
use penelope_rt_core::safety::SafetyEvent;
use penelope_supervisor::runs::RunOutput;
use penelope_supervisor::runs::report::motor_force;

/// The motors' force at the handle counted as none: the display's damping on a moving hand.
pub const MOTORS_AT_REST_N: f64 = 0.2;

/// Asserts that the master displayed at least `shown_n` N just before the sensor fault at
/// `fault_at`, and that both its commanded wrench and its motors' force at the handle were at
/// zero within `bound` and stayed there until `until` (after the fault); prints the delays,
/// labelled `what`, and when the slave's loop first saw the fault.
pub fn assert_master_let_go(
    out: &RunOutput,
    fault_at: Timestamp,
    shown_n: f64,
    bound: Duration,
    until: Duration,
    what: &str,
) {
    let commanded =
        |s: &penelope_runtime::objects::tick::TickRecord| s.sample.commanded_wrench.force.norm();
    let before: Vec<f64> = out
        .master
        .iter()
        .filter(|s| s.sample.time < fault_at && fault_at.saturating_since(s.sample.time) < bound)
        .map(commanded)
        .collect();
    assert!(
        !before.is_empty() && before.iter().all(|f| *f > shown_n),
        "{what}: the master displayed no force just before the fault: {before:?}"
    );
    let first_zero = out
        .master
        .iter()
        .find(|s| s.sample.time >= fault_at && commanded(s) == 0.0)
        .map(|s| s.sample.time.saturating_since(fault_at));
    // A tick's record holds the torque the plant applied up to it, which the tick before
    // commanded: the motors let go at that tick.
    let motors_let_go = out
        .master
        .windows(2)
        .find(|w| {
            w[0].sample.time >= fault_at
                && motor_force(&out.info, &w[1]).is_some_and(|f| f.norm() < MOTORS_AT_REST_N)
        })
        .map(|w| w[0].sample.time.saturating_since(fault_at));
    // Where the time went: the slave's loop first saw the fault at this tick.
    let slave_saw = out
        .slave
        .iter()
        .find(|s| s.sample.time >= fault_at && s.sample.events.contains(SafetyEvent::SensorError))
        .map(|s| s.sample.time.saturating_since(fault_at));
    eprintln!(
        "{what}: sensor fault to zero displayed force {first_zero:?}, to the motors below \
         {MOTORS_AT_REST_N} N {motors_let_go:?} (bound {bound:?}); the slave's loop saw it after \
         {slave_saw:?}"
    );
    let first_zero = first_zero.expect("the master never displayed zero force after the fault");
    assert!(first_zero <= bound, "{what}: {first_zero:?} > {bound:?}");
    let motors_let_go = motors_let_go.expect("the motors never let go after the fault");
    assert!(
        motors_let_go <= bound,
        "{what}: {motors_let_go:?} > {bound:?}"
    );
    // And zero while the fault lasted.
    let during: Vec<f64> = out
        .master
        .iter()
        .filter(|s| s.sample.time >= fault_at + bound && s.sample.time < fault_at + until)
        .map(commanded)
        .collect();
    assert!(
        during.len() as u128 * 1_000 > (until - bound).as_micros() / 2,
        "{what}: master ticks during the fault: {}",
        during.len()
    );
    assert!(
        during.iter().all(|f| *f == 0.0),
        "{what}: the master displayed force during the sensor fault: {:?}",
        during
            .iter()
            .filter(|f| **f != 0.0)
            .take(10)
            .collect::<Vec<_>>()
    );
}
