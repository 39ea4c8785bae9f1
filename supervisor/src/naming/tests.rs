//! Unit tests of the naming tree, the service, authorization and the reaper, and a property
//! test that random operations keep the tree's invariants.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::tree::join;
use super::*;
use penelope_protocol::proto::{
    Call, CallError, Class, NameEntry, NamingCall, NodeInfo, ObjectRef, Reply, Role, WireError,
};
use penelope_protocol::service::{Identity, Service, Session};
use proptest::prelude::*;

fn r(node: &str, name: &str) -> ObjectRef {
    ObjectRef {
        node: node.into(),
        address: "127.0.0.1:7301".into(),
        name: name.into(),
        class: Class::Robot,
        kind: "robot/puma560".into(),
    }
}

const S: fn(u64) -> Duration = Duration::from_secs;

#[test]
fn bind_resolve_list_unbind() {
    let mut t = NamingTree::default();
    t.bind("/lab/robots/slave", r("lab", "slave"), false)
        .unwrap();
    assert_eq!(t.resolve("/lab/robots/slave").unwrap().name, "slave");
    assert_eq!(
        t.list("/").unwrap(),
        vec![NameEntry::Context { name: "lab".into() }]
    );
    assert_eq!(
        t.list("/lab").unwrap(),
        vec![NameEntry::Context {
            name: "robots".into()
        }]
    );
    assert!(matches!(
        t.bind("/lab/robots/slave", r("lab", "x"), false),
        Err(WireError::Call(CallError::NameTaken(_)))
    ));
    t.bind("/lab/robots/slave", r("lab", "x"), true).unwrap();
    assert_eq!(t.resolve("/lab/robots/slave").unwrap().name, "x");
    assert_eq!(t.binding_count(), 1);
    t.bind("/lab/robots/master", r("lab", "m"), false).unwrap();
    let names: Vec<_> = t
        .list("/lab/robots")
        .unwrap()
        .iter()
        .map(|e| e.name().to_string())
        .collect();
    assert_eq!(names, ["master", "slave"]);
    // Contexts and objects do not replace each other.
    assert!(matches!(
        t.bind("/lab/robots", r("lab", "x"), true),
        Err(WireError::Call(CallError::NameTaken(_)))
    ));
    assert!(matches!(
        t.bind("/lab/robots/slave/deeper", r("lab", "x"), true),
        Err(WireError::Call(CallError::NameTaken(p))) if p == "/lab/robots/slave"
    ));
    assert!(matches!(
        t.resolve("/lab"),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    assert!(matches!(
        t.list("/lab/robots/slave"),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    assert!(matches!(
        t.resolve("/nope"),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    assert!(matches!(
        t.unbind("/lab"),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    t.unbind("/lab/robots/slave").unwrap();
    assert!(t.list("/lab/robots").is_ok());
    t.unbind("/lab/robots/master").unwrap();
    // Unregistered contexts left empty go away.
    assert!(t.list("/").unwrap().is_empty());
    assert_eq!(t.binding_count(), 0);
    assert!(matches!(
        t.unbind("/lab/robots/master"),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    t.check_invariants().unwrap();
}

#[test]
fn paths_are_checked() {
    let t = NamingTree::default();
    for bad in [
        "", "lab", "/lab/", "//lab", "/lab//x", "/a b", "/../x", "/a/./b",
    ] {
        assert!(
            matches!(
                t.resolve(bad),
                Err(WireError::Call(CallError::BadName { .. }))
            ),
            "{bad:?}"
        );
    }
    let deep = "/a".repeat(9);
    assert!(matches!(
        t.list(&deep),
        Err(WireError::Call(CallError::BadName { .. }))
    ));
    assert!(t.parse_path(&"/a".repeat(8)).is_ok());
    let mut t = t;
    assert!(matches!(
        t.bind("/", r("a", "b"), true),
        Err(WireError::Call(CallError::BadName { .. }))
    ));
    let mut bad_ref = r("lab", "x");
    bad_ref.address = "x".repeat(MAX_ADDRESS_LEN + 1);
    assert!(matches!(
        t.bind("/a/b", bad_ref, false),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    t.check_invariants().unwrap();
}

#[test]
fn limits_refuse_without_changing_anything() {
    let mut t = NamingTree::new(NamingLimits {
        max_bindings: 2,
        max_nodes: 1,
        ..NamingLimits::default()
    });
    t.bind("/a/x", r("a", "x"), false).unwrap();
    t.bind("/a/y", r("a", "y"), false).unwrap();
    assert!(matches!(
        t.bind("/b/c/z", r("a", "z"), false),
        Err(WireError::Call(CallError::LimitReached { limit: 2, .. }))
    ));
    // A rebind is not a new binding.
    t.bind("/a/y", r("a", "y2"), true).unwrap();
    assert_eq!(t.list("/").unwrap().len(), 1, "no context was left behind");
    t.register("n1", "h:1", S(1), S(0)).unwrap();
    assert!(matches!(
        t.register("n2", "h:2", S(1), S(0)),
        Err(WireError::Call(CallError::LimitReached { .. }))
    ));
    assert!(matches!(
        t.register("n1", "h:1", Duration::from_millis(1), S(0)),
        Err(WireError::Call(CallError::BadArgument(_)))
    ));
    t.check_invariants().unwrap();
}

#[test]
fn a_node_context_lives_with_its_lease() {
    let mut t = NamingTree::default();
    t.register("a", "127.0.0.1:1", S(3), S(0)).unwrap();
    t.register("b", "127.0.0.1:2", S(3), S(0)).unwrap();
    t.bind("/a/creator", r("a", "creator"), false).unwrap();
    t.bind("/a/robots/slave", r("a", "slave"), false).unwrap();
    t.bind("/b/sensors/ft", r("b", "ft"), false).unwrap();
    t.bind("/shared/thing", r("b", "thing"), false).unwrap();
    // A registered node's context survives its last unbind.
    t.unbind("/a/robots/slave").unwrap();
    t.unbind("/a/creator").unwrap();
    assert_eq!(t.list("/a").unwrap(), vec![]);
    t.bind("/a/robots/slave", r("a", "slave"), false).unwrap();
    // Renewals keep it alive.
    assert!(t.expire(S(2)).is_empty());
    t.renew("a", S(2)).unwrap();
    assert_eq!(t.expire(S(3)), vec!["b".to_string()]);
    assert!(matches!(
        t.resolve("/b/sensors/ft"),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    assert!(matches!(
        t.renew("b", S(3)),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    // Bindings outside a node context belong to nobody.
    assert!(t.resolve("/shared/thing").is_ok());
    assert_eq!(t.expire(S(5)), vec!["a".to_string()]);
    assert_eq!(
        t.list("/").unwrap(),
        vec![NameEntry::Context {
            name: "shared".into()
        }]
    );
    assert_eq!(t.binding_count(), 1);
    t.check_invariants().unwrap();
}

#[test]
fn registering_again_starts_afresh_and_names_are_not_stolen() {
    let mut t = NamingTree::default();
    t.register("a", "h:1", S(3), S(0)).unwrap();
    t.bind("/a/robots/slave", r("a", "slave"), false).unwrap();
    assert!(matches!(
        t.register("a", "h:2", S(3), S(1)),
        Err(WireError::Call(CallError::NameTaken(_)))
    ));
    t.register("a", "h:1", S(3), S(1)).unwrap();
    assert_eq!(t.list("/a").unwrap(), vec![]);
    assert_eq!(t.binding_count(), 0);
    // After the lease lapsed, another address may take the name.
    t.register("a", "h:2", S(3), S(4)).unwrap();
    assert_eq!(t.node("a").unwrap().address, "h:2");
    t.bind("/c", r("a", "c"), false).unwrap();
    assert!(matches!(
        t.register("c", "h:3", S(3), S(4)),
        Err(WireError::Call(CallError::NameTaken(_)))
    ));
    t.unregister("a").unwrap();
    assert!(matches!(
        t.unregister("a"),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    t.check_invariants().unwrap();
}

#[test]
fn the_service_serves_naming_calls_and_refuses_the_rest() {
    let s = NamingService::new("naming", NamingLimits::default());
    s.handle(NamingCall::Register {
        node: "a".into(),
        address: "h:1".into(),
        lease_ms: 20,
    })
    .unwrap();
    s.handle(NamingCall::Bind {
        path: "/a/creator".into(),
        reference: r("a", "creator"),
        rebind: false,
    })
    .unwrap();
    assert!(matches!(
        s.handle(NamingCall::Resolve {
            path: "/a/creator".into()
        }),
        Ok(Reply::Resolved(_))
    ));
    std::thread::sleep(Duration::from_millis(40));
    assert!(matches!(
        s.handle(NamingCall::Resolve {
            path: "/a/creator".into()
        }),
        Err(WireError::Call(CallError::UnknownName(_)))
    ));
    let (outbox, _rx) = penelope_protocol::service::Outbox::bounded(1);
    let session = Session {
        id: 1,
        peer: "127.0.0.1:1".parse().unwrap(),
        client: "t".into(),
        identity: penelope_protocol::service::Identity::LOCAL_NODE,
        outbox,
    };
    assert!(matches!(
        s.call(&session, Call::NodeInfo),
        Ok(Reply::Node(NodeInfo {
            hosts_naming: true,
            ..
        }))
    ));
    assert!(matches!(
        s.call(
            &session,
            Call::Creator(penelope_protocol::proto::CreatorCall::Kinds)
        ),
        Err(WireError::Call(CallError::Unsupported { .. }))
    ));
}

#[test]
fn authorization_follows_the_role_and_the_own_context() {
    let node = Identity {
        role: Role::Node,
        proven: true,
    };
    let reader = Identity {
        role: Role::Reader,
        proven: true,
    };
    let admin = Identity {
        role: Role::Admin,
        proven: true,
    };
    let bind = |path: &str| NamingCall::Bind {
        path: path.into(),
        reference: r("a", "x"),
        rebind: true,
    };
    let unbind = |path: &str| NamingCall::Unbind { path: path.into() };
    let unregister = |n: &str| NamingCall::Unregister { node: n.into() };
    let list = NamingCall::List {
        context: "/b".into(),
    };
    for who in [node, reader, admin] {
        assert!(authorize(who, "a", &list).is_ok());
    }
    assert!(authorize(node, "a", &bind("/a/robots/x")).is_ok());
    assert!(authorize(node, "a", &unbind("/a/x")).is_ok());
    assert!(authorize(node, "a", &unregister("a")).is_ok());
    for call in [
        bind("/b/robots/x"),
        bind("/ab/x"),
        bind("/a"),
        bind("a/x"),
        bind("/"),
        unbind("/b/x"),
        unregister("b"),
    ] {
        assert!(
            matches!(
                authorize(node, "a", &call),
                Err(WireError::Call(CallError::Forbidden(_)))
            ),
            "{call:?}"
        );
        assert!(matches!(
            authorize(reader, "a", &call),
            Err(WireError::Call(CallError::Forbidden(_)))
        ));
        assert!(authorize(admin, "a", &call).is_ok());
    }
}

#[test]
fn the_reaper_expires_without_calls() {
    let s = Arc::new(NamingService::new("naming", NamingLimits::default()));
    s.handle(NamingCall::Register {
        node: "a".into(),
        address: "h:1".into(),
        lease_ms: 10,
    })
    .unwrap();
    let reaper = s.start_reaper(Duration::from_millis(5)).unwrap();
    let t0 = Instant::now();
    while s.lock().node("a").is_some() && t0.elapsed() < Duration::from_secs(5) {
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(s.lock().node("a").is_none());
    reaper.stop();
}

#[derive(Clone, Debug)]
enum Op {
    Bind(Vec<u8>, bool),
    Unbind(Vec<u8>),
    Register(u8, u8),
    Renew(u8),
    Unregister(u8),
    Advance(u8),
}

const NAMES: [&str; 4] = ["a", "b", "c", "d"];

fn path_of(comps: &[u8]) -> String {
    join(
        &comps
            .iter()
            .map(|c| NAMES[*c as usize % 4])
            .collect::<Vec<_>>(),
    )
}

fn op() -> impl Strategy<Value = Op> {
    let comps = prop::collection::vec(0u8..4, 1..5);
    prop_oneof![
        4 => (comps.clone(), any::<bool>()).prop_map(|(c, r)| Op::Bind(c, r)),
        3 => comps.prop_map(Op::Unbind),
        2 => (0u8..4, 0u8..2).prop_map(|(n, a)| Op::Register(n, a)),
        2 => (0u8..4).prop_map(Op::Renew),
        1 => (0u8..4).prop_map(Op::Unregister),
        2 => (0u8..5).prop_map(Op::Advance),
    ]
}

proptest! {
    #[test]
    fn random_operations_keep_the_tree_consistent(ops in prop::collection::vec(op(), 1..60)) {
        let mut t = NamingTree::new(NamingLimits {
            max_bindings: 12,
            max_depth: 4,
            max_nodes: 3,
            ..NamingLimits::default()
        });
        let mut now = Duration::ZERO;
        for op in ops {
            match op {
                Op::Bind(c, rebind) => {
                    let _ = t.bind(&path_of(&c), r("a", "x"), rebind);
                }
                Op::Unbind(c) => {
                    let _ = t.unbind(&path_of(&c));
                }
                Op::Register(n, a) => {
                    let _ = t.register(NAMES[n as usize], &format!("h:{a}"), S(3), now);
                }
                Op::Renew(n) => {
                    let _ = t.renew(NAMES[n as usize], now);
                }
                Op::Unregister(n) => {
                    let _ = t.unregister(NAMES[n as usize]);
                }
                Op::Advance(s) => {
                    now += S(u64::from(s));
                    for node in t.expire(now) {
                        let path = format!("/{node}");
                        prop_assert!(t.node(&node).is_none(), "{} still registered", path);
                    }
                }
            }
            if let Err(e) = t.check_invariants() {
                prop_assert!(false, "{}", e);
            }
            // Every resolvable path lists in its parent.
            for comps in all_paths(4) {
                let path = path_of(&comps);
                if let Ok(reference) = t.resolve(&path) {
                    let parent = path_of(&comps[..comps.len() - 1]);
                    let name = NAMES[*comps.last().unwrap() as usize];
                    let listed = t.list(&parent).unwrap();
                    let entry = NameEntry::Object { name: name.into(), reference };
                    prop_assert!(listed.contains(&entry), "{} not listed in {}", path, parent);
                }
            }
            // No node outlives its lease.
            for l in t.nodes() {
                prop_assert!(l.deadline > now, "{} outlived its lease", l.node);
            }
        }
    }
}

fn all_paths(depth: usize) -> Vec<Vec<u8>> {
    let mut out: Vec<Vec<u8>> = Vec::new();
    let mut layer: Vec<Vec<u8>> = vec![vec![]];
    for _ in 0..depth {
        let mut next = Vec::new();
        for p in &layer {
            for c in 0..4u8 {
                let mut q = p.clone();
                q.push(c);
                next.push(q);
            }
        }
        out.extend(next.iter().cloned());
        layer = next;
    }
    out
}

#[test]
fn a_node_takes_its_name_back_from_a_registration_nobody_answers_at() {
    let s = NamingService::new("naming", NamingLimits::default());
    let register = |address: &str| NamingCall::Register {
        node: "a".into(),
        address: address.into(),
        lease_ms: 60_000,
    };
    // The first run, alive: its address accepts connections.
    let first = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let first_address = first.local_addr().unwrap().to_string();
    s.handle(register(&first_address)).unwrap();
    s.handle(NamingCall::Bind {
        path: "/a/robots/slave".into(),
        reference: r("a", "slave"),
        rebind: false,
    })
    .unwrap();
    let second = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let second_address = second.local_addr().unwrap().to_string();
    // A live holder keeps its name: a second node of that name is refused.
    assert!(matches!(
        s.handle(register(&second_address)),
        Err(WireError::Call(CallError::NameTaken(_)))
    ));
    // The first run dies (nothing listens there any more): the restarted node, at another
    // address, takes the name back at once, with a fresh context, long before the lease ends.
    drop(first);
    let started = Instant::now();
    s.handle(register(&second_address)).unwrap();
    assert!(started.elapsed() < Duration::from_secs(5));
    let tree = s.snapshot();
    assert_eq!(tree.node("a").unwrap().address, second_address);
    assert_eq!(tree.list("/a").unwrap(), vec![]);
    // A holder whose address cannot be probed without a look-up keeps its name.
    let t = NamingService::new("naming", NamingLimits::default());
    t.handle(NamingCall::Register {
        node: "b".into(),
        address: "box.lab:7300".into(),
        lease_ms: 60_000,
    })
    .unwrap();
    assert!(matches!(
        t.handle(NamingCall::Register {
            node: "b".into(),
            address: second_address.clone(),
            lease_ms: 60_000,
        }),
        Err(WireError::Call(CallError::NameTaken(_)))
    ));
}
