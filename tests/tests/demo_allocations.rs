//! The demo's real-time path, as the node runtime builds it from `config/demo.toml`, allocates
//! nothing: the master's and the slave's control and communication tasks, the FRHC and PUMA 200
//! plants behind their simulated boards, the operator's hand, the wrist sensor reading the
//! slave's plant, inverse kinematics, the teleoperation channel and the bilateral laws, over
//! 100,000 control ticks per robot (the script's clutch, contact and tapping phases included).
//!
//! The loops are built by the creator of a node the demo's system file was applied to, and
//! stepped on this test's thread; the counting allocator counts the allocations of this test's
//! thread; this binary holds this one test only.

use std::net::SocketAddr;

use penelope_hal::Transition;
use penelope_protocol::proto::{Call, Method};
use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::runs::DEMO_SYSTEM;
use penelope_supervisor::system::SystemFile;
use penelope_testkit::alloc::CountingAllocator;
use penelope_tests::{assert_pair_ran, step_teleop_pair};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn one_hundred_thousand_demo_ticks_allocate_nothing() {
    let mut file = SystemFile::parse(DEMO_SYSTEM).unwrap();
    for o in &mut file.objects {
        o.active = false; // built below without threads
    }
    let mut config = NodeConfig::new("lab", NamingChoice::None);
    config.listen = SocketAddr::from(([127, 0, 0, 1], 0));
    config.creator.clock = ClockMode::Simulated;
    let node = Node::start(config).unwrap();
    file.apply(&node).expect("the demo's system applies");
    let c = node.creator();
    let mut master = c.detach_loop("display").expect("the master's loop builds");
    let mut slave = c.detach_loop("follow").expect("the slave's loop builds");
    assert!(
        slave.wrench.is_none(),
        "the wrist sensor is read in the slave's loop, not through a feed"
    );
    // Warm-up: the first ticks start the channels and anchor the mapping.
    step_teleop_pair(&mut master, &mut slave, 1..1001, &mut |_| {});
    let allocated = step_teleop_pair(&mut master, &mut slave, 1001..101_001, &mut |_| {});
    assert_eq!(
        allocated, 0,
        "the demo's loops allocated or freed {allocated} times"
    );
    assert_pair_ran(&master, &slave, 101_000, 50_000);
    drop((master, slave));
    let _ = node.call(Call::Object {
        object: "follow".into(),
        method: Method::Transition(Transition::Cleanup),
    });
    node.shutdown();
}
