//! The robots a recording draws in 3D ([`crate::objects::recording::scene`]): for each
//! recorded controller, the robot it drives, its model, its place in the row, its contact
//! shapes and its sensor's mount.

use penelope_hal::Pose;
use penelope_scene::default_placement;

use super::{KindState, Registry};
use crate::objects::recording::SceneRobot;

impl Registry {
    /// The robots `controllers` drive (once per robot, the first controller's ticks), placed
    /// side by side along world y in creation order, with the contact shapes of their
    /// simulated boards and their sensors' mounts. A controller with no robot bound draws
    /// nothing.
    pub(crate) fn scene_robots(&self, controllers: &[String]) -> Vec<SceneRobot> {
        let registry = self;
        // Every robot of the node in creation order: its place in the row.
        let mut order: Vec<(u64, &str)> = registry
            .objects
            .values()
            .filter_map(|o| match &o.body {
                KindState::Robot(r) => Some((r.created, o.name.as_str())),
                _ => None,
            })
            .collect();
        order.sort_unstable();
        let mut robots: Vec<SceneRobot> = Vec::new();
        for controller in controllers {
            let Some(KindState::Controller(c)) = registry.objects.get(controller).map(|o| &o.body)
            else {
                continue;
            };
            let Some(robot) = &c.robot else { continue };
            if robots.iter().any(|r| &r.robot == robot) {
                continue;
            }
            let Some(KindState::Robot(r)) = registry.objects.get(robot).map(|o| &o.body) else {
                continue;
            };
            let index = order.iter().position(|(_, n)| n == robot).unwrap_or(0);
            let sensor_mount = c.sensor.as_ref().map(|sensor| {
                match registry.objects.get(sensor).map(|o| &o.body) {
                    Some(KindState::Sensor(s)) => {
                        let [x, y, z] = s.config.mount_xyz;
                        Pose::translation(x, y, z)
                    }
                    Some(KindState::ReplaySensor(s)) => s.config.mount(),
                    Some(KindState::LoopSensor(s)) => s.mount(),
                    // A sensor on another node: its mount is not known here.
                    _ => Pose::identity(),
                }
            });
            robots.push(SceneRobot {
                robot: robot.clone(),
                controller: controller.clone(),
                model: r.model.clone(),
                placement: default_placement(index),
                contacts: registry.contacts_of(robot).unwrap_or_default(),
                sensor_mount,
            });
        }
        robots
    }
}
