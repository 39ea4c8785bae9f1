//! The naming service alone over TCP: bind, resolve, list and unbind over the wire; typed errors;
//! the lease expiry of a node that stops renewing; a node registering in it.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use penelope_protocol::net::conn::{ClientConfig, Connection, RpcError};
use penelope_protocol::net::server::{Server, ServerConfig};
use penelope_protocol::proto::{
    Call, CallError, Class, CreatorCall, NameEntry, NamingCall, ObjectRef, Reply, WireError,
};
use penelope_supervisor::naming::{NamingLimits, NamingService};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};

fn serve() -> (Server, Arc<NamingService>) {
    let service = Arc::new(NamingService::new("naming", NamingLimits::default()));
    let loopback: SocketAddr = "127.0.0.1:0".parse().unwrap();
    let server = Server::bind(loopback, ServerConfig::new("naming"), service.clone()).unwrap();
    (server, service)
}

fn connect(server: &Server) -> Connection {
    // An administrator: these tests play several nodes over one connection.
    Connection::connect(server.local_addr(), &ClientConfig::admin("test")).unwrap()
}

fn naming(conn: &mut Connection, call: NamingCall) -> Result<Reply, WireError> {
    match conn.call(Call::Naming(call)) {
        Ok(reply) => Ok(reply),
        Err(RpcError::Remote(e)) => Err(e),
        Err(other) => panic!("transport failure: {other}"),
    }
}

fn reference(node: &str, name: &str, class: Class) -> ObjectRef {
    ObjectRef {
        node: node.into(),
        address: "127.0.0.1:7301".into(),
        name: name.into(),
        class,
        kind: "sensor/virtual".into(),
    }
}

fn names(reply: Result<Reply, WireError>) -> Vec<String> {
    match reply {
        Ok(Reply::Names(entries)) => entries.iter().map(|e| e.name().to_string()).collect(),
        other => panic!("expected names, got {other:?}"),
    }
}

#[test]
fn bind_resolve_list_unbind_over_the_wire() {
    let (server, _service) = serve();
    let mut c = connect(&server);
    assert_eq!(c.node(), "naming");
    let r = reference("lab-b", "ft", Class::Sensor);
    let bind = |path: &str, rebind| NamingCall::Bind {
        path: path.into(),
        reference: r.clone(),
        rebind,
    };
    assert_eq!(
        naming(&mut c, bind("/lab-b/sensors/ft", false)),
        Ok(Reply::Unit)
    );
    assert!(matches!(
        naming(&mut c, bind("/lab-b/sensors/ft", false)),
        Err(WireError::Call(CallError::NameTaken(_)))
    ));
    assert_eq!(
        naming(&mut c, bind("/lab-b/sensors/ft", true)),
        Ok(Reply::Unit)
    );
    assert_eq!(
        naming(
            &mut c,
            NamingCall::Resolve {
                path: "/lab-b/sensors/ft".into()
            }
        ),
        Ok(Reply::Resolved(r.clone()))
    );
    assert_eq!(
        names(naming(
            &mut c,
            NamingCall::List {
                context: "/".into()
            }
        )),
        ["lab-b"]
    );
    assert_eq!(
        naming(
            &mut c,
            NamingCall::List {
                context: "/lab-b/sensors".into()
            }
        ),
        Ok(Reply::Names(vec![NameEntry::Object {
            name: "ft".into(),
            reference: r.clone()
        }]))
    );
    typed_errors_cross_the_wire(&mut c);
    pipelined_unbinds_come_back_in_order(&mut c);
    server.shutdown();
}

/// Typed errors cross the wire: a bad name, an unknown one, a creator call at a naming service.
fn typed_errors_cross_the_wire(c: &mut Connection) {
    assert!(matches!(
        naming(
            c,
            NamingCall::Resolve {
                path: "no-slash".into()
            }
        ),
        Err(WireError::Call(CallError::BadName { .. }))
    ));
    assert!(matches!(
        naming(
            c,
            NamingCall::Resolve {
                path: "/lab-b/sensors/nope".into()
            }
        ),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    assert!(matches!(
        c.call(Call::Creator(CreatorCall::Kinds)),
        Err(RpcError::Remote(WireError::Call(
            CallError::Unsupported { .. }
        )))
    ));
    assert!(matches!(c.call(Call::NodeInfo), Ok(Reply::Node(info)) if info.hosts_naming));
}

/// Pipelined calls come back in order: an unbind, the same again (unknown now), and the list
/// of the root, empty (the unregistered contexts went with their last entry).
fn pipelined_unbinds_come_back_in_order(c: &mut Connection) {
    let answers = c
        .call_many(vec![
            Call::Naming(NamingCall::Unbind {
                path: "/lab-b/sensors/ft".into(),
            }),
            Call::Naming(NamingCall::Unbind {
                path: "/lab-b/sensors/ft".into(),
            }),
            Call::Naming(NamingCall::List {
                context: "/".into(),
            }),
        ])
        .unwrap();
    assert_eq!(answers[0], Ok(Reply::Unit));
    assert!(matches!(
        answers[1],
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    // The unregistered contexts went with their last entry.
    assert_eq!(answers[2], Ok(Reply::Names(vec![])));
}

#[test]
fn a_node_that_stops_renewing_expires() {
    let (server, service) = serve();
    let mut c = connect(&server);
    let register = |node: &str| NamingCall::Register {
        node: node.into(),
        address: "127.0.0.1:7301".into(),
        lease_ms: 300,
    };
    naming(&mut c, register("alive")).unwrap();
    naming(&mut c, register("dying")).unwrap();
    for node in ["alive", "dying"] {
        naming(
            &mut c,
            NamingCall::Bind {
                path: format!("/{node}/sensors/ft"),
                reference: reference(node, "ft", Class::Sensor),
                rebind: false,
            },
        )
        .unwrap();
    }
    naming(
        &mut c,
        NamingCall::Bind {
            path: "/shared/ft".into(),
            reference: reference("dying", "ft", Class::Sensor),
            rebind: false,
        },
    )
    .unwrap();
    // `alive` renews every 100 ms, `dying` never does.
    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(600) {
        naming(
            &mut c,
            NamingCall::Renew {
                node: "alive".into(),
            },
        )
        .unwrap();
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(
        names(naming(
            &mut c,
            NamingCall::List {
                context: "/".into()
            }
        )),
        ["alive", "shared"],
        "the lapsed node's context is gone, the others stay"
    );
    assert!(matches!(
        naming(
            &mut c,
            NamingCall::Renew {
                node: "dying".into()
            }
        ),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    assert!(service.snapshot().check_invariants().is_ok());
    // Registering again starts afresh.
    naming(&mut c, register("dying")).unwrap();
    assert_eq!(
        names(naming(
            &mut c,
            NamingCall::List {
                context: "/dying".into()
            }
        )),
        Vec::<String>::new()
    );
    naming(
        &mut c,
        NamingCall::Unregister {
            node: "dying".into(),
        },
    )
    .unwrap();
    server.shutdown();
}

#[test]
fn a_node_registers_renews_and_unregisters() {
    let (server, service) = serve();
    let mut config = NodeConfig::new("lab-a", NamingChoice::Remote(server.local_addr()));
    config.lease = Duration::from_millis(300);
    let node = Node::start(config).unwrap();
    let mut c = connect(&server);
    match naming(
        &mut c,
        NamingCall::Resolve {
            path: "/lab-a/creator".into(),
        },
    ) {
        Ok(Reply::Resolved(r)) => {
            assert_eq!(r.class, Class::Creator);
            assert_eq!(r.address, node.address().to_string());
        }
        other => panic!("{other:?}"),
    }
    // The renewal thread keeps it registered well past its lease.
    std::thread::sleep(Duration::from_millis(900));
    assert_eq!(
        names(naming(
            &mut c,
            NamingCall::List {
                context: "/lab-a".into()
            }
        )),
        ["creator"]
    );
    // When the naming service forgets it (as after a restart), it registers again.
    naming(
        &mut c,
        NamingCall::Unregister {
            node: "lab-a".into(),
        },
    )
    .unwrap();
    let start = Instant::now();
    while service.snapshot().node("lab-a").is_none() && start.elapsed() < Duration::from_secs(5) {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(
        naming(
            &mut c,
            NamingCall::Resolve {
                path: "/lab-a/creator".into()
            }
        )
        .is_ok()
    );
    node.shutdown();
    assert_eq!(
        names(naming(
            &mut c,
            NamingCall::List {
                context: "/".into()
            }
        )),
        Vec::<String>::new()
    );
    server.shutdown();
}
