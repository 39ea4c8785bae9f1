//! The schemas of the scene's channels: Foxglove's published JSON Schemas, vendored unchanged
//! (`scene/schemas/`, MIT: `scene/LICENSE-foxglove-schemas`), and Penelope's own
//! `penelope.RobotDescription`.

/// `foxglove.FrameTransforms`.
pub const FRAME_TRANSFORMS: &str = "foxglove.FrameTransforms";
/// `foxglove.FrameTransform`.
pub const FRAME_TRANSFORM: &str = "foxglove.FrameTransform";
/// `foxglove.SceneUpdate`.
pub const SCENE_UPDATE: &str = "foxglove.SceneUpdate";
/// `foxglove.SceneEntity`.
pub const SCENE_ENTITY: &str = "foxglove.SceneEntity";
/// `foxglove.ArrowPrimitive`.
pub const ARROW_PRIMITIVE: &str = "foxglove.ArrowPrimitive";
/// `foxglove.CubePrimitive`.
pub const CUBE_PRIMITIVE: &str = "foxglove.CubePrimitive";
/// `penelope.RobotDescription` (Penelope's own: a robot's URDF and frames).
pub const ROBOT_DESCRIPTION: &str = "penelope.RobotDescription";

/// The JSON Schema of `penelope.RobotDescription`.
pub const ROBOT_DESCRIPTION_SCHEMA: &str = r#"{
  "title": "penelope.RobotDescription",
  "description": "A robot's URDF and its frames (frame ids on /tf are <robot>/<frame>)",
  "type": "object",
  "properties": {
    "robot": { "type": "string", "description": "The robot object's name" },
    "urdf": { "type": "string", "description": "The URDF; its link names are the frames" },
    "frames": { "type": "array", "items": { "type": "string" }, "description": "Root first" }
  },
  "required": ["robot", "urdf", "frames"]
}
"#;

/// The camera frame's schema.
pub const COMPRESSED_IMAGE: &str = "foxglove.CompressedImage";
/// The camera calibration's schema.
pub const CAMERA_CALIBRATION: &str = "foxglove.CameraCalibration";
/// The schema of 2D annotations drawn on a camera's frames (circles, lines, texts).
pub const IMAGE_ANNOTATIONS: &str = "foxglove.ImageAnnotations";

/// Every schema this crate knows: `(name, JSON Schema text)`.
pub const ALL: [(&str, &str); 17] = [
    (
        FRAME_TRANSFORMS,
        include_str!("../schemas/FrameTransforms.json"),
    ),
    (
        FRAME_TRANSFORM,
        include_str!("../schemas/FrameTransform.json"),
    ),
    (SCENE_UPDATE, include_str!("../schemas/SceneUpdate.json")),
    (SCENE_ENTITY, include_str!("../schemas/SceneEntity.json")),
    (
        "foxglove.SceneEntityDeletion",
        include_str!("../schemas/SceneEntityDeletion.json"),
    ),
    (
        ARROW_PRIMITIVE,
        include_str!("../schemas/ArrowPrimitive.json"),
    ),
    (
        CUBE_PRIMITIVE,
        include_str!("../schemas/CubePrimitive.json"),
    ),
    (
        "foxglove.SpherePrimitive",
        include_str!("../schemas/SpherePrimitive.json"),
    ),
    ("foxglove.Pose", include_str!("../schemas/Pose.json")),
    ("foxglove.Vector3", include_str!("../schemas/Vector3.json")),
    (
        "foxglove.Quaternion",
        include_str!("../schemas/Quaternion.json"),
    ),
    ("foxglove.Color", include_str!("../schemas/Color.json")),
    (
        "foxglove.KeyValuePair",
        include_str!("../schemas/KeyValuePair.json"),
    ),
    (ROBOT_DESCRIPTION, ROBOT_DESCRIPTION_SCHEMA),
    (
        COMPRESSED_IMAGE,
        include_str!("../schemas/CompressedImage.json"),
    ),
    (
        CAMERA_CALIBRATION,
        include_str!("../schemas/CameraCalibration.json"),
    ),
    (
        IMAGE_ANNOTATIONS,
        include_str!("../schemas/ImageAnnotations.json"),
    ),
];

/// The JSON Schema text of the schema `name` (such as `"foxglove.FrameTransforms"`), or
/// `None` for a schema this crate does not carry.
pub fn schema(name: &str) -> Option<&'static str> {
    ALL.iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
}
