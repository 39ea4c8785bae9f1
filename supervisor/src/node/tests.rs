//! Unit tests of a node: its objects' naming bindings and the names and leases it refuses.

use super::*;
use penelope_protocol::proto::{CallError, Class, CreatorCall, Method, NodeInfo};

fn names(node: &Node, context: &str) -> Vec<String> {
    let tree = node.hosted_naming().unwrap().snapshot();
    tree.list(context)
        .unwrap()
        .iter()
        .map(|e| e.name().to_string())
        .collect()
}

#[test]
fn created_objects_are_bound_and_destroyed_ones_unbound() {
    let node = Node::start(NodeConfig::new("lab-a", NamingChoice::Host)).unwrap();
    assert_eq!(names(&node, "/lab-a"), ["creator"]);
    let create = Call::Creator(CreatorCall::Create {
        kind: "sensor/virtual".into(),
        name: "ft".into(),
        config: String::new(),
    });
    assert!(matches!(node.call(create.clone()), Ok(Reply::Object(_))));
    assert!(matches!(
        node.call(create),
        Err(WireError::Call(CallError::NameTaken(_)))
    ));
    let tree = node.hosted_naming().unwrap().snapshot();
    let r = tree.resolve("/lab-a/sensors/ft").unwrap();
    assert_eq!(
        (r.class, r.address.as_str()),
        (Class::Sensor, node.advertised())
    );
    // The node reaches its own objects through its Remote.
    assert!(matches!(
        node.remote().call("/lab-a/sensors/ft", Method::Describe),
        Ok(Reply::Object(_))
    ));
    assert!(matches!(
        node.remote().call("/lab-a/sensors/nope", Method::Describe),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    let destroy = Call::Creator(CreatorCall::Destroy {
        name: "ft".into(),
        force: false,
    });
    node.call(destroy).unwrap();
    assert_eq!(names(&node, "/lab-a"), ["creator"]);
    assert!(matches!(
        node.call(Call::NodeInfo),
        Ok(Reply::Node(NodeInfo {
            hosts_naming: true,
            objects: 0,
            ..
        }))
    ));
    let naming = node.hosted_naming().unwrap().clone();
    node.shutdown();
    assert!(naming.snapshot().list("/").unwrap().is_empty());
}

#[test]
fn bad_names_and_leases_are_refused() {
    let mut config = NodeConfig::new("no/slash", NamingChoice::None);
    assert!(matches!(
        Node::start(config.clone()),
        Err(NodeError::BadName(_))
    ));
    config.name = "ok".into();
    config.naming = NamingChoice::Host;
    config.lease = Duration::from_millis(1);
    assert!(matches!(Node::start(config), Err(NodeError::BadLease(_))));
}
