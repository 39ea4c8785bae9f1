//! The demo's real-time path, as the node runtime builds it from `config/demo.toml`, allocates
//! nothing: the master's and the slave's control and communication tasks, the FRHC and PUMA 200
//! plants behind their simulated boards, the operator's hand, the wrist sensor reading the
//! slave's plant, inverse kinematics, the teleoperation channel and the bilateral laws, over
//! 100,000 control ticks per robot (the script's clutch, contact and tapping phases included).
//!
//! The loops are built by the creator of a node the demo's system file was applied to, and
//! stepped on this test's thread; the counting allocator counts every allocation of the
//! process, so this binary holds this one test only.

use std::net::SocketAddr;

use penelope_hal::{Timestamp, Transition};
use penelope_rt_core::safety::SafetyState;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::objects::clock::ClockMode;
use penelope_supervisor::proto::{Call, Method};
use penelope_supervisor::runs::DEMO_SYSTEM;
use penelope_supervisor::system::SystemFile;
use penelope_tests::{CountingAllocator, allocations};

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
    let mut step = |i: u64| {
        let now = Timestamp::from_nanos(i * 1_000_000);
        if i.is_multiple_of(2) {
            master.comm.tick(now);
            slave.comm.tick(now);
        }
        master.control.tick(now);
        slave.control.tick(now);
        while master.telemetry.pop().is_some() {}
        while slave.telemetry.pop().is_some() {}
    };
    // Warm-up: the first ticks start the channels and anchor the mapping.
    for i in 0..1000 {
        step(i);
    }
    let before = allocations();
    for i in 1000..101_000 {
        step(i);
    }
    let after = allocations();
    assert_eq!(
        after - before,
        0,
        "the demo's loops allocated or freed {} times",
        after - before
    );
    for (name, d) in [("master", &master), ("slave", &slave)] {
        let last = *d.control.control_loop().last_sample();
        assert_eq!(last.seq, 101_000, "{name}");
        assert_eq!(last.state, SafetyState::Running, "{name}: {:?}", last.fault);
        assert!(d.comm.published() > 50_000, "{name}");
    }
    // The slave met the wall during the script (its sensor read the plant's contact).
    drop((master, slave));
    let _ = node.call(Call::Object {
        object: "follow".into(),
        method: Method::Transition(Transition::Cleanup),
    });
    node.shutdown();
}
