//! `sensor/test-signal`, the kind that is one module: made, described, read from the
//! non-real-time side, and read in a controller's loop (the loop's wrench is the signal).

use std::time::Duration;

use penelope_hal::Transition;
use penelope_protocol::proto::{
    CallError, ControllerMethod, Method, Reply, RobotMethod, SensorMethod, WireError,
};

mod common;

use common::*;

#[test]
fn a_test_signal_is_read_in_the_loop_of_the_controller_bound_to_it() {
    let c = creator();
    let (s, _rx) = session(1);
    puma_on_two_boards(&c, &s, "trajectory/step", "pose = \"start\"");
    // 0 Hz at 90°: a constant wrench, the amplitudes.
    create(
        &c,
        &s,
        "sensor/test-signal",
        "sig",
        "force_amplitude_n = [1, -2, 3]\ntorque_amplitude_nm = [0, 0, 0.5]\nfrequency_hz = 0\nphase_deg = 90",
    );
    lifecycle(&c, &s, "sig", Transition::Configure).unwrap();
    let Ok(Reply::Wrench(w)) = call(&c, &s, ("sig", Method::Sensor(SensorMethod::Read))) else {
        panic!("read");
    };
    assert_eq!((w.force, w.torque), ([1.0, -2.0, 3.0], [0.0, 0.0, 0.5]));
    assert!(matches!(
        call(&c, &s, ("sig", Method::Sensor(SensorMethod::Bias))),
        Err(WireError::Call(CallError::Unsupported { .. }))
    ));
    let Ok(Reply::Object(info)) = call(&c, &s, ("sig", Method::Describe)) else {
        panic!("describe");
    };
    assert!(
        info.relations
            .iter()
            .any(|(k, v)| k == "signal" && v.contains("0.000 Hz")),
        "{:?}",
        info.relations
    );

    ctl(
        &c,
        &s,
        "pid",
        ControllerMethod::SetSensor {
            sensor: "sig".into(),
        },
    )
    .unwrap();
    lifecycle(&c, &s, "pid", Transition::Activate).unwrap();
    let status = |c: &penelope_runtime::objects::Creator| match ctl(
        c,
        &s,
        "pid",
        ControllerMethod::Status,
    ) {
        Ok(Reply::Status(st)) => st,
        other => panic!("{other:?}"),
    };
    wait_for("the signal in the loop", Duration::from_secs(5), || {
        status(&c)
            .last
            .is_some_and(|l| l.wrench.force == [1.0, -2.0, 3.0])
    });
    assert!(matches!(
        call(&c, &s, ("robot", Method::Robot(RobotMethod::ToolWrench))),
        Ok(Reply::Wrench(w)) if w.force == [1.0, -2.0, 3.0] && w.torque == [0.0, 0.0, 0.5]
    ));
    // In use by a running loop: it cannot be cleaned up under it.
    assert!(matches!(
        lifecycle(&c, &s, "sig", Transition::Cleanup),
        Err(WireError::Call(CallError::InUse { .. }))
    ));
    c.shutdown();
    assert!(!status(&c).running);
}
