//! Penelope's robots as a 3D scene, in Foxglove's well-known messages.
//!
//! Recordings (`runtime`'s MCAP recorder) and the live Foxglove gateway publish the same
//! channels, built here:
//!
//! | Topic | Schema | What |
//! |---|---|---|
//! | [`TOPIC_TF`] `/tf` | [`FRAME_TRANSFORMS`] `foxglove.FrameTransforms` | every link of every robot |
//! | [`TOPIC_SCENE`] `/scene` | [`SCENE_UPDATE`] `foxglove.SceneUpdate` | walls and other contact shapes, force arrows |
//! | `/robot_description/<robot>` ([`robot_description_topic`]) | [`ROBOT_DESCRIPTION`] `penelope.RobotDescription` | the robot's URDF |
//!
//! Messages are serde structs whose JSON is Foxglove's JSON encoding of the schema
//! ([`messages`]); the schemas' text is vendored unchanged from Foxglove's published JSON
//! Schemas ([`schemas`], MIT, see `LICENSE-foxglove-schemas`). The frame tree
//! ([`robot_transforms`]): `world` → `<robot>/<root>` (the robot's placement, side by side
//! along world y by default: [`default_placement`]) → `<robot>/<frame>` for every other frame.
//!
//! Nothing here is for a real-time loop: building a message allocates.

#![warn(missing_docs)]

pub mod builders;
pub mod messages;
pub mod schemas;

pub use builders::{
    ContactShape, DISPLAYED_COLOR, METRES_PER_NEWTON, SENSED_COLOR, default_placement, frame_id,
    robot_transforms, wall_entity, wrench_arrow,
};
pub use messages::{
    ArrowPrimitive, CameraCalibration, Color, CompressedImage, CubePrimitive, Duration,
    FrameTransform, FrameTransforms, KeyValuePair, Quaternion, RobotDescription, SceneEntity,
    SceneEntityDeletion, ScenePose, SceneUpdate, SpherePrimitive, Timestamp, Vector3,
};
pub use schemas::{
    CAMERA_CALIBRATION, COMPRESSED_IMAGE, FRAME_TRANSFORMS, IMAGE_ANNOTATIONS, ROBOT_DESCRIPTION,
    SCENE_UPDATE, schema,
};

/// The topic of every robot's link transforms (`foxglove.FrameTransforms`).
pub const TOPIC_TF: &str = "/tf";
/// The topic of the environment and the force arrows (`foxglove.SceneUpdate`).
pub const TOPIC_SCENE: &str = "/scene";
/// The prefix of a robot's description topic.
pub const TOPIC_ROBOT_DESCRIPTION_PREFIX: &str = "/robot_description/";
/// The frame every robot is placed in.
pub const WORLD_FRAME: &str = "world";

/// The topic of `robot_object`'s description: `/robot_description/<robot_object>`.
pub fn robot_description_topic(robot_object: &str) -> String {
    format!("{TOPIC_ROBOT_DESCRIPTION_PREFIX}{robot_object}")
}
