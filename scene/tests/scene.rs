//! The scene's messages: their JSON against the vendored Foxglove JSON Schemas (a validator of
//! the subset those schemas use: type, properties, required, items, minimum/maximum, oneOf of
//! consts), and the builders' geometry (frame tree, arrows, walls).

use penelope_hal::Pose;
use penelope_hal::nalgebra::{Translation3, UnitQuaternion, Vector3};
use penelope_scene::{
    Color, ContactShape, FRAME_TRANSFORMS, RobotDescription, SCENE_UPDATE, SceneUpdate,
    default_placement, robot_transforms, schema, schemas, wall_entity, wrench_arrow,
};
use serde_json::Value;

/// Checks `v` against `s`; returns where it fails.
fn validate(v: &Value, s: &Value, at: &str) -> Result<(), String> {
    if let Some(options) = s.get("oneOf").and_then(Value::as_array) {
        let matched = options
            .iter()
            .filter(|o| validate(v, o, at).is_ok())
            .count();
        return if matched == 1 {
            Ok(())
        } else {
            Err(format!("{at}: {matched} of oneOf match"))
        };
    }
    if let Some(c) = s.get("const") {
        return if v == c {
            Ok(())
        } else {
            Err(format!("{at}: {v} is not {c}"))
        };
    }
    let ty = s.get("type").and_then(Value::as_str);
    let ok = match ty {
        Some("object") => v.is_object(),
        Some("array") => v.is_array(),
        Some("string") => v.is_string(),
        Some("number") => v.is_number(),
        Some("integer") => v.is_i64() || v.is_u64(),
        Some("boolean") => v.is_boolean(),
        Some(other) => return Err(format!("{at}: schema type {other} not handled")),
        None => true,
    };
    if !ok {
        return Err(format!("{at}: {v} is not of type {ty:?}"));
    }
    if let Some(min) = s.get("minimum").and_then(Value::as_f64)
        && v.as_f64().is_some_and(|x| x < min)
    {
        return Err(format!("{at}: {v} below {min}"));
    }
    if let Some(max) = s.get("maximum").and_then(Value::as_f64)
        && v.as_f64().is_some_and(|x| x > max)
    {
        return Err(format!("{at}: {v} above {max}"));
    }
    if let (Some(obj), Some(props)) = (
        v.as_object(),
        s.get("properties").and_then(Value::as_object),
    ) {
        for r in s
            .get("required")
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
        {
            let r = r.as_str().unwrap();
            if !obj.contains_key(r) {
                return Err(format!("{at}: `{r}` missing"));
            }
        }
        for (k, x) in obj {
            let Some(p) = props.get(k) else {
                return Err(format!("{at}: `{k}` is not in the schema"));
            };
            validate(x, p, &format!("{at}.{k}"))?;
        }
    }
    if let (Some(items), Some(each)) = (v.as_array(), s.get("items")) {
        for (i, x) in items.iter().enumerate() {
            validate(x, each, &format!("{at}[{i}]"))?;
        }
    }
    Ok(())
}

fn check(name: &str, msg: &impl serde::Serialize) {
    let schema: Value = serde_json::from_str(schema(name).unwrap()).unwrap();
    assert_eq!(schema["title"], name);
    let v = serde_json::to_value(msg).unwrap();
    validate(&v, &schema, name).unwrap_or_else(|e| panic!("{e}\n{v}"));
}

fn frames() -> Vec<String> {
    ["base_link", "link1", "tool"].map(String::from).to_vec()
}

fn poses() -> Vec<Pose> {
    vec![
        Pose::identity(),
        Pose::from_parts(
            Translation3::new(0.0, 0.0, 0.5),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
        ),
        Pose::from_parts(
            Translation3::new(0.4, 0.1, 0.6),
            UnitQuaternion::from_euler_angles(0.2, -0.4, 1.0),
        ),
    ]
}

#[test]
fn every_vendored_schema_is_json_with_its_name_as_title() {
    for (name, text) in schemas::ALL {
        let v: Value = serde_json::from_str(text).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(v["title"], name);
    }
    assert!(schema("foxglove.NoSuchThing").is_none());
}

#[test]
fn the_messages_are_valid_against_foxglove_schemas() {
    let tf = robot_transforms(
        "slave",
        &frames(),
        &poses(),
        &default_placement(1),
        1_500_000_123,
    );
    check(FRAME_TRANSFORMS, &tf);
    check("foxglove.FrameTransform", &tf.transforms[0]);
    let red = Color {
        r: 1.0,
        g: 0.0,
        b: 0.0,
        a: 1.0,
    };
    let update = SceneUpdate {
        deletions: vec![],
        entities: vec![
            wrench_arrow(
                "slave/wrench",
                "slave/tool",
                [3.0, -4.0, 12.0],
                0.01,
                red,
                7,
            ),
            wrench_arrow("slave/none", "slave/tool", [0.0; 3], 0.01, red, 7),
            wall_entity(
                "slave/wall0",
                "slave/base_link",
                &ContactShape::Plane {
                    point: [0.6, 0.0, 0.0],
                    normal: [-1.0, 0.0, 0.0],
                },
                7,
            ),
            wall_entity(
                "slave/ball",
                "slave/base_link",
                &ContactShape::Sphere {
                    center: [0.0, 0.3, 0.2],
                    radius: 0.1,
                },
                7,
            ),
        ],
    };
    check(SCENE_UPDATE, &update);
    check("foxglove.SceneEntity", &update.entities[0]);
    check("foxglove.ArrowPrimitive", &update.entities[0].arrows[0]);
    check("foxglove.CubePrimitive", &update.entities[2].cubes[0]);
    check(
        penelope_scene::ROBOT_DESCRIPTION,
        &RobotDescription {
            robot: "slave".into(),
            urdf: "<robot/>".into(),
            frames: frames(),
        },
    );
    // A message missing a required field fails the validator (it can fail).
    let mut v = serde_json::to_value(&tf).unwrap();
    v["transforms"][0]
        .as_object_mut()
        .unwrap()
        .remove("rotation");
    let s: Value = serde_json::from_str(schema(FRAME_TRANSFORMS).unwrap()).unwrap();
    assert!(validate(&v, &s, "tf").is_err());
}

fn pose_of(t: &penelope_scene::FrameTransform) -> Pose {
    Pose::from_parts(
        Translation3::new(t.translation.x, t.translation.y, t.translation.z),
        UnitQuaternion::from_quaternion(penelope_hal::nalgebra::Quaternion::new(
            t.rotation.w,
            t.rotation.x,
            t.rotation.y,
            t.rotation.z,
        )),
    )
}

#[test]
fn the_frame_tree_places_the_robot_then_every_link_in_its_root() {
    let placement = default_placement(2);
    assert_eq!(placement.translation.vector, Vector3::new(0.0, 2.0, 0.0));
    let tf = robot_transforms("master", &frames(), &poses(), &placement, 3_000_000_007);
    assert_eq!(tf.transforms.len(), 3);
    assert_eq!(tf.transforms[0].parent_frame_id, "world");
    assert_eq!(tf.transforms[0].child_frame_id, "master/base_link");
    for (t, name) in tf.transforms[1..]
        .iter()
        .zip(["master/link1", "master/tool"])
    {
        assert_eq!(t.parent_frame_id, "master/base_link");
        assert_eq!(t.child_frame_id, name);
        assert_eq!((t.timestamp.sec, t.timestamp.nsec), (3, 7));
    }
    // world -> tool composes placement and the tool's pose.
    let tool = pose_of(&tf.transforms[0]) * pose_of(&tf.transforms[2]);
    let expected = placement * poses()[2];
    assert!((tool.translation.vector - expected.translation.vector).norm() < 1e-12);
    assert!(tool.rotation.angle_to(&expected.rotation) < 1e-9);
}

#[test]
fn an_arrow_points_along_its_force_and_scales_with_it() {
    let c = Color {
        r: 0.0,
        g: 1.0,
        b: 0.0,
        a: 1.0,
    };
    for f in [[3.0, -4.0, 12.0], [-2.0, 0.0, 0.0], [0.0, 0.0, -5.0]] {
        let e = wrench_arrow("a", "x/tool", f, 0.02, c, 0);
        let a = &e.arrows[0];
        let q = a.pose.orientation;
        let r = UnitQuaternion::from_quaternion(penelope_hal::nalgebra::Quaternion::new(
            q.w, q.x, q.y, q.z,
        ));
        let dir = r * Vector3::x();
        let force = Vector3::from(f);
        assert!((dir - force.normalize()).norm() < 1e-9, "{f:?} -> {dir}");
        assert!((a.shaft_length + a.head_length - 0.02 * force.norm()).abs() < 1e-12);
    }
    assert!(
        wrench_arrow("a", "x/tool", [1e-5, 0.0, 0.0], 0.02, c, 0)
            .arrows
            .is_empty()
    );
    assert!(
        wrench_arrow("a", "x/tool", [f64::NAN, 0.0, 0.0], 0.02, c, 0)
            .arrows
            .is_empty()
    );
}

#[test]
fn a_wall_is_a_slab_whose_top_face_is_the_plane() {
    let e = wall_entity(
        "w",
        "x/base_link",
        &ContactShape::Plane {
            point: [0.6, 0.1, 0.2],
            normal: [-2.0, 0.0, 0.0],
        },
        0,
    );
    let cube = &e.cubes[0];
    let q = cube.pose.orientation;
    let r = UnitQuaternion::from_quaternion(penelope_hal::nalgebra::Quaternion::new(
        q.w, q.x, q.y, q.z,
    ));
    let up = r * Vector3::z();
    assert!((up - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-9);
    let centre = Vector3::new(
        cube.pose.position.x,
        cube.pose.position.y,
        cube.pose.position.z,
    );
    let top = centre + up * (cube.size.z / 2.0);
    assert!((top - Vector3::new(0.6, 0.1, 0.2)).norm() < 1e-12);
    let s = wall_entity(
        "s",
        "x/base_link",
        &ContactShape::Sphere {
            center: [0.0; 3],
            radius: 0.1,
        },
        0,
    );
    assert_eq!(s.spheres[0].size.x, 0.2);
}

#[test]
fn a_camera_frame_and_its_calibration_are_valid_and_the_bytes_round_trip() {
    let image = penelope_scene::CompressedImage {
        timestamp: penelope_scene::Timestamp::from_ns(2_000_000_017),
        frame_id: "camera/optical".into(),
        data: vec![0xff, 0xd8, 0xff, 0x00, 0x10, 0xd9],
        format: "jpeg".into(),
    };
    check(penelope_scene::COMPRESSED_IMAGE, &image);
    let v = serde_json::to_value(&image).unwrap();
    assert_eq!(v["data"], "/9j/ABDZ", "Foxglove's base64 of the bytes");
    let back: penelope_scene::CompressedImage = serde_json::from_value(v).unwrap();
    assert_eq!(back, image);
    let calibration = penelope_scene::CameraCalibration {
        timestamp: penelope_scene::Timestamp::from_ns(0),
        frame_id: "camera/optical".into(),
        width: 640,
        height: 480,
        distortion_model: "plumb_bob".into(),
        d: vec![],
        k: [554.0, 0.0, 320.0, 0.0, 554.0, 240.0, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [
            554.0, 0.0, 320.0, 0.0, 0.0, 554.0, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
    };
    check(penelope_scene::CAMERA_CALIBRATION, &calibration);
    let v = serde_json::to_value(&calibration).unwrap();
    assert_eq!(v["K"][2], 320.0);
}
