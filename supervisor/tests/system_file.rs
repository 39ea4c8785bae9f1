//! The system file: parsed with errors that name the line and the key, applied to a node in
//! class order (the paper's task comes up active from `config/teleop.toml`), and a file that
//! cannot be applied whole leaves nothing behind.

use std::time::{Duration, Instant};

use penelope_hal::LifecycleState;
use penelope_protocol::proto::{
    Call, CallError, ControllerMethod, CreatorCall, Method, Reply, WireError,
};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::system::{SystemFile, SystemFileError};

const TELEOP: &str = include_str!("../../config/teleop.toml");
const EXAMPLE: &str = include_str!("../../config/node-example.toml");

fn node() -> Node {
    let mut config = NodeConfig::new("lab", NamingChoice::None);
    config.creator.rt.priority = None;
    Node::start(config).unwrap()
}

fn line_of(e: &SystemFileError) -> usize {
    match e {
        SystemFileError::Parse { line, .. }
        | SystemFileError::Invalid { line, .. }
        | SystemFileError::Step { line, .. } => *line,
    }
}

#[test]
fn the_shipped_files_parse_in_class_order_with_the_timing_merged() {
    let file = SystemFile::parse(TELEOP).unwrap();
    let order: Vec<&str> = file.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(
        order,
        [
            "frhc-io", "puma-io", "hand", "wrist", "frhc", "puma", "link", "display", "follow"
        ]
    );
    let follow = file.objects.last().unwrap();
    assert_eq!(follow.kind, "controller/slave-tracking");
    assert_eq!(
        (follow.robot.as_deref(), follow.trajectory.as_deref()),
        (Some("puma"), Some("link"))
    );
    assert_eq!(follow.sensor.as_deref(), Some("wrist"));
    assert!(follow.active);
    assert!(
        follow.config.contains("period_us = 1000"),
        "{}",
        follow.config
    );
    assert_eq!(follow.node, "lab");
    assert_eq!(file.policy("lab", Default::default()).priority, Some(80));
    let puma = file.objects.iter().find(|o| o.name == "puma").unwrap();
    assert_eq!(puma.joints[0].joints.len(), 6);
    assert!(puma.config.is_empty(), "{}", puma.config);

    let example = SystemFile::parse(EXAMPLE).unwrap();
    assert_eq!(example.objects.len(), 4);
    assert!(example.objects[2].config.contains("waypoints"));
}

#[test]
fn malformed_files_are_refused_naming_the_line_and_the_key() {
    for (text, line, needle) in [
        ("[boards.a]\nkind = \"sim\"\n[boards.a\n", 3, ""),
        ("colour = \"red\"\n", 1, "colour"),
        ("\n\n[robots.r]\nkind = \"r2d2\"\n", 3, "robots.r.kind"),
        ("[boards.b]\ndac_bits = 16\n", 1, "boards.b.kind"),
        (
            "[boards.b]\nkind = \"sim\"\n\n[robots.r]\nkind = \"puma560\"\njoints = [{ board = \"b\", joints = [0, 1], axes = [0] }]\n",
            4,
            "robots.r.joints",
        ),
        ("[boards.\"a b\"]\nkind = \"sim\"\n", 1, "boards.a b"),
        (
            "[boards.b]\nkind = \"sim\"\nnode = \"x\"\n[boards.c]\nkind = \"sim\"\nnode = \"y\"\n[robots.r]\nkind = \"frhc\"\n",
            7,
            "robots.r.node",
        ),
        (
            "[boards.b]\nkind = \"sim\"\n[sensors.b]\nkind = \"virtual\"\n",
            3,
            "b",
        ),
    ] {
        let e = SystemFile::parse(text).expect_err(text);
        assert_eq!(line_of(&e), line, "{text}: {e}");
        assert!(e.to_string().contains(needle), "{text}: {e}");
    }
}

#[test]
fn a_node_brings_the_papers_task_up_from_the_file() {
    let node = node();
    let file = SystemFile::parse(TELEOP).unwrap();
    let created = file.apply(&node).expect("the task comes up");
    assert_eq!(created.len(), 9);
    for name in ["display", "follow"] {
        assert_eq!(
            node.creator().info(name).unwrap().state,
            LifecycleState::Active,
            "{name}"
        );
    }
    // Both loops run (a condition with a deadline, not a timing claim).
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let ticks = |name: &str| match node.call(Call::Object {
            object: name.into(),
            method: Method::Controller(ControllerMethod::Status),
        }) {
            Ok(Reply::Status(s)) => s.ticks,
            other => panic!("{other:?}"),
        };
        if ticks("display") > 200 && ticks("follow") > 200 {
            break;
        }
        assert!(Instant::now() < deadline, "the loops never ran");
        std::thread::sleep(Duration::from_millis(10));
    }
    node.shutdown();
}

#[test]
fn a_file_for_other_nodes_is_refused_not_applied_to_nothing() {
    let mut config = NodeConfig::new("elsewhere", NamingChoice::None);
    config.creator.rt.priority = None;
    let node = Node::start(config).unwrap();
    let file = SystemFile::parse(TELEOP).unwrap();
    match file.apply(&node) {
        Err(SystemFileError::Invalid { message, .. }) => {
            assert!(message.contains("lab"), "{message}")
        }
        other => panic!("{other:?}"),
    }
    assert!(node.creator().list().is_empty());
    // A file that names no node goes to whichever node applies it.
    let example = SystemFile::parse(EXAMPLE).unwrap();
    assert_eq!(example.apply(&node).unwrap().len(), 4);
    node.shutdown();
}

#[test]
fn a_file_that_cannot_be_applied_whole_leaves_nothing_behind() {
    let node = node();
    // The slave half on the master's robot: refused at activation, after everything was made
    // and `display` already runs.
    let text = TELEOP.replace(
        "kind = \"slave-tracking\"       # slave half: IK and computed torque to the mapped master pose\nrobot = \"puma\"",
        "kind = \"slave-tracking\"\nrobot = \"frhc\"",
    );
    assert_ne!(text, TELEOP);
    let file = SystemFile::parse(&text).unwrap();
    match file.apply(&node) {
        Err(SystemFileError::Step {
            line,
            key,
            step,
            error,
        }) => {
            assert_eq!(key, "controllers.follow");
            assert_eq!(step, "activate");
            assert_eq!(text.lines().nth(line - 1), Some("[controllers.follow]"));
            // The FRHC is already driven by `display`.
            assert!(
                matches!(error, WireError::Call(CallError::InUse { .. })),
                "{error:?}"
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        node.call(Call::Creator(CreatorCall::List)),
        Ok(Reply::Objects(list)) if list.is_empty()
    ));
    node.shutdown();
}
