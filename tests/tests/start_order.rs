//! Nodes and the naming service start in any order: a node started before its naming service
//! serves at once, registers (with the objects it created meanwhile) when the naming service
//! starts, and registers again after the naming service restarts and forgot everything.
//! Every wait is for a condition, bounded by a deadline, never for a fixed time.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use penelope_protocol::client::Client;
use penelope_protocol::net::conn::{ClientConfig, RpcError};
use penelope_protocol::net::server::{Server, ServerConfig};
use penelope_protocol::proto::{Call, CallError, CreatorCall, Reply, WireError};
use penelope_supervisor::naming::{NamingLimits, NamingService};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_testkit::net::free_tcp_addr;
use penelope_testkit::wait::wait_until;

fn naming_at(address: SocketAddr) -> (Arc<NamingService>, Server) {
    let naming = Arc::new(NamingService::new("naming", NamingLimits::default()));
    let server = Server::bind(address, ServerConfig::new("naming"), naming.clone()).unwrap();
    (naming, server)
}

fn resolves(client: &Client, path: &str) -> bool {
    client.resolve(path).is_ok()
}

#[test]
fn a_node_started_before_its_naming_service_registers_when_it_starts_and_after_a_restart() {
    let naming_addr = free_tcp_addr();
    let mut config = NodeConfig::new("early", NamingChoice::Remote(naming_addr));
    config.lease = Duration::from_millis(600);
    let node = Node::start(config).expect("a silent naming service does not stop a node");
    assert!(!node.is_registered());

    // The node serves while it waits: an object created now is bound once it registers.
    let created = node.call(Call::Creator(CreatorCall::Create {
        kind: "sensor/virtual".into(),
        name: "ft".into(),
        config: String::new(),
    }));
    assert!(matches!(created, Ok(Reply::Object(_))), "{created:?}");

    // The naming service starts: the node registers, creator and object bound.
    let (naming, server) = naming_at(naming_addr);
    let client = Client::connect(naming_addr, ClientConfig::admin("test")).unwrap();
    wait_until("the node registers", || {
        node.is_registered() && resolves(&client, "/early/sensors/ft")
    });
    assert!(resolves(&client, "/early/creator"));
    naming.snapshot().check_invariants().unwrap();

    // The naming service restarts on the same address, empty.
    server.shutdown();
    drop(naming);
    let (naming, server) = naming_at(naming_addr);
    let client = Client::connect(naming_addr, ClientConfig::admin("test")).unwrap();
    assert!(matches!(
        client.resolve("/early/creator"),
        Err(RpcError::Remote(WireError::Call(CallError::UnknownName(_))))
    ));
    wait_until("the node registers again after the restart", || {
        resolves(&client, "/early/creator") && resolves(&client, "/early/sensors/ft")
    });
    assert!(node.is_registered());
    naming.snapshot().check_invariants().unwrap();

    node.shutdown();
    wait_until("a clean shutdown unregisters", || {
        !resolves(&client, "/early/creator")
    });
    server.shutdown();
}

#[test]
fn a_node_whose_naming_service_never_answers_keeps_serving_and_stops_cleanly() {
    let naming_addr = free_tcp_addr();
    let node = Node::start(NodeConfig::new("alone", NamingChoice::Remote(naming_addr))).unwrap();
    let client = Client::connect(node.address(), ClientConfig::admin("direct")).unwrap();
    // Reached directly, the node answers although it is not registered anywhere.
    let info = client.node_at(node.address()).unwrap().info().unwrap();
    assert_eq!(info.node, "alone");
    assert!(!node.is_registered());
    node.shutdown();
}
