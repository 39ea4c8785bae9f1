//! Reading a system file: the TOML, checked object by object, into a [`SystemFile`] whose every
//! object knows its kind, node, configuration, relations and line.

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

use penelope_hal::MAX_JOINTS;
use penelope_protocol::proto::{JointAxis, check_name};

use super::cross_node::{name_sensors_on_other_nodes, split_cross_node_channels};
use super::{JointMap, NodePolicy, ObjectSpec, SystemFile, SystemFileError, class_key};

/// Keys of every object that are not its kind's configuration.
const COMMON_KEYS: [&str; 2] = ["kind", "node"];

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
    if penelope_runtime::objects::catalog::parse_kind(&kind).is_none() {
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
