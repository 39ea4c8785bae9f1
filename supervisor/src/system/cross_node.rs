//! What a file that places objects on several nodes implies: a teleoperation channel between
//! robots on two nodes is placed on both, linked over the data plane, and a controller's sensor
//! on another node is read over the data plane by its naming path.

use std::collections::BTreeMap;

use super::{NodePolicy, ObjectSpec, SystemFileError, class_key};

/// Puts each teleoperation channel whose master and slave robots are on different nodes on
/// both nodes, each copy with `listen` (its node's data-plane address) and `peer` (the other
/// node's), unless the file set them itself.
pub(super) fn split_cross_node_channels(
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
        if o.kind != penelope_runtime::objects::kinds::Kind::TELEOP.as_str() {
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
pub(super) fn name_sensors_on_other_nodes(
    objects: &mut [ObjectSpec],
) -> Result<(), SystemFileError> {
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
