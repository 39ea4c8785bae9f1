//! Foxglove's well-known messages as serde structs: serialised with `serde_json`, each is the
//! JSON encoding of its schema (field names and nesting as in [`crate::schemas`]).

use serde::{Deserialize, Serialize};

/// A point in time: seconds and nanoseconds (`time` in Foxglove's schemas).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Timestamp {
    /// Whole seconds.
    pub sec: u32,
    /// Nanoseconds, 0..=999 999 999.
    pub nsec: u32,
}

impl Timestamp {
    /// From nanoseconds (on whatever clock the channel uses); past `u32::MAX` seconds the
    /// seconds saturate.
    pub fn from_ns(ns: u64) -> Self {
        Timestamp {
            sec: u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX),
            nsec: (ns % 1_000_000_000) as u32,
        }
    }
}

/// A length of time (`duration` in Foxglove's schemas); zero lifetime means "until replaced".
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Duration {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, 0..=999 999 999.
    pub nsec: u32,
}

/// `foxglove.Vector3`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `foxglove.Quaternion` (unit, Hamilton convention, `w` the scalar part).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w (scalar).
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `foxglove.Pose`: a position and an orientation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ScenePose {
    /// Position, m.
    pub position: Vector3,
    /// Orientation.
    pub orientation: Quaternion,
}

impl From<&penelope_hal::Pose> for ScenePose {
    fn from(p: &penelope_hal::Pose) -> Self {
        let t = p.translation.vector;
        let q = p.rotation.coords;
        ScenePose {
            position: Vector3 {
                x: t.x,
                y: t.y,
                z: t.z,
            },
            orientation: Quaternion {
                x: q.x,
                y: q.y,
                z: q.z,
                w: q.w,
            },
        }
    }
}

/// `foxglove.Color`: RGBA, each 0..=1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Color {
    /// Red.
    pub r: f64,
    /// Green.
    pub g: f64,
    /// Blue.
    pub b: f64,
    /// Alpha (1: opaque).
    pub a: f64,
}

/// `foxglove.FrameTransform`: the pose of a child frame in its parent frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameTransform {
    /// When the transform holds.
    pub timestamp: Timestamp,
    /// The parent frame.
    pub parent_frame_id: String,
    /// The child frame.
    pub child_frame_id: String,
    /// The child's origin in the parent frame, m.
    pub translation: Vector3,
    /// The child's orientation in the parent frame.
    pub rotation: Quaternion,
}

/// `foxglove.FrameTransforms`: several transforms in one message.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameTransforms {
    /// The transforms.
    pub transforms: Vec<FrameTransform>,
}

/// `foxglove.KeyValuePair`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct KeyValuePair {
    /// Key.
    pub key: String,
    /// Value.
    pub value: String,
}

/// `foxglove.ArrowPrimitive`: an arrow along the +x axis of its pose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ArrowPrimitive {
    /// The arrow's tail and direction (+x).
    pub pose: ScenePose,
    /// Shaft length, m.
    pub shaft_length: f64,
    /// Shaft diameter, m.
    pub shaft_diameter: f64,
    /// Head length, m.
    pub head_length: f64,
    /// Head diameter, m.
    pub head_diameter: f64,
    /// Colour.
    pub color: Color,
}

/// `foxglove.CubePrimitive`: a box centred on its pose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CubePrimitive {
    /// Centre and orientation.
    pub pose: ScenePose,
    /// Edge lengths along the pose's x, y, z, m.
    pub size: Vector3,
    /// Colour.
    pub color: Color,
}

/// `foxglove.SpherePrimitive`: an ellipsoid centred on its pose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpherePrimitive {
    /// Centre and orientation.
    pub pose: ScenePose,
    /// Diameters along the pose's x, y, z, m.
    pub size: Vector3,
    /// Colour.
    pub color: Color,
}

/// `foxglove.SceneEntity`: primitives drawn in one frame. Only arrows, cubes and spheres are
/// built here; the other primitive lists are kept empty (the schema requires them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneEntity {
    /// When it holds.
    pub timestamp: Timestamp,
    /// The frame its primitives are given in.
    pub frame_id: String,
    /// Its id: a later entity with the same id on the topic replaces it.
    pub id: String,
    /// How long it shows (zero: until replaced or deleted).
    pub lifetime: Duration,
    /// Whether it stays attached to its frame as the frame moves.
    pub frame_locked: bool,
    /// Free key-value pairs.
    pub metadata: Vec<KeyValuePair>,
    /// Arrows.
    pub arrows: Vec<ArrowPrimitive>,
    /// Boxes.
    pub cubes: Vec<CubePrimitive>,
    /// Spheres.
    pub spheres: Vec<SpherePrimitive>,
    /// Cylinders (empty here).
    pub cylinders: Vec<serde_json::Value>,
    /// Lines (empty here).
    pub lines: Vec<serde_json::Value>,
    /// Triangles (empty here).
    pub triangles: Vec<serde_json::Value>,
    /// Texts (empty here).
    pub texts: Vec<serde_json::Value>,
    /// Models (empty here).
    pub models: Vec<serde_json::Value>,
}

impl SceneEntity {
    /// An entity with no primitives yet.
    pub fn new(id: &str, frame_id: &str, time_ns: u64) -> Self {
        SceneEntity {
            timestamp: Timestamp::from_ns(time_ns),
            frame_id: frame_id.to_string(),
            id: id.to_string(),
            lifetime: Duration::default(),
            frame_locked: true,
            metadata: Vec::new(),
            arrows: Vec::new(),
            cubes: Vec::new(),
            spheres: Vec::new(),
            cylinders: Vec::new(),
            lines: Vec::new(),
            triangles: Vec::new(),
            texts: Vec::new(),
            models: Vec::new(),
        }
    }
}

/// `foxglove.SceneEntityDeletion`: removes one entity (`type` 0, by id) or all (`type` 1).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SceneEntityDeletion {
    /// When it applies.
    pub timestamp: Timestamp,
    /// 0: the entity `id`; 1: every entity on the topic.
    #[serde(rename = "type")]
    pub kind: u8,
    /// The entity's id (ignored for type 1).
    pub id: String,
}

/// `foxglove.SceneUpdate`: entities to delete, then entities to add or replace.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SceneUpdate {
    /// Deletions.
    pub deletions: Vec<SceneEntityDeletion>,
    /// Additions and replacements.
    pub entities: Vec<SceneEntity>,
}

/// `penelope.RobotDescription`: a robot's URDF and its frames, on
/// `/robot_description/<robot>` (a 3D panel's URDF layer reads the `urdf` field).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RobotDescription {
    /// The robot object's name (the prefix of its frame ids).
    pub robot: String,
    /// The URDF; its link names are `frames`.
    pub urdf: String,
    /// The robot's frames, root first (their ids are `<robot>/<frame>`).
    pub frames: Vec<String>,
}

/// `foxglove.CompressedImage`: a camera frame (JPEG, PNG, ...), its bytes base64 in the JSON
/// encoding, stamped with its capture instant.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// The frame's capture instant.
    pub timestamp: Timestamp,
    /// The camera's optical frame (x right, y down, z forward).
    pub frame_id: String,
    /// The compressed bytes, base64.
    #[serde(with = "base64_bytes")]
    pub data: Vec<u8>,
    /// `jpeg`, `png`, `webp` or `avif`.
    pub format: String,
}

/// `foxglove.CameraCalibration`: a pinhole camera's intrinsics, with which a 3D panel places
/// the image in the scene and a user projects points onto it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraCalibration {
    /// When it holds from.
    pub timestamp: Timestamp,
    /// The camera's optical frame.
    pub frame_id: String,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// `plumb_bob` (with `D` empty: no distortion).
    pub distortion_model: String,
    /// Distortion parameters.
    #[serde(rename = "D")]
    pub d: Vec<f64>,
    /// Intrinsic matrix, row-major 3x3.
    #[serde(rename = "K")]
    pub k: [f64; 9],
    /// Rectification matrix, row-major 3x3 (the identity for a monocular camera).
    #[serde(rename = "R")]
    pub r: [f64; 9],
    /// Projection matrix, row-major 3x4.
    #[serde(rename = "P")]
    pub p: [f64; 12],
}

impl CameraCalibration {
    /// An ideal pinhole camera (no distortion, identity rectification) of `width` x `height`
    /// px with focal lengths `f` = `[fx, fy]` and principal point `c` = `[cx, cy]` (px).
    pub fn pinhole(
        timestamp: Timestamp,
        frame_id: String,
        (width, height): (u32, u32),
        [fx, fy]: [f64; 2],
        [cx, cy]: [f64; 2],
    ) -> Self {
        CameraCalibration {
            timestamp,
            frame_id,
            width,
            height,
            distortion_model: "plumb_bob".into(),
            d: Vec::new(),
            k: [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        }
    }
}

/// Bytes as a base64 string, as Foxglove's JSON encoding writes a `bytes` field.
mod base64_bytes {
    use base64::Engine as _;
    use base64::engine::general_purpose::STANDARD;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(bytes: &[u8], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&STANDARD.encode(bytes))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
        let text = String::deserialize(d)?;
        STANDARD.decode(text).map_err(serde::de::Error::custom)
    }
}
