//! A teleoperation session survives its master's half being stopped and started again: the
//! slave holds while the master is silent, and once the master runs again (and the slave's
//! latched watchdog fault is re-armed) the slave follows it, because a re-activated end goes on
//! numbering its samples where it stopped (the other side keeps the newest by sequence number).

use std::time::Duration;

use penelope_hal::Transition;
use penelope_protocol::proto::{Call, ControllerMethod, Method, Reply};
use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::runs::DEMO_SYSTEM;
use penelope_supervisor::system::SystemFile;

fn ok(node: &Node, object: &str, method: Method) -> Reply {
    node.call(Call::Object {
        object: object.into(),
        method,
    })
    .unwrap_or_else(|e| panic!("{object}: {e}"))
}

/// The slave's newest sample: its safety state and fault, and its loop's tick count.
fn slave(node: &Node) -> (String, Option<String>, u64) {
    match ok(node, "follow", Method::Controller(ControllerMethod::Status)) {
        Reply::Status(s) => {
            let last = s.last.expect("the slave's loop has ticked");
            (last.state, last.fault, s.ticks)
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_slave_follows_a_master_stopped_and_started_again() {
    let mut config = NodeConfig::new("lab", NamingChoice::None);
    config.creator.rt.priority = None;
    config.creator.clock = ClockMode::Simulated;
    let node = Node::start(config).unwrap();
    SystemFile::parse(DEMO_SYSTEM)
        .unwrap()
        .apply(&node)
        .expect("the demo's system comes up");
    let advance = |ms| node.creator().advance(Duration::from_millis(ms)).unwrap();
    advance(2000);
    assert_eq!(slave(&node).0, "running");

    // The master stops: the slave holds (and its watchdog may latch a fault).
    ok(&node, "display", Method::Transition(Transition::Deactivate));
    advance(500);
    let (state, fault, _) = slave(&node);
    assert!(state == "holding" || state == "fault", "{state} {fault:?}");

    // The master runs again (the slave re-armed if it latched): the slave follows again.
    ok(&node, "display", Method::Transition(Transition::Activate));
    if state == "fault" {
        ok(&node, "follow", Method::Controller(ControllerMethod::Rearm));
    }
    advance(1000);
    let (state, fault, ticks) = slave(&node);
    assert_eq!(state, "running", "{fault:?}");
    assert!(fault.is_none(), "{fault:?}");
    assert!(ticks > 3000, "{ticks}");
    node.shutdown();
}
