//! The robots in 3D: each robot's description (its URDF, frames and the contact shapes of its
//! simulated world) asked once through the protocol, its place in the world (side by side along
//! world y, 1 m apart in the order the robots were found, as in the recordings), and its frames'
//! transforms at a tick's joint positions (`RobotProxy::link_frames`, the node's own model).
//!
//! Topics, as in the recordings (`penelope-scene` builds every message):
//! - `/robot_description/<robot>` (`penelope.RobotDescription`, latched: each subscriber gets
//!   it at once);
//! - `/tf` (`foxglove.FrameTransforms`): every frame of the robot at each published tick;
//! - `/scene` (`foxglove.SceneUpdate`): the robot's contact shapes (the wall), its sensed
//!   wrench and its displayed force (the commanded wrench: what a master's motors produce) as
//!   arrows at the tool.

use std::sync::Arc;

use penelope_hal::nalgebra::Vector3;
use penelope_hal::{JointVector, Pose};
use penelope_protocol::client::RobotProxy;
use penelope_protocol::net::conn::RpcError;
use penelope_protocol::proto::{ContactShapeMsg, TelemetryRecord};
use penelope_scene::{
    ContactShape, DISPLAYED_COLOR, METRES_PER_NEWTON, RobotDescription, SENSED_COLOR, SceneUpdate,
    frame_id, robot_transforms, wall_entity, wrench_arrow,
};

use crate::hub::Hub;

/// One robot as drawn: its proxy, frames, contact shapes and place, and the channels it feeds.
pub struct RobotView {
    /// The robot object's name (its frame ids' prefix).
    pub name: String,
    proxy: RobotProxy,
    frames: Vec<String>,
    walls: Vec<ContactShape>,
    placement: Pose,
    hub: Arc<Hub>,
    tf: u32,
    scene: u32,
    /// Its description's channel.
    pub description: u32,
}

fn contact_shape(c: &ContactShapeMsg) -> ContactShape {
    match *c {
        ContactShapeMsg::Plane { point, normal } => ContactShape::Plane { point, normal },
        ContactShapeMsg::Sphere { center, radius } => ContactShape::Sphere { center, radius },
    }
}

impl RobotView {
    /// Asks `proxy` for the robot's description and serves it (latched) on
    /// `/robot_description/<name>`; `/tf` and `/scene` are the channels `tf` and `scene`.
    ///
    /// # Errors
    /// The node's answer to the description, or a transport error.
    pub fn describe(
        name: &str,
        proxy: RobotProxy,
        placement: Pose,
        hub: Arc<Hub>,
        channels: (u32, u32),
        time_ns: u64,
    ) -> Result<Self, RpcError> {
        let d = proxy.description()?;
        let topic = penelope_scene::robot_description_topic(name);
        let description = hub.add_channel(
            &topic,
            penelope_scene::ROBOT_DESCRIPTION,
            penelope_scene::schemas::ROBOT_DESCRIPTION_SCHEMA,
        );
        let message = RobotDescription {
            robot: name.to_string(),
            urdf: d.urdf,
            frames: d.frames.clone(),
        };
        let payload = serde_json::to_vec(&message).unwrap_or_default();
        hub.publish_latched(description, time_ns, &payload);
        Ok(RobotView {
            name: name.to_string(),
            proxy,
            frames: d.frames,
            walls: d.contacts.iter().map(contact_shape).collect(),
            placement,
            hub,
            tf: channels.0,
            scene: channels.1,
            description,
        })
    }

    /// Draws the robot at `record`'s joint positions, stamped `time_ns` (common clock): its
    /// frames on `/tf` (the node's model gives their poses) and its walls and sensed wrench on
    /// `/scene`. Nothing is asked of the node when no client subscribes to either.
    ///
    /// # Errors
    /// The node's answer to `link_frames`, or a transport error.
    pub fn draw(&self, record: &TelemetryRecord, time_ns: u64) -> Result<(), RpcError> {
        let tf = self.hub.has_subscribers(self.tf);
        let scene = self.hub.has_subscribers(self.scene);
        if !(tf || scene) {
            return Ok(());
        }
        let mut q = JointVector::zeros();
        for (slot, value) in q.iter_mut().zip(&record.q) {
            *slot = *value;
        }
        let poses = self.proxy.link_frames(Some(&q))?;
        if tf {
            let message =
                robot_transforms(&self.name, &self.frames, &poses, &self.placement, time_ns);
            let payload = serde_json::to_vec(&message).unwrap_or_default();
            self.hub.publish(self.tf, time_ns, &payload);
        }
        if scene {
            let message = scene_update(
                &self.name,
                &self.frames,
                &self.walls,
                record,
                &poses,
                time_ns,
            );
            let payload = serde_json::to_vec(&message).unwrap_or_default();
            self.hub.publish(self.scene, time_ns, &payload);
        }
        Ok(())
    }
}

/// `name`'s walls (in its root frame, the first of `frames`) and its sensed wrench as an arrow
/// at the tool (the last frame, whose pose in the root frame is the last of `poses`).
pub fn scene_update(
    name: &str,
    frames: &[String],
    walls: &[ContactShape],
    record: &TelemetryRecord,
    poses: &[Pose],
    time_ns: u64,
) -> SceneUpdate {
    let root = frame_id(name, frames.first().map_or("", String::as_str));
    let tool = frame_id(name, frames.last().map_or("", String::as_str));
    let mut entities: Vec<_> = walls
        .iter()
        .enumerate()
        .map(|(k, w)| wall_entity(&format!("{name}/contact{k}"), &root, w, time_ns))
        .collect();
    // The wire's wrenches are in the base frame; the arrows are drawn in the tool's.
    let tool_pose = poses.last().copied().unwrap_or_else(Pose::identity);
    for (what, force, color) in [
        ("sensed_wrench", record.wrench.force, SENSED_COLOR),
        (
            "displayed_force",
            record.commanded_wrench.force,
            DISPLAYED_COLOR,
        ),
    ] {
        let f = tool_pose.rotation.inverse() * Vector3::from(force);
        entities.push(wrench_arrow(
            &format!("{name}/{what}"),
            &tool,
            [f.x, f.y, f.z],
            METRES_PER_NEWTON,
            color,
            time_ns,
        ));
    }
    SceneUpdate {
        deletions: Vec::new(),
        entities,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_hal::nalgebra::{Translation3, UnitQuaternion};
    use penelope_protocol::proto::WrenchMsg;

    #[test]
    fn the_sensed_force_is_drawn_in_the_tool_frame_and_the_wall_in_the_root_frame() {
        let frames: Vec<String> = ["base_link", "link1", "tool"].map(String::from).to_vec();
        // The tool turned half a turn about x: a push up (+z, base) is -z in the tool's frame.
        let tool = Pose::from_parts(
            Translation3::new(0.3, 0.0, 0.2),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
        );
        let record = TelemetryRecord {
            time_ns: 9,
            seq: 1,
            q: vec![0.0; 6],
            qd: vec![0.0; 6],
            effort: vec![0.0; 6],
            tool_position: [0.3, 0.0, 0.2],
            wrench: WrenchMsg {
                force: [0.0, 0.0, 20.0],
                torque: [0.0; 3],
            },
            state: "running".into(),
            fault: None,
            commanded_wrench: WrenchMsg {
                force: [0.0; 3],
                torque: [0.0; 3],
            },
            clutch: None,
            port_energy: None,
            channel_energy: None,
        };
        let walls = [ContactShape::Plane {
            point: [0.35, 0.1, 0.29],
            normal: [0.0, 0.0, 1.0],
        }];
        let update = scene_update(
            "puma",
            &frames,
            &walls,
            &record,
            &[Pose::identity(), Pose::identity(), tool],
            9,
        );
        // The wall, the sensed wrench, and the displayed force (none commanded: no arrow).
        assert_eq!(update.entities.len(), 3);
        let displayed = &update.entities[2];
        assert_eq!(displayed.id, "puma/displayed_force");
        assert!(displayed.arrows.is_empty());
        let wall = &update.entities[0];
        assert_eq!(
            (wall.id.as_str(), wall.frame_id.as_str()),
            ("puma/contact0", "puma/base_link")
        );
        assert_eq!(wall.cubes.len(), 1);
        let arrow = &update.entities[1];
        assert_eq!(
            (arrow.id.as_str(), arrow.frame_id.as_str()),
            ("puma/sensed_wrench", "puma/tool")
        );
        // The arrow points along the force in the tool frame: -z, 20 N at 1 cm/N = 0.2 m.
        let a = &arrow.arrows[0];
        assert!((a.shaft_length + a.head_length - 0.2).abs() < 1e-9);
        let q = &a.pose.orientation;
        let along = UnitQuaternion::from_quaternion(penelope_hal::nalgebra::Quaternion::new(
            q.w, q.x, q.y, q.z,
        )) * Vector3::x();
        assert!(
            (along - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-9,
            "{along}"
        );
        // No force, no arrow (the entity stays, so the last arrow goes away).
        let mut still = record.clone();
        still.wrench.force = [0.0; 3];
        let update = scene_update("puma", &frames, &[], &still, &[tool], 9);
        assert!(update.entities[0].arrows.is_empty());
    }
}
