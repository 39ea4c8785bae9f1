//! Applying a system file to a node: create, relate, configure and activate its objects there,
//! or keep none of them.

use penelope_hal::Transition;
use penelope_protocol::proto::{
    Call, ControllerMethod, CreatorCall, Method, ObjectInfo, Reply, RobotMethod, WireError,
};

use super::{ObjectSpec, SystemFile, SystemFileError, class_key};

/// What a system file is applied to: a node, by its name and its calls (the node module
/// implements it for `Node`, so this module needs nothing of the node).
pub trait ApplyTarget {
    /// The node's name: the file's objects placed on it are applied.
    fn node_name(&self) -> &str;
    /// One call to the node, served as its server serves a peer's.
    ///
    /// # Errors
    /// The node's refusal.
    fn node_call(&self, call: Call) -> Result<Reply, WireError>;
}

impl SystemFile {
    /// Creates, relates, configures and activates the objects on `node`. On any refusal every
    /// object created from the file is destroyed again (forced: loops stopped, amplifiers off).
    ///
    /// # Errors
    /// [`SystemFileError::Invalid`] when the file names its nodes and `node` is not one of them;
    /// [`SystemFileError::Step`] for the first refused step.
    pub fn apply(&self, node: &impl ApplyTarget) -> Result<Vec<ObjectInfo>, SystemFileError> {
        self.apply_through(node.node_name(), |call| node.node_call(call))
    }

    /// [`SystemFile::apply`] to node `node` through `call`, which sends one call to that node's
    /// creator, step for step: the node serves `CreatorCall::ApplySystem` this way, each step
    /// a call of its own service (so what is created is bound by name).
    ///
    /// # Errors
    /// As [`SystemFile::apply`].
    pub fn apply_through(
        &self,
        node: &str,
        call: impl Fn(Call) -> Result<Reply, WireError>,
    ) -> Result<Vec<ObjectInfo>, SystemFileError> {
        // A file that names its nodes is applied only to one of them (never silently to none).
        let names = self.node_names();
        if !names.is_empty() && !names.iter().any(|n| n == node) {
            return Err(SystemFileError::Invalid {
                line: 1,
                key: "node".into(),
                message: format!("the file places objects on {names:?}, not on `{node}`"),
            });
        }
        let objects: Vec<&ObjectSpec> = self.objects_on(node).collect();
        let mut created: Vec<ObjectInfo> = Vec::new();
        let result = apply_steps(&call, &objects, &mut created);
        if let Err(e) = result {
            // Controllers first, so that nothing they use is still held.
            for info in created.iter().rev() {
                let _ = call(Call::Creator(CreatorCall::Destroy {
                    name: info.name.clone(),
                    force: true,
                }));
            }
            return Err(e);
        }
        Ok(created)
    }
}

fn apply_steps(
    call: &impl Fn(Call) -> Result<Reply, WireError>,
    objects: &[&ObjectSpec],
    created: &mut Vec<ObjectInfo>,
) -> Result<(), SystemFileError> {
    let step = |o: &ObjectSpec, step: &str, c: Call| {
        call(c).map_err(|error| SystemFileError::Step {
            line: o.line,
            key: format!("{}.{}", class_key(&o.kind), o.name),
            step: step.to_string(),
            error,
        })
    };
    let object = |o: &ObjectSpec, method: Method| Call::Object {
        object: o.name.clone(),
        method,
    };
    for o in objects {
        let reply = step(
            o,
            "create",
            Call::Creator(CreatorCall::Create {
                kind: o.kind.clone(),
                name: o.name.clone(),
                config: o.config.clone(),
            }),
        )?;
        if let Reply::Object(info) = reply {
            created.push(info);
        }
    }
    for o in objects {
        for m in &o.joints {
            let method = Method::Robot(RobotMethod::MapJoints {
                board: m.board.clone(),
                joints: m.joints.clone(),
            });
            step(o, "map joints", object(o, method))?;
        }
        let relations = [
            (&o.robot, "set robot"),
            (&o.trajectory, "set trajectory"),
            (&o.sensor, "set sensor"),
        ];
        for (value, what) in relations {
            let Some(v) = value else { continue };
            let m = match what {
                "set robot" => ControllerMethod::SetRobot { robot: v.clone() },
                "set trajectory" => ControllerMethod::SetTrajectory {
                    trajectory: v.clone(),
                },
                _ => ControllerMethod::SetSensor { sensor: v.clone() },
            };
            step(o, what, object(o, Method::Controller(m)))?;
        }
    }
    for o in objects {
        step(
            o,
            "configure",
            object(o, Method::Transition(Transition::Configure)),
        )?;
    }
    // A joint group's members run in the group's loop, not on their own.
    let members = group_members(objects);
    for o in objects
        .iter()
        .filter(|o| o.active && !members.contains(&o.name.as_str()))
    {
        step(
            o,
            "activate",
            object(o, Method::Transition(Transition::Activate)),
        )?;
    }
    Ok(())
}

/// The names of the controllers that are members of a `controller/joint-groups` in `objects`.
fn group_members<'a>(objects: &[&'a ObjectSpec]) -> Vec<&'a str> {
    let mut members = Vec::new();
    for o in objects
        .iter()
        .filter(|o| o.kind == penelope_runtime::objects::kinds::Kind::JOINT_GROUPS.as_str())
    {
        let Ok(table) = o.config.parse::<toml::Table>() else {
            continue;
        };
        let groups = table.get("groups").and_then(toml::Value::as_array);
        for g in groups.into_iter().flatten() {
            if let Some(name) = g.get("controller").and_then(toml::Value::as_str) {
                members.extend(
                    objects
                        .iter()
                        .find(|o| o.name == name)
                        .map(|o| o.name.as_str()),
                );
            }
        }
    }
    members
}
