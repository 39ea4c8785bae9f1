//! The creator in-process (no network but loopback): a remote force sensor reached through a
//! fake [`Remote`] that only says where the sensor is published, read over the data plane (its
//! wrench in telemetry, stale when its publisher stops), and a local virtual sensor.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use nalgebra::Vector3;
use penelope_hal::{Frame, Transition, Wrench};
use penelope_protocol::proto::{
    CallError, ControllerMethod, Method, Reply, RobotMethod, SensorMethod, WireError,
};
use penelope_protocol::service::Remote;
use penelope_runtime::dataplane::endpoint::Endpoint;
use penelope_runtime::dataplane::sensor_stream::{Probe, SensorPublisher};
use penelope_runtime::objects::Creator;

mod common;

use common::*;

/// Another node's naming service and sensor, as far as a controller needs them: where the
/// sensor is published (and nothing per sample).
struct FakeRemote {
    calls: AtomicU64,
    published: Mutex<Option<SocketAddr>>,
}

impl Remote for FakeRemote {
    fn call(&self, path: &str, method: Method) -> Result<Reply, WireError> {
        assert_eq!(path, "/other/sensors/ft");
        self.calls.fetch_add(1, Ordering::Relaxed);
        match (method, *self.published.lock().unwrap()) {
            (Method::Sensor(SensorMethod::Stream), Some(a)) => Ok(Reply::Address(a.to_string())),
            (Method::Sensor(SensorMethod::Stream), None) => {
                Err(WireError::Call(CallError::NotReady(
                    "sensor `ft` is not published on the data plane: it has no `publish` key"
                        .into(),
                )))
            }
            (other, _) => Err(WireError::Call(CallError::BadArgument(format!(
                "{other:?}"
            )))),
        }
    }
}

/// A publisher on loopback whose sensor reads a constant wrench, whatever the probe.
fn constant_publisher() -> SensorPublisher {
    let endpoint = Endpoint::bind("127.0.0.1:0".parse().unwrap(), None).unwrap();
    let measure = Box::new(|_: Option<&Probe>| {
        Some(Wrench {
            force: Vector3::new(1.0, 2.0, 3.0),
            torque: Vector3::new(0.0, 0.0, 0.5),
            frame: Frame::Base,
        })
    });
    SensorPublisher::start("ft", endpoint, Duration::from_millis(1), measure).unwrap()
}

#[test]
fn a_remote_sensor_is_read_over_the_data_plane_and_goes_stale_when_its_publisher_stops() {
    let c = creator();
    let (s, _rx) = session(1);
    puma_on_two_boards(&c, &s, "trajectory/step", "pose = \"start\"");
    let remote = Arc::new(FakeRemote {
        calls: AtomicU64::new(0),
        published: Mutex::new(None),
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
        Err(WireError::Call(CallError::NotReady(_)))
    ));
    // A sensor that does not publish is refused, naming its path and the missing key.
    c.set_remote(remote.clone());
    match lifecycle(&c, &s, "pid", Transition::Activate) {
        Err(WireError::Call(CallError::NotReady(why))) => {
            assert!(
                why.contains("/other/sensors/ft") && why.contains("publish"),
                "{why}"
            );
        }
        other => panic!("{other:?}"),
    }
    let publisher = constant_publisher();
    *remote.published.lock().unwrap() = Some(publisher.address());
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
    // The feed's probes reached the publisher; samples came back.
    wait_for("probes at the publisher", Duration::from_secs(5), || {
        publisher.stats().probes > 10 && publisher.stats().samples > 10
    });
    drop(publisher);
    wait_for("the stale wrench", Duration::from_secs(5), || {
        status(&c)
            .last
            .is_some_and(|l| l.wrench.force == [0.0, 0.0, 0.0])
    });
    // The loop keeps running (the sensor is optional for a joint PID).
    assert_eq!(status(&c).last.unwrap().state, "running");
    // One request per activation (where is the sensor published?), none per sample.
    assert_eq!(remote.calls.load(Ordering::Relaxed), 2);
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
        Err(WireError::Call(CallError::NotReady(_)))
    ));
    lifecycle(&c, &s, "ft", Transition::Configure).unwrap();
    let pose = |z: f64| penelope_protocol::proto::PoseMsg {
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
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
}
