//! The scene's messages built from a robot's frames, its contacts and its forces.

use penelope_hal::Pose;
use penelope_hal::nalgebra::{Translation3, Unit, UnitQuaternion, Vector3 as V3};

use crate::WORLD_FRAME;
use crate::messages::{
    ArrowPrimitive, Color, CubePrimitive, FrameTransform, FrameTransforms, Quaternion, SceneEntity,
    ScenePose, SpherePrimitive, Timestamp, Vector3,
};

/// A contact shape of a simulated environment, in a robot's root frame (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ContactShape {
    /// An infinite plane: free space on the side `normal` points to.
    Plane {
        /// A point on the plane.
        point: [f64; 3],
        /// Its normal into free space (need not be unit).
        normal: [f64; 3],
    },
    /// A solid sphere.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius.
        radius: f64,
    },
}

/// The side of the square drawn for an (infinite) plane, m.
pub const PLANE_SIDE_M: f64 = 1.0;
/// The thickness of the slab drawn for a plane, m.
pub const PLANE_THICKNESS_M: f64 = 0.004;

/// The frame id of `frame` of `robot_object`: `<robot_object>/<frame>`.
pub fn frame_id(robot_object: &str, frame: &str) -> String {
    format!("{robot_object}/{frame}")
}

/// Where the `index`-th robot (in creation order, from 0) stands in the world: side by side
/// along world y, 1 m apart.
pub fn default_placement(index: usize) -> Pose {
    Pose::from_parts(
        Translation3::new(0.0, index as f64, 0.0),
        UnitQuaternion::identity(),
    )
}

fn transform(parent: String, child: String, pose: &Pose, timestamp: Timestamp) -> FrameTransform {
    let p = ScenePose::from(pose);
    FrameTransform {
        timestamp,
        parent_frame_id: parent,
        child_frame_id: child,
        translation: p.position,
        rotation: p.orientation,
    }
}

/// The transforms of a robot's frames at one instant: `world` → `<robot>/<root>` by
/// `placement`, then `<robot>/<root>` → `<robot>/<frame>` by each pose (poses in the root
/// frame, as `link_frames` gives them; `frames[0]` is the root, its pose ignored). Frames and
/// poses are paired in order; extra entries of the longer list are ignored.
pub fn robot_transforms(
    robot_object: &str,
    frames: &[String],
    poses: &[Pose],
    placement: &Pose,
    time_ns: u64,
) -> FrameTransforms {
    let timestamp = Timestamp::from_ns(time_ns);
    let Some(root) = frames.first() else {
        return FrameTransforms::default();
    };
    let root_id = frame_id(robot_object, root);
    let mut transforms = Vec::with_capacity(frames.len());
    transforms.push(transform(
        WORLD_FRAME.to_string(),
        root_id.clone(),
        placement,
        timestamp,
    ));
    for (frame, pose) in frames.iter().zip(poses).skip(1) {
        transforms.push(transform(
            root_id.clone(),
            frame_id(robot_object, frame),
            pose,
            timestamp,
        ));
    }
    FrameTransforms { transforms }
}

/// The rotation taking +x onto `direction` (identity for a zero vector).
fn x_onto(direction: &V3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(&V3::x(), direction).unwrap_or_else(|| {
        if direction.x < 0.0 {
            // Antiparallel: half a turn about z.
            UnitQuaternion::from_axis_angle(&V3::z_axis(), std::f64::consts::PI)
        } else {
            UnitQuaternion::identity()
        }
    })
}

fn scene_pose(position: V3<f64>, rotation: UnitQuaternion<f64>) -> ScenePose {
    ScenePose {
        position: Vector3 {
            x: position.x,
            y: position.y,
            z: position.z,
        },
        orientation: Quaternion {
            x: rotation.coords.x,
            y: rotation.coords.y,
            z: rotation.coords.z,
            w: rotation.coords.w,
        },
    }
}

/// An arrow's length per newton of force, m: the same in the recordings and live.
pub const METRES_PER_NEWTON: f64 = 0.01;
/// The sensed wrench's arrow colour (red).
pub const SENSED_COLOR: Color = Color {
    r: 0.9,
    g: 0.15,
    b: 0.1,
    a: 1.0,
};
/// The displayed force's arrow colour (blue): what a master's motors are made to produce.
pub const DISPLAYED_COLOR: Color = Color {
    r: 0.1,
    g: 0.4,
    b: 0.95,
    a: 1.0,
};

/// An entity `id` holding one arrow from the origin of `frame_id` along `force` (N, expressed
/// in that frame), `metres_per_newton` long per newton (the head included), in `color`. A
/// force under 1 mN (or a non-finite one) gives the entity without an arrow, so the previous
/// arrow of that id disappears.
pub fn wrench_arrow(
    id: &str,
    frame_id: &str,
    force: [f64; 3],
    metres_per_newton: f64,
    color: Color,
    time_ns: u64,
) -> SceneEntity {
    let mut entity = SceneEntity::new(id, frame_id, time_ns);
    let f = V3::from(force);
    let magnitude = f.norm();
    if !(magnitude.is_finite() && magnitude >= 1e-3 && metres_per_newton > 0.0) {
        return entity;
    }
    let length = magnitude * metres_per_newton;
    let head = (0.25 * length).min(0.05);
    entity.arrows.push(ArrowPrimitive {
        pose: scene_pose(V3::zeros(), x_onto(&f)),
        shaft_length: length - head,
        shaft_diameter: (0.2 * head).max(0.004),
        head_length: head,
        head_diameter: (0.6 * head).max(0.01),
        color,
    });
    entity
}

/// An entity `id` drawing a contact shape in `frame_id` (the robot's root frame): a plane as a
/// thin square slab ([`PLANE_SIDE_M`] wide, its free side the slab's top face, centred on its
/// point), a sphere as a sphere; translucent grey.
pub fn wall_entity(id: &str, frame_id: &str, shape: &ContactShape, time_ns: u64) -> SceneEntity {
    let mut entity = SceneEntity::new(id, frame_id, time_ns);
    let color = Color {
        r: 0.55,
        g: 0.6,
        b: 0.7,
        a: 0.5,
    };
    match *shape {
        ContactShape::Plane { point, normal } => {
            let n = V3::from(normal);
            let Some(n) = Unit::try_new(n, 1e-12) else {
                return entity;
            };
            // The slab's z along the normal, its top face on the plane.
            let rotation = UnitQuaternion::rotation_between(&V3::z(), &n).unwrap_or_else(|| {
                UnitQuaternion::from_axis_angle(&V3::x_axis(), std::f64::consts::PI)
            });
            let centre = V3::from(point) - n.into_inner() * (PLANE_THICKNESS_M * 0.5);
            entity.cubes.push(CubePrimitive {
                pose: scene_pose(centre, rotation),
                size: Vector3 {
                    x: PLANE_SIDE_M,
                    y: PLANE_SIDE_M,
                    z: PLANE_THICKNESS_M,
                },
                color,
            });
        }
        ContactShape::Sphere { center, radius } => {
            let d = 2.0 * radius;
            entity.spheres.push(SpherePrimitive {
                pose: scene_pose(V3::from(center), UnitQuaternion::identity()),
                size: Vector3 { x: d, y: d, z: d },
                color,
            });
        }
    }
    entity
}
