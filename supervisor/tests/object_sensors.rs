//! The creator in-process (no network): a remote force sensor reached through a fake
//! [`Remote`] (its wrench in telemetry, stale when the remote fails) and a local virtual sensor.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use penelope_hal::Transition;
use penelope_supervisor::objects::Creator;
use penelope_supervisor::proto::{
    ControllerMethod, Method, Reply, RobotMethod, SensorMethod, WireError, WrenchMsg,
};
use penelope_supervisor::service::Remote;

mod common;

use common::*;

struct FakeRemote {
    calls: AtomicU64,
    fail: AtomicBool,
}

impl Remote for FakeRemote {
    fn call(&self, path: &str, method: Method) -> Result<Reply, WireError> {
        assert_eq!(path, "/other/sensors/ft");
        self.calls.fetch_add(1, Ordering::Relaxed);
        if self.fail.load(Ordering::Relaxed) {
            return Err(WireError::Remote("node `other` is unreachable".into()));
        }
        match method {
            Method::Sensor(SensorMethod::Measure { pose, .. }) => {
                assert!(pose.to_pose().is_ok());
                Ok(Reply::Wrench(WrenchMsg {
                    force: [1.0, 2.0, 3.0],
                    torque: [0.0, 0.0, 0.5],
                }))
            }
            other => Err(WireError::BadArgument(format!("{other:?}"))),
        }
    }
}

#[test]
fn a_remote_sensor_wrench_reaches_telemetry_and_goes_stale_when_the_remote_fails() {
    let c = creator();
    let (s, _rx) = session(1);
    puma_on_two_boards(&c, &s, "trajectory/step", "pose = \"start\"");
    let remote = Arc::new(FakeRemote {
        calls: AtomicU64::new(0),
        fail: AtomicBool::new(false),
    });
    ctl(
        &c,
        &s,
        "pid",
        ControllerMethod::SetSensor {
            sensor: "/other/sensors/ft".into(),
        },
    )
    .unwrap();
    // Without a remote the activation is refused, typed.
    assert!(matches!(
        lifecycle(&c, &s, "pid", Transition::Activate),
        Err(WireError::NotReady(_))
    ));
    c.set_remote(remote.clone());
    lifecycle(&c, &s, "pid", Transition::Activate).unwrap();
    let status = |c: &Creator| match ctl(c, &s, "pid", ControllerMethod::Status) {
        Ok(Reply::Status(st)) => st,
        other => panic!("{other:?}"),
    };
    wait_for("the remote wrench", Duration::from_secs(5), || {
        status(&c)
            .last
            .is_some_and(|l| l.wrench.force == [1.0, 2.0, 3.0])
    });
    assert!(matches!(
        call(&c, &s, ("robot", Method::Robot(RobotMethod::ToolWrench))),
        Ok(Reply::Wrench(w)) if w.force == [1.0, 2.0, 3.0]
    ));
    remote.fail.store(true, Ordering::Relaxed);
    wait_for("the stale wrench", Duration::from_secs(5), || {
        status(&c)
            .last
            .is_some_and(|l| l.wrench.force == [0.0, 0.0, 0.0])
    });
    // The loop keeps running (the sensor is optional for a joint PID).
    assert_eq!(status(&c).last.unwrap().state, "running");
    assert!(remote.calls.load(Ordering::Relaxed) > 10);
    c.shutdown();
    assert!(!status(&c).running);
}

#[test]
fn a_local_virtual_sensor_measures_its_environment() {
    let c = creator();
    let (s, _rx) = session(1);
    create(
        &c,
        &s,
        "sensor/virtual",
        "ft",
        "[[shapes]]\nkind = \"plane\"\npoint = [0, 0, 0.5]\nnormal = [0, 0, 1]\nstiffness = 1000\ndamping = 0",
    );
    assert!(matches!(
        call(&c, &s, ("ft", Method::Sensor(SensorMethod::Read))),
        Err(WireError::NotReady(_))
    ));
    lifecycle(&c, &s, "ft", Transition::Configure).unwrap();
    let pose = |z: f64| penelope_supervisor::proto::PoseMsg {
        position: [0.0, 0.0, z],
        n: [1.0, 0.0, 0.0],
        o: [0.0, 1.0, 0.0],
        a: [0.0, 0.0, 1.0],
    };
    let Ok(Reply::Wrench(w)) = call(
        &c,
        &s,
        (
            "ft",
            Method::Sensor(SensorMethod::Measure {
                pose: pose(0.49),
                velocity: [0.0; 3],
            }),
        ),
    ) else {
        panic!("measure")
    };
    assert!(
        (w.force[2] - 10.0).abs() < 1e-9,
        "1 cm into a 1000 N/m wall: {w:?}"
    );
    call(&c, &s, ("ft", Method::Sensor(SensorMethod::Bias))).unwrap();
    assert!(matches!(
        call(&c, &s, ("ft", Method::Sensor(SensorMethod::Read))),
        Ok(Reply::Wrench(w)) if w.force[2].abs() < 1e-12
    ));
    assert!(matches!(
        call(
            &c,
            &s,
            (
                "ft",
                Method::Sensor(SensorMethod::SetProbe {
                    pose: pose(f64::NAN),
                    velocity: [0.0; 3]
                })
            )
        ),
        Err(WireError::BadArgument(_))
    ));
}
