//! The paper's task made of objects on a node: an FRHC held by the scripted operator's hand
//! (`sensor/operator-hand`), a PUMA 200 over a wall with a wrist sensor, the channel between
//! them (`trajectory/teleop`) and the two halves of position-forward / force-back
//! (`controller/force-display`, `controller/slave-tracking`), created, related and configured
//! through the creator exactly as `ctl` would, then the loops the creator builds stepped on a
//! simulated clock (communication every 2 ms, control every 1 ms, the sensor feed's work done
//! by the test each 2 ms).

use penelope_drivers::sim::scripts::{self, CONTACT_PHASE, FREE_MOTION_PHASES, INDEX_PHASE};
use penelope_hal::{Timestamp, Transition};
use penelope_protocol::proto::{
    CallError, ControllerMethod, Method, Reply, RobotMethod, WireError,
};
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_runtime::objects::Creator;
use penelope_tests::papers_task::{create, ok, papers_task, relate, step_papers_task};

fn call(c: &Creator, name: &str, method: Method) -> Result<Reply, WireError> {
    c.call_object(name, method).map_err(WireError::from)
}

fn phase(t: Timestamp) -> &'static str {
    scripts::demo()
        .segment_at(std::time::Duration::from_nanos(t.as_nanos()))
        .map_or("", |(_, s, _)| s.label)
}

#[test]
fn a_node_runs_the_papers_task_from_objects() {
    let c = papers_task();
    let (master, slave) = step_papers_task(&c, 14.5, f64::INFINITY, |_, _, _| {});
    assert!(master.len() > 14_000 && slave.len() > 14_000);

    // Free motion: the slave follows its reference (the mapped master pose) closely, and it
    // really moves (the hand's reach and sweeps).
    let free: Vec<&TelemetrySample> = slave
        .iter()
        .filter(|s| {
            FREE_MOTION_PHASES.contains(&phase(s.time)) && s.time.as_nanos() > 1_500_000_000
        })
        .collect();
    assert!(free.len() > 5_000);
    let rms = (free
        .iter()
        .map(|s| (s.reference_position - s.tool_position).norm_squared())
        .sum::<f64>()
        / free.len() as f64)
        .sqrt();
    let span = |axis: usize| {
        let v: Vec<f64> = free.iter().map(|s| s.tool_position[axis]).collect();
        v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
    };
    assert!(rms < 0.002, "free-motion tracking RMS {:.3} mm", rms * 1e3);
    assert!(span(0) > 0.03 && span(1) > 0.06, "the slave hardly moved");

    // The clutch: while indexing, the hand rises 2 cm and the slave stays put.
    let index: Vec<&TelemetrySample> = slave
        .iter()
        .filter(|s| phase(s.time) == INDEX_PHASE)
        .collect();
    let rise = index.last().unwrap().reference_position.z - index[0].reference_position.z;
    assert!(
        rise.abs() < 0.002,
        "the slave followed the hand while clutched: {rise} m"
    );

    // Steady contact: the slave senses the wall and the master displays gain x that force.
    let contact = |rows: &[TelemetrySample]| -> Vec<TelemetrySample> {
        rows.iter()
            .filter(|s| phase(s.time) == CONTACT_PHASE)
            .skip(500)
            .copied()
            .collect()
    };
    let (mc, sc) = (contact(&master), contact(&slave));
    let mean = |v: &[TelemetrySample], f: &dyn Fn(&TelemetrySample) -> f64| {
        v.iter().map(f).sum::<f64>() / v.len() as f64
    };
    let sensed = mean(&sc, &|s| s.wrench.force.z);
    // What the FRHC's motors produce at the handle (not the reference they were given).
    let sampled: Vec<f64> = mc
        .iter()
        .step_by(50)
        .map(|s| motor_force(&c, "frhc", s).z)
        .collect();
    let displayed = sampled.iter().sum::<f64>() / sampled.len() as f64;
    // The wall pushes the slave up; the operator's hand is pushed up as much, scaled.
    println!(
        "free-motion RMS {:.3} mm over {} ticks; clutch drift {:.3} mm; contact: sensed \
         {sensed:.2} N, displayed {displayed:.2} N",
        rms * 1e3,
        free.len(),
        rise * 1e3
    );
    assert!(sensed > 2.0, "the slave never pressed the wall: {sensed} N");
    let expected = 0.5 * sensed;
    assert!(
        (displayed - expected).abs() < 0.05 * expected.abs(),
        "displayed {displayed:.2} N, expected {expected:.2} N (0.5 x {sensed:.2} N)"
    );
}

#[test]
fn the_task_runs_the_same_twice_and_its_channel_is_guarded() {
    let run = || step_papers_task(&papers_task(), 3.0, f64::INFINITY, |_, _, _| {});
    let (a, b) = (run(), run());
    assert_eq!(a.1.len(), b.1.len());
    assert!(
        a.1.iter()
            .zip(&b.1)
            .all(|(x, y)| x.q == y.q && x.effort == y.effort),
        "two runs of the same objects differ"
    );

    // A teleoperation law needs a channel whose side it runs, and a joint law no channel.
    let c = papers_task();
    create(&c, "controller/slave-tracking", "wrong-side", "");
    relate(&c, "wrong-side", "frhc", "link", None);
    ok(&c, "wrong-side", Method::Transition(Transition::Configure));
    let refused = call(&c, "wrong-side", Method::Transition(Transition::Activate));
    assert!(
        matches!(&refused, Err(WireError::Call(CallError::BadArgument(m))) if m.contains("slave of `link` is `puma`")),
        "{refused:?}"
    );
    create(&c, "controller/joint-pid", "pid", "");
    relate(&c, "pid", "puma", "link", None);
    ok(&c, "pid", Method::Transition(Transition::Configure));
    assert!(matches!(
        call(&c, "pid", Method::Transition(Transition::Activate)),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
}

#[test]
fn set_gains_changes_a_teleoperation_laws_gains_and_keeps_the_rest() {
    let c = papers_task();
    let set = |gains: &str| {
        call(
            &c,
            "display",
            Method::Controller(ControllerMethod::SetGains {
                gains: gains.into(),
            }),
        )
    };
    // Unknown keys and loop timing are refused; a gain is taken, the other keys kept.
    assert!(matches!(
        set("stiffness = 3"),
        Err(WireError::Call(CallError::BadConfig { .. }))
    ));
    assert!(matches!(
        set("period_us = 500"),
        Err(WireError::Call(CallError::BadConfig { .. }))
    ));
    assert!(matches!(
        set("max_force = -1.0"),
        Err(WireError::Call(CallError::BadConfig { .. }))
    ));
    set("max_force = 3.0").unwrap();
    // In steady contact the motors now display 3 N (7.9 N uncapped): the force the FRHC's
    // motors produce, F = J^-T (tau - g(q)), not the reference they were given.
    let (master, _) = step_papers_task(&c, 14.5, f64::INFINITY, |_, _, _| {});
    let contact: Vec<&TelemetrySample> = master
        .iter()
        .filter(|s| phase(s.time) == CONTACT_PHASE)
        .skip(500)
        .step_by(100)
        .collect();
    assert!(contact.len() >= 10);
    for s in contact {
        let f = motor_force(&c, "frhc", s);
        assert!(
            (2.8..=3.05).contains(&f.norm()),
            "the motors display {:.2} N ({f:?}) with a 3 N cap; the reference asked {:.2} N",
            f.norm(),
            s.commanded_wrench.force.norm()
        );
    }
}

/// The force at the tool that the motors of `robot` produce in sample `s`: the joint torques
/// less gravity compensation, mapped through the inverse transpose of the Jacobian (6 joints).
fn motor_force(c: &Creator, robot: &str, s: &TelemetrySample) -> nalgebra::Vector3<f64> {
    let q: Vec<f64> = s.q.iter().take(6).copied().collect();
    let j = match ok(
        c,
        robot,
        Method::Robot(RobotMethod::Jacobian { q: Some(q.clone()) }),
    ) {
        Reply::Matrix(m) => nalgebra::Matrix6::from_row_slice(&m.data),
        other => panic!("jacobian answered {other:?}"),
    };
    let g = match ok(c, robot, Method::Robot(RobotMethod::Gravity { q: Some(q) })) {
        Reply::Joints(g) => nalgebra::Vector6::from_column_slice(&g),
        other => panic!("gravity answered {other:?}"),
    };
    let tau = nalgebra::Vector6::from_iterator(s.effort.iter().take(6).copied());
    let wrench = j
        .transpose()
        .try_inverse()
        .expect("away from singularities")
        * (tau - g);
    wrench.fixed_rows::<3>(0).into_owned()
}

#[test]
fn a_silent_master_makes_the_slave_hold_within_its_watchdog() {
    use penelope_rt_core::safety::SafetyState;
    let c = papers_task();
    // The master's side goes silent at 3 s (the reach is under way).
    let (_, slave) = step_papers_task(&c, 3.5, 3.0, |_, _, _| {});
    let first_hold = slave
        .iter()
        .find(|s| s.time.as_nanos() > 3_000_000_000 && s.state != SafetyState::Running)
        .expect("the slave never stopped following a silent master");
    assert_eq!(first_hold.state, SafetyState::Holding);
    let after = first_hold.time.as_nanos() as f64 / 1e6 - 3000.0;
    // The watchdog is 50 ms; the last sample arrived up to one communication period earlier.
    assert!(
        (45.0..=55.0).contains(&after),
        "held {after:.1} ms after the master went silent"
    );
    // Until then it ran (after its first references arrived).
    assert!(
        slave
            .iter()
            .filter(|s| (500_000_000..3_000_000_000).contains(&s.time.as_nanos()))
            .all(|s| s.state == SafetyState::Running)
    );
}
