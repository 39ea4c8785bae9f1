//! Round trips of the wire's data and messages through postcard.

use nalgebra::{Translation3, UnitQuaternion};
use penelope_hal::{Frame, Pose};

use super::*;
use crate::proto::{CallError, ProtocolError, call_error_kinds, protocol_error_kinds};

#[test]
fn poses_wrenches_and_joints_cross_the_wire_intact() {
    let pose = Pose::from_parts(
        Translation3::new(0.1, -0.2, 0.3),
        UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1),
    );
    let back = PoseMsg::from(&pose).to_pose().unwrap();
    assert!((back.translation.vector - pose.translation.vector).norm() < 1e-12);
    assert!(back.rotation.angle_to(&pose.rotation) < 1e-9);
    let mut skew = PoseMsg::from(&pose);
    skew.n = [1.0, 1.0, 0.0];
    assert!(matches!(
        skew.to_pose(),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    let mut nan = PoseMsg::from(&pose);
    nan.position[1] = f64::NAN;
    assert!(nan.to_pose().is_err());

    let w = WrenchMsg {
        force: [1.0, 2.0, 3.0],
        torque: [0.1, 0.2, f64::INFINITY],
    };
    assert!(w.to_wrench(Frame::Base).is_err());

    assert!(joints_to_vector(&[0.1, 0.2], 3).is_err());
    assert!(joints_to_vector(&[0.1, f64::NAN, 0.3], 3).is_err());
    let q = joints_to_vector(&[0.1, 0.2, 0.3], 3).unwrap();
    assert_eq!(joints_from_vector(&q, 3), vec![0.1, 0.2, 0.3]);

    let m = MatrixMsg::from_block(
        &nalgebra::Matrix2x3::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0),
        2,
        2,
    );
    assert_eq!(m.data, vec![1.0, 2.0, 4.0, 5.0]);
    assert_eq!(m.get(1, 0), Some(4.0));
    assert_eq!(m.get(2, 0), None);
}

#[test]
fn names_are_checked() {
    assert!(check_name("slave-1.a_b").is_ok());
    for bad in ["", ".", "..", "a/b", "a b", "é", &"x".repeat(65)] {
        assert!(
            matches!(
                check_name(bad),
                Err(WireError::Call(CallError::BadName { .. }))
            ),
            "{bad:?}"
        );
    }
}

#[test]
fn classes_round_trip_their_names() {
    for c in Class::ALL {
        assert_eq!(Class::parse(c.as_str()), Some(c));
    }
    assert_eq!(
        object_path("lab-a", Class::Robot, "slave"),
        "/lab-a/robots/slave"
    );
    assert_eq!(object_path("lab-a", Class::Creator, "x"), "/lab-a/creator");
}

#[test]
fn every_message_round_trips_through_postcard() {
    let msgs = [
        ClientMsg::Hello(ClientHello::new("ctl", Role::Reader)),
        ClientMsg::Request {
            id: 7,
            call: Call::Object {
                object: "slave".into(),
                method: Method::Robot(RobotMethod::ForwardKinematics {
                    q: Some(vec![0.0, 0.1, 0.2, 0.0, 0.0, 0.0]),
                }),
            },
        },
        ClientMsg::Handshake { noise: vec![3; 48] },
        ClientMsg::Bye,
    ];
    for m in msgs {
        let bytes = postcard::to_stdvec(&m).unwrap();
        assert_eq!(postcard::from_bytes::<ClientMsg>(&bytes).unwrap(), m);
    }
    let reply = ServerMsg::Response {
        id: 7,
        result: Err(WireError::Call(CallError::InUse {
            name: "slave".into(),
            dependents: vec!["pid".into()],
        })),
    };
    let bytes = postcard::to_stdvec(&reply).unwrap();
    assert_eq!(postcard::from_bytes::<ServerMsg>(&bytes).unwrap(), reply);
}

#[test]
fn the_robot_description_variants_were_appended_and_round_trip() {
    let index = |bytes: &[u8]| bytes[0];
    // RobotMethod: MapJoints was the last (index 16); the new ones follow it.
    let map = postcard::to_stdvec(&RobotMethod::MapJoints {
        board: "b".into(),
        joints: vec![],
    })
    .unwrap();
    let description = postcard::to_stdvec(&RobotMethod::Description).unwrap();
    let frames = RobotMethod::LinkFrames {
        q: Some(vec![0.1, -0.2, 0.3]),
    };
    let frames_bytes = postcard::to_stdvec(&frames).unwrap();
    assert_eq!(index(&map), 16);
    assert_eq!(index(&description), 17);
    assert_eq!(index(&frames_bytes), 18);
    assert_eq!(
        postcard::from_bytes::<RobotMethod>(&description).unwrap(),
        RobotMethod::Description
    );
    assert_eq!(
        postcard::from_bytes::<RobotMethod>(&frames_bytes).unwrap(),
        frames
    );
    let pose = PoseMsg {
        position: [0.1, 0.2, 0.3],
        n: [1.0, 0.0, 0.0],
        o: [0.0, 1.0, 0.0],
        a: [0.0, 0.0, 1.0],
    };
    let replies = [
        Reply::RobotDescription(RobotDescriptionMsg {
            urdf: "<robot name=\"r\"/>".into(),
            frames: vec!["base_link".into(), "link1".into(), "tool".into()],
            joint_names: vec!["waist".into()],
            contacts: vec![
                ContactShapeMsg::Plane {
                    point: [0.5, 0.0, 0.0],
                    normal: [-1.0, 0.0, 0.0],
                },
                ContactShapeMsg::Sphere {
                    center: [0.0, 0.4, 0.2],
                    radius: 0.05,
                },
            ],
        }),
        Reply::Poses(vec![pose, pose]),
    ];
    // CreatorCall::ApplySystem was the last (index 8); RecordStartScene follows it.
    let scene = CreatorCall::RecordStartScene {
        path: "run.mcap".into(),
        objects: vec!["follow".into()],
        scene_hz: 50.0,
    };
    let bytes = postcard::to_stdvec(&scene).unwrap();
    assert_eq!(index(&bytes), 9);
    assert_eq!(postcard::from_bytes::<CreatorCall>(&bytes).unwrap(), scene);
    // Reply::Stopped was the last (index 25); the new ones follow it.
    let stopped = postcard::to_stdvec(&Reply::Stopped(StopReport::default())).unwrap();
    assert_eq!(index(&stopped), 25);
    for (k, r) in replies.into_iter().enumerate() {
        let bytes = postcard::to_stdvec(&r).unwrap();
        assert_eq!(usize::from(index(&bytes)), 26 + k);
        assert_eq!(postcard::from_bytes::<Reply>(&bytes).unwrap(), r);
    }
}

#[test]
fn the_sensor_stream_variants_were_appended_and_moved_no_index() {
    // postcard encodes a variant by its index: the earlier sensor methods and replies keep
    // theirs, and the new ones come last.
    let index = |bytes: Vec<u8>| bytes[0];
    let method = |m: SensorMethod| index(postcard::to_stdvec(&m).unwrap());
    assert_eq!(method(SensorMethod::Read), 0);
    assert_eq!(method(SensorMethod::Bias), 1);
    assert_eq!(method(SensorMethod::Stream), 4);
    let subscribed = Reply::Subscribed { subscription: 1 };
    assert_eq!(index(postcard::to_stdvec(&subscribed).unwrap()), 20);
    let address = Reply::Address("127.0.0.1:7420".into());
    let bytes = postcard::to_stdvec(&address).unwrap();
    assert_eq!(bytes[0], 21);
    assert_eq!(postcard::from_bytes::<Reply>(&bytes).unwrap(), address);
}

#[test]
fn the_link_telemetry_variants_were_appended_and_moved_no_index() {
    // A link batch is the last server message, the refusal of a channel without a link the
    // last error: every earlier message keeps its bytes.
    let batch = ServerMsg::Link(LinkBatch {
        subscription: 1,
        dropped: 0,
        records: Vec::new(),
    });
    let bytes = postcard::to_stdvec(&batch).unwrap();
    assert_eq!(bytes, [5, 1, 0, 0]);
    assert_eq!(postcard::from_bytes::<ServerMsg>(&bytes).unwrap(), batch);
    let forbidden = WireError::Call(CallError::Forbidden(String::new()));
    assert_eq!(postcard::to_stdvec(&forbidden).unwrap()[..2], [1, 16]);
    let no_link = WireError::Call(CallError::NoLink("link".into()));
    let bytes = postcard::to_stdvec(&no_link).unwrap();
    assert_eq!(bytes[..2], [1, 17]);
    assert_eq!(postcard::from_bytes::<WireError>(&bytes).unwrap(), no_link);
}

#[test]
fn protocol_failures_and_call_refusals_are_apart_on_the_wire() {
    // Protocol first (index 0), calls second (index 1): the outer byte says which.
    let auth = WireError::Protocol(ProtocolError::AuthFailed);
    assert_eq!(postcard::to_stdvec(&auth).unwrap(), [0, 5]);
    let unknown = WireError::Call(CallError::UnknownName("x".into()));
    assert_eq!(postcard::to_stdvec(&unknown).unwrap(), [1, 2, 1, b'x']);
    // Display is the inner error's, unchanged by the wrapping.
    assert_eq!(unknown.to_string(), "unknown name `x`");
    assert_eq!(auth.to_string(), "authentication failed");
}

#[test]
fn the_error_kinds_are_the_variants_in_wire_order() {
    let protocol = protocol_error_kinds();
    let call = call_error_kinds();
    assert_eq!(protocol.first(), Some(&"Malformed"));
    assert_eq!(protocol.last(), Some(&"Timeout"));
    assert_eq!(call.first(), Some(&"LimitReached"));
    assert_eq!(call.last(), Some(&"NoLink"));
    assert_eq!((protocol.len(), call.len()), (9, 18));
    // A value's kind is the name at its variant's index.
    let samples = [
        WireError::Protocol(ProtocolError::BadMagic),
        WireError::Protocol(ProtocolError::Timeout("idle".into())),
        WireError::Call(CallError::UnknownName("x".into())),
        WireError::Call(CallError::NoNamingService),
        WireError::Call(CallError::NoLink("link".into())),
    ];
    let kinds: Vec<&str> = samples.iter().map(WireError::kind).collect();
    assert_eq!(
        kinds,
        [
            "BadMagic",
            "Timeout",
            "UnknownName",
            "NoNamingService",
            "NoLink"
        ]
    );
    for e in &samples {
        assert!(format!("{e:?}").contains(e.kind()), "{e:?}");
    }
}

#[test]
fn the_crtk_verbs_were_appended_and_round_trip() {
    // RobotMethod: LinkFrames was the last (index 18); the six verbs follow it in this order.
    let pose = PoseMsg {
        position: [0.4, 0.1, 0.2],
        n: [1.0, 0.0, 0.0],
        o: [0.0, -1.0, 0.0],
        a: [0.0, 0.0, -1.0],
    };
    let links = postcard::to_stdvec(&RobotMethod::LinkFrames { q: None }).unwrap();
    assert_eq!(links[0], 18);
    let methods = [
        RobotMethod::MoveJoints {
            q: vec![0.1, -0.2, 0.3],
            duration_s: 2.0,
        },
        RobotMethod::MoveTool {
            pose,
            duration_s: 1.5,
        },
        RobotMethod::ServoJoints { q: vec![0.0, 0.5] },
        RobotMethod::ServoTool { pose },
        RobotMethod::Setpoints,
        RobotMethod::OperatingState,
    ];
    for (k, m) in methods.into_iter().enumerate() {
        let bytes = postcard::to_stdvec(&m).unwrap();
        assert_eq!(usize::from(bytes[0]), 19 + k, "{m:?}");
        assert_eq!(postcard::from_bytes::<RobotMethod>(&bytes).unwrap(), m);
    }
    // Reply: Poses was the last (index 27).
    assert_eq!(postcard::to_stdvec(&Reply::Poses(vec![])).unwrap(), [27, 0]);
    let replies = [
        Reply::Setpoints(SetpointsMsg {
            time_ns: 5_000_000,
            joints: Some(vec![0.0, -0.5, 0.5]),
            pose: Some(pose),
        }),
        Reply::OperatingState(OperatingStateMsg {
            state: "ENABLED".into(),
            is_homed: true,
            is_busy: false,
        }),
    ];
    for (k, r) in replies.into_iter().enumerate() {
        let bytes = postcard::to_stdvec(&r).unwrap();
        assert_eq!(usize::from(bytes[0]), 28 + k, "{r:?}");
        assert_eq!(postcard::from_bytes::<Reply>(&bytes).unwrap(), r);
    }
}
