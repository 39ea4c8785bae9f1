//! The system file: one TOML file that names every object of a system, its kind and
//! configuration, its relations and the node that hosts it (DESIGN.md section 1).
//! `penelope node --name N --config FILE` creates, relates, configures and activates the
//! objects the file places on node `N` ([`SystemFile::apply`]); a file that cannot be applied
//! whole leaves nothing behind.
//!
//! ```toml
//! name = "teleop"                       # optional: what the system is called
//!
//! [timing]                              # optional: loop keys every controller gets unless it
//! period_us = 1000                      # sets them itself (`penelope ctl kinds` lists them)
//! comm_period_us = 2000
//!
//! [nodes.lab]                           # optional: real-time policy of a node
//! priority = 80                         # SCHED_FIFO priority of control threads (0: normal)
//! cpu = 1                               # pin them to this CPU
//! lock_memory = false                   # mlockall before the first tick
//! data_plane = "127.0.0.1:7410"         # where a channel to a robot on another node binds
//! record = "lab.mcap"                   # `penelope node` records from the first tick (MCAP)
//! record_scene_hz = 100                 # its 3D scene's rate (/tf, /scene), Hz of tick time
//! records = "/var/lib/penelope/rec"     # where `ctl record start NAME` creates its files
//! robot_files = ["robots"]              # where a robot/urdf's `file` is read from
//! zenoh = "tcp/127.0.0.1:7447"          # a Zenoh bridge to this router or peer (or a table
//!                                       # { connect = ENDPOINT, config = "zenoh.json5" })
//!
//! [boards.puma-io]                      # <class>.<name>: boards, robots, sensors,
//! kind = "sim"                          #   trajectories, controllers; `kind` without the class
//! node = "lab"                          # optional: default, the file's only node
//! dac_bits = 16                         # every other key is the kind's configuration
//!
//! [robots.puma]
//! kind = "puma200"
//! joints = [{ board = "puma-io", axes = [0, 1, 2, 3, 4, 5] }]  # joint i on axis axes[i];
//!                                       # `joints = [3, 4, 5]` picks joints of a robot spread
//!                                       # over several boards
//!
//! [controllers.follow]
//! kind = "slave-tracking"
//! robot = "puma"                        # relations: names on the same node...
//! trajectory = "link"
//! sensor = "wrist"                      # a sensor on another node: its name (read over the
//!                                       # data plane, see below) or its naming path
//! active = true                         # activate at start (the default)
//! ```
//!
//! A `trajectory/teleop` whose master and slave robots are on different nodes is placed on both
//! (leave out its `node`), each copy with `listen` at its node's `data_plane` address and `peer`
//! at the other's (the file's second such channel takes the next port of each, and so on); its
//! samples cross on the data plane.
//!
//! A controller whose `sensor` names a sensor on another node reads it over the data plane: the
//! relation becomes the sensor's naming path (`/node/sensors/wrist`), and the sensor needs
//! `publish = "host:port"` (where its node serves it to every reader; port 0: any free port).
//! A sensor read from several nodes is published once, and every reader gets the same samples.
//!
//! Order of work: every object is created (boards, sensors, robots, trajectories, controllers;
//! in file order within a class), then related, then configured in the same order (so a hand
//! exists before the robot it holds is configured, and robots before the channel between them),
//! then the controllers marked `active` are activated in file order (except the members of a
//! `joint-groups` controller, which run in the group's loop). Any refusal destroys
//! everything created so far and names the line, the object and the step.

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

use penelope_hal::{MAX_JOINTS, Transition};
use penelope_protocol::proto::{
    Call, ControllerMethod, CreatorCall, JointAxis, Method, ObjectInfo, Reply, RobotMethod,
    WireError, check_name,
};
use penelope_runtime::objects::RtPolicy;

/// The classes of a system file, in the order their objects are created and configured.
pub const CLASSES: [&str; 5] = ["boards", "sensors", "robots", "trajectories", "controllers"];

/// Keys of every object that are not its kind's configuration.
const COMMON_KEYS: [&str; 2] = ["kind", "node"];

/// A node's real-time policy in a system file.
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodePolicy {
    /// SCHED_FIFO priority of control threads (1-99; 0: normal scheduling).
    pub priority: Option<u8>,
    /// Pin control threads to this CPU.
    pub cpu: Option<usize>,
    /// `mlockall` before the first tick.
    pub lock_memory: Option<bool>,
    /// The node's data-plane address: a teleoperation channel between a robot on this node
    /// and one on another binds it (the file's first such channel on this port, the next on
    /// the port after, and so on).
    pub data_plane: Option<std::net::SocketAddr>,
    /// `penelope node` records every tick of the controllers the file activates on this node,
    /// their safety events and its channels' links, from the first tick, to this MCAP file
    /// (relative to the node's working directory; `--record` overrides it).
    pub record: Option<std::path::PathBuf>,
    /// How often that recording draws the robots in 3D (`/tf`, `/scene`), Hz of tick time, 0..=10000
    /// (0: their descriptions only; default 100; `--record-scene-hz` overrides it).
    pub record_scene_hz: Option<u32>,
    /// The directory `ctl record start` creates this node's recordings in (a client names a
    /// plain file name; `--records` overrides it; default: `recordings` under the node's
    /// state directory, `$XDG_STATE_HOME/penelope/<node>`).
    pub records: Option<std::path::PathBuf>,
    /// The directories a `robot/urdf`'s `file` is read from on this node (`--robot-files`
    /// overrides them; default: the system file's directory).
    pub robot_files: Option<Vec<std::path::PathBuf>>,
    /// `penelope node` runs a Zenoh bridge ([`crate::zenoh_bridge`]) with these settings
    /// (`--zenoh` and `--zenoh-config` override them).
    pub zenoh: Option<crate::zenoh_bridge::ZenohSettings>,
}

impl NodePolicy {
    /// `base` with what this policy sets.
    pub fn applied_to(&self, mut base: RtPolicy) -> RtPolicy {
        if let Some(p) = self.priority {
            base.priority = (p > 0).then_some(p);
        }
        if let Some(c) = self.cpu {
            base.cpu = Some(c);
        }
        if let Some(l) = self.lock_memory {
            base.lock_memory = l;
        }
        base
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    name: Option<String>,
    #[serde(default)]
    timing: toml::Table,
    #[serde(default)]
    nodes: BTreeMap<String, Spanned<NodePolicy>>,
    #[serde(default)]
    boards: toml::Table,
    #[serde(default)]
    sensors: toml::Table,
    #[serde(default)]
    robots: toml::Table,
    #[serde(default)]
    trajectories: toml::Table,
    #[serde(default)]
    controllers: toml::Table,
}

/// Joints of a robot on one board's axes.
#[derive(Clone, Debug, PartialEq)]
pub struct JointMap {
    /// The board's name.
    pub board: String,
    /// Joint and axis pairs.
    pub joints: Vec<JointAxis>,
}

/// One object of a system file.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectSpec {
    /// `class/kind`, as `penelope ctl kinds` lists it.
    pub kind: String,
    /// Its name on its node.
    pub name: String,
    /// The node that hosts it.
    pub node: String,
    /// The kind's configuration, as TOML text.
    pub config: String,
    /// Robots: joints on board axes.
    pub joints: Vec<JointMap>,
    /// Controllers: robot, trajectory and sensor.
    pub robot: Option<String>,
    /// Controllers: the trajectory.
    pub trajectory: Option<String>,
    /// Controllers: the sensor (a name, or a naming path on another node).
    pub sensor: Option<String>,
    /// Controllers: activate at start.
    pub active: bool,
    /// Line of its table in the file (1-based).
    pub line: usize,
}

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

/// A parsed system file.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemFile {
    /// What the system is called.
    pub name: Option<String>,
    /// Real-time policy per node.
    pub nodes: BTreeMap<String, NodePolicy>,
    /// Every object, in creation order.
    pub objects: Vec<ObjectSpec>,
}

/// Why a system file could not be read or applied.
#[derive(Debug, thiserror::Error)]
pub enum SystemFileError {
    /// Not TOML, or not a system file; names the line and key where it can.
    #[error("line {line}: {message}")]
    Parse {
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// An object is wrong before anything was created.
    #[error("line {line}: {key}: {message}")]
    Invalid {
        /// 1-based line of the object's table.
        line: usize,
        /// The key, such as `robots.puma.joints`.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// The node refused a step; everything created from the file was destroyed again.
    #[error("line {line}: {key}: {step}: {error} (nothing from the file was kept)")]
    Step {
        /// 1-based line of the object's table.
        line: usize,
        /// The object, such as `robots.puma`.
        key: String,
        /// The step (`create`, `map joints`, `configure`, ...).
        step: String,
        /// The node's error.
        error: WireError,
    },
}

/// The 1-based line of byte `offset` of `text`.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())]
        .bytes()
        .filter(|b| *b == b'\n')
        .count()
        + 1
}

/// The line of `[class.name]` (or the first line mentioning it) in `text`.
fn table_line(text: &str, class: &str, name: &str) -> usize {
    let header = format!("[{class}.{name}]");
    let quoted = format!("[{class}.\"{name}\"]");
    text.lines()
        .position(|l| {
            let l = l.trim_start();
            l.starts_with(&header) || l.starts_with(&quoted)
        })
        .map_or(1, |i| i + 1)
}

impl SystemFile {
    /// Parses and checks a system file.
    ///
    /// # Errors
    /// [`SystemFileError::Parse`] for TOML errors and unknown top-level keys,
    /// [`SystemFileError::Invalid`] for an object that is wrong on its face (no kind, a bad
    /// name, an unknown node, a malformed joint map, relations of another class).
    pub fn parse(text: &str) -> Result<SystemFile, SystemFileError> {
        let raw: RawFile = toml::from_str(text).map_err(|e| SystemFileError::Parse {
            line: e.span().map_or(1, |s| line_of(text, s.start)),
            message: e.message().to_string(),
        })?;
        let nodes: BTreeMap<String, NodePolicy> = raw
            .nodes
            .iter()
            .map(|(k, v)| (k.clone(), v.get_ref().clone()))
            .collect();
        for (name, policy) in &raw.nodes {
            let invalid = |message: String| SystemFileError::Invalid {
                line: line_of(text, policy.span().start),
                key: format!("nodes.{name}"),
                message,
            };
            check_name(name).map_err(|e| invalid(e.to_string()))?;
            if policy.get_ref().priority.is_some_and(|p| p > 99) {
                return Err(invalid("priority must be 0..=99".into()));
            }
        }
        let classes = [
            ("boards", &raw.boards),
            ("sensors", &raw.sensors),
            ("robots", &raw.robots),
            ("trajectories", &raw.trajectories),
            ("controllers", &raw.controllers),
        ];
        let mut objects = Vec::new();
        for (class, table) in classes {
            let mut specs: Vec<ObjectSpec> = Vec::new();
            for (name, value) in table {
                let line = table_line(text, class, name);
                let spec = object_spec(class, name, value, line, &raw.timing, &nodes)?;
                specs.push(spec);
            }
            // File order within a class.
            specs.sort_by_key(|s| s.line);
            objects.extend(specs);
        }
        split_cross_node_channels(&mut objects, &nodes)?;
        name_sensors_on_other_nodes(&mut objects)?;
        // With several nodes, every object says where it lives.
        let named: Vec<&str> = objects
            .iter()
            .filter(|o| !o.node.is_empty())
            .map(|o| o.node.as_str())
            .chain(nodes.keys().map(String::as_str))
            .collect();
        let several = named.iter().any(|n| *n != named[0]);
        if let Some(o) = objects.iter().find(|o| several && o.node.is_empty()) {
            return Err(SystemFileError::Invalid {
                line: o.line,
                key: format!("{}.{}.node", class_key(&o.kind), o.name),
                message: "missing: the file places objects on several nodes".into(),
            });
        }
        // One name per node.
        let mut seen = BTreeMap::new();
        for o in &objects {
            if let Some(first) = seen.insert((o.node.clone(), o.name.clone()), o.line) {
                return Err(SystemFileError::Invalid {
                    line: o.line,
                    key: o.name.clone(),
                    message: format!(
                        "the name is used twice on node `{}` (first on line {first})",
                        o.node
                    ),
                });
            }
        }
        Ok(SystemFile {
            name: raw.name,
            nodes,
            objects,
        })
    }

    /// The nodes the file places objects on (or names in `[nodes]`).
    pub fn node_names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.nodes.keys().cloned().collect();
        for o in &self.objects {
            if !o.node.is_empty() && !names.contains(&o.node) {
                names.push(o.node.clone());
            }
        }
        names
    }

    /// The objects on node `node` (objects without `node` belong to the file's only node,
    /// whatever it is called).
    pub fn objects_on<'a>(&'a self, node: &'a str) -> impl Iterator<Item = &'a ObjectSpec> + 'a {
        self.objects
            .iter()
            .filter(move |o| o.node.is_empty() || o.node == node)
    }

    /// The real-time policy of node `node` applied to `base`.
    pub fn policy(&self, node: &str, base: RtPolicy) -> RtPolicy {
        self.nodes.get(node).map_or(base, |p| p.applied_to(base))
    }

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
        .filter(|o| o.kind == penelope_runtime::objects::kinds::CONTROLLER_JOINT_GROUPS)
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

/// Puts each teleoperation channel whose master and slave robots are on different nodes on
/// both nodes, each copy with `listen` (its node's data-plane address) and `peer` (the other
/// node's), unless the file set them itself.
fn split_cross_node_channels(
    objects: &mut Vec<ObjectSpec>,
    nodes: &BTreeMap<String, NodePolicy>,
) -> Result<(), SystemFileError> {
    let robot_node = |name: &str| {
        objects
            .iter()
            .find(|o| o.kind.starts_with("robot/") && o.name == name)
            .map(|o| o.node.clone())
    };
    let mut split = Vec::new();
    let mut crossing = 0u16;
    for (i, o) in objects.iter().enumerate() {
        if o.kind != penelope_runtime::objects::kinds::TRAJECTORY_TELEOP {
            continue;
        }
        let Ok(config) = o.config.parse::<toml::Table>() else {
            continue;
        };
        if config.contains_key("listen") || config.contains_key("peer") {
            continue;
        }
        let side = |k: &str| {
            config
                .get(k)
                .and_then(toml::Value::as_str)
                .and_then(robot_node)
        };
        let (Some(master), Some(slave)) = (side("master"), side("slave")) else {
            continue;
        };
        if master == slave || master.is_empty() || slave.is_empty() {
            continue;
        }
        let key = format!("trajectories.{}", o.name);
        let address = |node: &str| {
            let base = nodes.get(node).and_then(|p| p.data_plane).ok_or_else(|| {
                SystemFileError::Invalid {
                    line: o.line,
                    key: key.clone(),
                    message: format!(
                        "its master and slave are on nodes `{master}` and `{slave}`: \
                         [nodes.{node}] needs `data_plane = \"host:port\"`"
                    ),
                }
            })?;
            let port =
                base.port()
                    .checked_add(crossing)
                    .ok_or_else(|| SystemFileError::Invalid {
                        line: o.line,
                        key: format!("nodes.{node}.data_plane"),
                        message: "no port left for this channel".into(),
                    })?;
            Ok::<_, SystemFileError>(std::net::SocketAddr::new(base.ip(), port))
        };
        let (m, s) = (address(&master)?, address(&slave)?);
        crossing += 1;
        for (node, listen, peer) in [(&master, m, s), (&slave, s, m)] {
            let mut copy = o.clone();
            let mut table = config.clone();
            table.insert("listen".into(), listen.to_string().into());
            table.insert("peer".into(), peer.to_string().into());
            copy.config = toml::to_string(&table).map_err(|e| SystemFileError::Invalid {
                line: o.line,
                key: key.clone(),
                message: e.to_string(),
            })?;
            copy.node = node.clone();
            split.push((i, copy));
        }
    }
    // Each split channel gives way to its two copies, in place (file order is kept).
    let mut copies: BTreeMap<usize, Vec<ObjectSpec>> = BTreeMap::new();
    for (i, copy) in split {
        copies.entry(i).or_default().push(copy);
    }
    let all = std::mem::take(objects);
    for (i, o) in all.into_iter().enumerate() {
        match copies.remove(&i) {
            Some(c) => objects.extend(c),
            None => objects.push(o),
        }
    }
    Ok(())
}

/// Turns a controller's `sensor = "wrist"`, where `wrist` is on another node, into that
/// sensor's naming path (`/node/sensors/wrist`): the controller then reads it over the data
/// plane, which needs the sensor's `publish` key.
fn name_sensors_on_other_nodes(objects: &mut [ObjectSpec]) -> Result<(), SystemFileError> {
    let sensors: Vec<(String, String, bool)> = objects
        .iter()
        .filter(|o| class_key(&o.kind) == "sensors")
        .map(|o| {
            let publishes = o
                .config
                .parse::<toml::Table>()
                .is_ok_and(|t| t.contains_key("publish"));
            (o.name.clone(), o.node.clone(), publishes)
        })
        .collect();
    for c in objects.iter_mut() {
        let Some(name) = c.sensor.clone().filter(|s| !s.starts_with('/')) else {
            continue;
        };
        let mut named = sensors.iter().filter(|(n, _, _)| *n == name);
        if named.clone().any(|(_, node, _)| *node == c.node) {
            continue;
        }
        let (Some((_, node, publishes)), None) = (named.next(), named.next()) else {
            continue;
        };
        if !publishes {
            return Err(SystemFileError::Invalid {
                line: c.line,
                key: format!("controllers.{}.sensor", c.name),
                message: format!(
                    "sensor `{name}` is on node `{node}`: give it `publish = \"host:port\"` so \
                     that this controller reads it over the data plane"
                ),
            });
        }
        c.sensor = Some(format!("/{node}/sensors/{name}"));
    }
    Ok(())
}

/// The system-file class key of a `class/kind`.
fn class_key(kind: &str) -> &'static str {
    match kind.split('/').next() {
        Some("board") => "boards",
        Some("sensor") => "sensors",
        Some("robot") => "robots",
        Some("trajectory") => "trajectories",
        _ => "controllers",
    }
}

/// The `class/kind` of a system-file class key and kind word.
fn full_kind(class: &str, kind: &str) -> String {
    let singular = match class {
        "boards" => "board",
        "sensors" => "sensor",
        "robots" => "robot",
        "trajectories" => "trajectory",
        _ => "controller",
    };
    format!("{singular}/{kind}")
}

fn object_spec(
    class: &str,
    name: &str,
    value: &toml::Value,
    line: usize,
    timing: &toml::Table,
    nodes: &BTreeMap<String, NodePolicy>,
) -> Result<ObjectSpec, SystemFileError> {
    let key = format!("{class}.{name}");
    let invalid = |key: String, message: String| SystemFileError::Invalid { line, key, message };
    check_name(name).map_err(|e| invalid(key.clone(), e.to_string()))?;
    let Some(table) = value.as_table() else {
        return Err(invalid(key, "must be a table of keys".into()));
    };
    let kind = match table.get("kind") {
        Some(toml::Value::String(k)) => full_kind(class, k),
        Some(_) => return Err(invalid(format!("{key}.kind"), "must be a string".into())),
        None => return Err(invalid(format!("{key}.kind"), "missing".into())),
    };
    if penelope_runtime::objects::kinds::Kind::parse(&kind).is_none() {
        return Err(invalid(
            format!("{key}.kind"),
            format!("unknown kind `{kind}` (see `penelope ctl kinds`)"),
        ));
    }
    let node = match table.get("node") {
        Some(toml::Value::String(n)) => {
            if !nodes.is_empty() && !nodes.contains_key(n) {
                return Err(invalid(
                    format!("{key}.node"),
                    format!("node `{n}` is not in [nodes]"),
                ));
            }
            n.clone()
        }
        Some(_) => return Err(invalid(format!("{key}.node"), "must be a string".into())),
        None if nodes.len() == 1 => nodes.keys().next().cloned().unwrap_or_default(),
        None => String::new(),
    };
    let relation_keys: &[&str] = match class {
        "robots" => &["joints"],
        "controllers" => &["robot", "trajectory", "sensor", "active"],
        _ => &[],
    };
    let mut config = toml::Table::new();
    for (k, v) in table {
        if !COMMON_KEYS.contains(&k.as_str()) && !relation_keys.contains(&k.as_str()) {
            config.insert(k.clone(), v.clone());
        }
    }
    if class == "controllers" {
        for (k, v) in timing {
            config.entry(k.clone()).or_insert_with(|| v.clone());
        }
    }
    let string = |k: &str| -> Result<Option<String>, SystemFileError> {
        match table.get(k) {
            None => Ok(None),
            Some(toml::Value::String(s)) => Ok(Some(s.clone())),
            Some(_) => Err(invalid(format!("{key}.{k}"), "must be a string".into())),
        }
    };
    let active = match table.get("active") {
        None => class == "controllers",
        Some(toml::Value::Boolean(b)) => *b,
        Some(_) => {
            return Err(invalid(
                format!("{key}.active"),
                "must be true or false".into(),
            ));
        }
    };
    let joints = match table.get("joints") {
        None => Vec::new(),
        Some(v) => joint_maps(v).map_err(|m| invalid(format!("{key}.joints"), m))?,
    };
    Ok(ObjectSpec {
        kind,
        name: name.to_string(),
        node,
        config: toml::to_string(&config).map_err(|e| invalid(key.clone(), e.to_string()))?,
        joints,
        robot: string("robot").map(|r| r.filter(|_| class == "controllers"))?,
        trajectory: string("trajectory").map(|r| r.filter(|_| class == "controllers"))?,
        sensor: string("sensor").map(|r| r.filter(|_| class == "controllers"))?,
        active,
        line,
    })
}

/// `[{ board = "b", joints = [..]?, axes = [..]? }, ...]`: joint `joints[i]` on axis `axes[i]`
/// (both default to 0, 1, 2, ... as long as the other).
fn joint_maps(v: &toml::Value) -> Result<Vec<JointMap>, String> {
    let list = v
        .as_array()
        .ok_or("must be a list of { board, joints, axes } tables")?;
    let numbers = |t: &toml::Table, k: &str| -> Result<Option<Vec<u8>>, String> {
        match t.get(k) {
            None => Ok(None),
            Some(toml::Value::Array(a)) => a
                .iter()
                .map(|x| {
                    x.as_integer()
                        .and_then(|i| u8::try_from(i).ok())
                        .filter(|i| usize::from(*i) < MAX_JOINTS)
                        .ok_or_else(|| format!("`{k}` holds {x}, not a number 0..{MAX_JOINTS}"))
                })
                .collect::<Result<Vec<u8>, String>>()
                .map(Some),
            Some(_) => Err(format!("`{k}` must be a list of numbers")),
        }
    };
    list.iter()
        .map(|m| {
            let t = m.as_table().ok_or("each map must be a table")?;
            for k in t.keys() {
                if !["board", "joints", "axes"].contains(&k.as_str()) {
                    return Err(format!("unknown key `{k}` (board, joints, axes)"));
                }
            }
            let board = t
                .get("board")
                .and_then(toml::Value::as_str)
                .ok_or("needs `board` (a board's name)")?
                .to_string();
            let joints = numbers(t, "joints")?;
            let axes = numbers(t, "axes")?;
            let (joints, axes) = match (joints, axes) {
                (Some(j), Some(a)) if j.len() != a.len() => {
                    return Err(format!("{} joints but {} axes", j.len(), a.len()));
                }
                (Some(j), Some(a)) => (j, a),
                (Some(j), None) => (j.clone(), j),
                (None, Some(a)) => ((0..a.len() as u8).collect(), a),
                (None, None) => return Err("needs `joints` or `axes`".into()),
            };
            Ok(JointMap {
                board,
                joints: joints
                    .into_iter()
                    .zip(axes)
                    .map(|(joint, axis)| JointAxis { joint, axis })
                    .collect(),
            })
        })
        .collect()
}
