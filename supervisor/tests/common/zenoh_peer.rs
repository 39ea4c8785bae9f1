//! The Zenoh tests' shared set-up: a test's own Zenoh peer on loopback, and a node on a
//! simulated clock whose bridge connects to it (with a ROS 2 presence if asked).

use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::ros2::Ros2Settings;
use penelope_supervisor::system::SystemFile;
use penelope_supervisor::zenoh_bridge::{BridgeStats, ZenohSettings};
use zenoh::Wait;

/// The test's Zenoh peer: listens on `tcp/127.0.0.1:<port>` only, no scouting.
pub fn test_peer(port: u16) -> zenoh::Session {
    let mut c = zenoh::Config::default();
    c.insert_json5("mode", r#""peer""#).unwrap();
    c.insert_json5("listen/endpoints", &format!(r#"["tcp/127.0.0.1:{port}"]"#))
        .unwrap();
    c.insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    zenoh::open(c).wait().expect("the test's peer opens")
}

/// Node `name` on a simulated clock, its bridge connected to the test's peer on `port` (and
/// its ROS 2 presence with `ros2`), `system` applied.
pub fn bridged_node(name: &str, port: u16, system: &str, ros2: Option<Ros2Settings>) -> Node {
    let mut config = NodeConfig::new(name, NamingChoice::None);
    config.creator.rt.priority = None;
    config.creator.clock = ClockMode::Simulated;
    config.zenoh = Some(ZenohSettings {
        connect: Some(format!("tcp/127.0.0.1:{port}")),
        ..ZenohSettings::default()
    });
    config.ros2 = ros2;
    let node = Node::start(config).expect("the node and its bridge start");
    SystemFile::parse(system)
        .unwrap()
        .apply(&node)
        .expect("the test's system");
    node
}

/// What the node's bridge did so far.
pub fn stats(node: &Node) -> BridgeStats {
    node.zenoh_stats().expect("the node runs a bridge")
}
