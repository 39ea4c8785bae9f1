//! Live link telemetry: a client subscribed to a `trajectory/teleop` channel whose end is
//! linked to another node gets its link records as `ServerMsg::Link` batches, over a real
//! connection. The demo's two-node system (`config/demo-two-nodes.toml`) on simulated clocks
//! stepped in turn, 1 ms at a time (records follow the simulated clock: one every 100 ms), and
//! a LinkStream through the naming service on real clocks.

use std::time::{Duration, Instant};

use penelope_protocol::client::Client;
use penelope_protocol::net::conn::{ClientConfig, Connection, Pushed, RpcError};
use penelope_protocol::proto::{Call, CallError, CreatorCall, LinkRecord, Reply, WireError};
use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};
use penelope_supervisor::runs::DEMO_SYSTEM;
use penelope_supervisor::system::SystemFile;
use penelope_testkit::net::free_udp_port;

/// The demo's two-node system on free loopback ports.
fn two_nodes() -> String {
    include_str!("../../config/demo-two-nodes.toml")
        .replace("127.0.0.1:7410", &format!("127.0.0.1:{}", free_udp_port()))
        .replace("127.0.0.1:7420", &format!("127.0.0.1:{}", free_udp_port()))
}

fn node(name: &str, clock: ClockMode, naming: NamingChoice) -> Node {
    let mut config = NodeConfig::new(name, naming);
    config.creator.rt.priority = None;
    config.creator.clock = clock;
    Node::start(config).unwrap()
}

/// A client's connection to `node`.
fn connect(node: &Node) -> Connection {
    // An admin: the test also destroys channels.
    Connection::connect(node.address(), &ClientConfig::admin("watcher")).unwrap()
}

fn subscribe(conn: &mut Connection, object: &str) -> Result<u64, RpcError> {
    match conn.call(Call::Subscribe {
        object: object.into(),
        decimation: 1,
    })? {
        Reply::Subscribed { subscription } => Ok(subscription),
        other => panic!("{other:?}"),
    }
}

/// Steps both simulated nodes `ms` milliseconds, 1 ms at a time.
fn step(a: &Node, b: &Node, ms: u32) {
    for _ in 0..ms {
        a.creator().advance(Duration::from_millis(1)).unwrap();
        b.creator().advance(Duration::from_millis(1)).unwrap();
    }
}

/// The link records of `subscription` that arrive within `wait`.
fn records(conn: &mut Connection, subscription: u64, wait: Duration) -> Vec<LinkRecord> {
    let mut out = Vec::new();
    let deadline = Instant::now() + wait;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match conn.next_pushed(left).unwrap() {
            Some(Pushed::Link(batch)) => {
                assert_eq!(batch.subscription, subscription);
                assert_eq!(batch.dropped, 0, "a client that keeps up loses nothing");
                out.extend(batch.records);
            }
            Some(other) => panic!("only link records were subscribed to: {other:?}"),
            None => return out,
        }
    }
}

#[test]
fn a_subscriber_to_a_linked_channel_gets_its_link_records_every_100_ms() {
    let file = SystemFile::parse(&two_nodes()).expect("a valid system file");
    let a = node("master", ClockMode::Simulated, NamingChoice::None);
    let b = node("slave", ClockMode::Simulated, NamingChoice::None);
    file.apply(&a).expect("the master's half");
    file.apply(&b).expect("the slave's half");
    // The loops run and the link carries samples and heartbeats before anyone watches.
    step(&a, &b, 200);

    let mut conn = connect(&a);
    let subscription = subscribe(&mut conn, "link").expect("a linked channel is watched");
    step(&a, &b, 500);
    // Every record was pushed during the steps: the wait only lets the frames cross.
    let got = records(&mut conn, subscription, Duration::from_secs(2));
    assert_eq!(
        got.len(),
        5,
        "one record per 100 ms of simulated time: {got:#?}"
    );
    for pair in got.windows(2) {
        assert_eq!(
            pair[1].time_ns - pair[0].time_ns,
            100_000_000,
            "on the simulated clock"
        );
        assert!(
            pair[1].samples_taken > pair[0].samples_taken,
            "samples keep arriving: {} then {}",
            pair[0].samples_taken,
            pair[1].samples_taken
        );
        assert!(pair[1].trips >= pair[0].trips);
    }
    let last = got.last().unwrap();
    assert!(!last.down);
    assert!(
        last.clock_offset_ns.is_some(),
        "heartbeats estimate the offset: {last:?}"
    );
    assert!(last.one_way_delay_ns.is_some() && last.last_heard_ns.is_some());
    assert_eq!(a.creator().subscription_count(), 1);

    // Unsubscribed: nothing more comes.
    assert_eq!(
        conn.call(Call::Unsubscribe { subscription }).unwrap(),
        Reply::Unit
    );
    step(&a, &b, 300);
    assert!(records(&mut conn, subscription, Duration::from_millis(200)).is_empty());
    assert_eq!(a.creator().subscription_count(), 0);

    // A subscription ends with its channel.
    let subscription = subscribe(&mut conn, "link").unwrap();
    step(&a, &b, 100);
    assert!(!records(&mut conn, subscription, Duration::from_millis(500)).is_empty());
    conn.call(Call::Creator(CreatorCall::Destroy {
        name: "link".into(),
        force: true,
    }))
    .expect("the channel destroyed, its controllers stopped");
    assert_eq!(a.creator().subscription_count(), 0);
    step(&a, &b, 300);
    assert!(records(&mut conn, subscription, Duration::from_millis(200)).is_empty());

    // A client that leaves ends its subscriptions.
    let mut other = connect(&b);
    subscribe(&mut other, "link").unwrap();
    assert_eq!(b.creator().subscription_count(), 1);
    drop(other);
    let deadline = Instant::now() + Duration::from_secs(5);
    while b.creator().subscription_count() > 0 {
        assert!(
            Instant::now() < deadline,
            "the node never noticed the client left"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    for n in [a, b] {
        n.shutdown();
    }
}

#[test]
fn a_channel_with_both_ends_on_one_node_has_no_link_to_watch() {
    let lab = node("lab", ClockMode::Simulated, NamingChoice::None);
    SystemFile::parse(DEMO_SYSTEM)
        .unwrap()
        .apply(&lab)
        .expect("the demo on one node");
    let mut conn = connect(&lab);
    match subscribe(&mut conn, "link") {
        Err(RpcError::Remote(WireError::Call(CallError::NoLink(channel)))) => {
            assert_eq!(channel, "link")
        }
        other => panic!("{other:?}"),
    }
    // Other trajectories are no channels at all.
    assert!(matches!(
        subscribe(&mut conn, "nope"),
        Err(RpcError::Remote(WireError::Call(CallError::UnknownName(_))))
    ));
    assert_eq!(lab.creator().subscription_count(), 0);
    lab.shutdown();
}

#[test]
fn a_link_stream_through_the_naming_service_on_real_clocks() {
    let naming = node("naming", ClockMode::RealTime, NamingChoice::Host);
    let at = NamingChoice::Remote(naming.address());
    let a = node("master", ClockMode::RealTime, at);
    let b = node(
        "slave",
        ClockMode::RealTime,
        NamingChoice::Remote(naming.address()),
    );
    let file = SystemFile::parse(&two_nodes()).unwrap();
    file.apply(&a).unwrap();
    file.apply(&b).unwrap();
    let client = Client::connect(naming.address(), ClientConfig::admin("watcher")).unwrap();
    // Bound once the node registered its objects.
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut stream = loop {
        match client.watch_link("slave/link", 1) {
            Ok(s) => break s,
            Err(e) => assert!(Instant::now() < deadline, "never watchable: {e}"),
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert_eq!(stream.path(), "/slave/trajectories/link");
    let mut taken = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    while taken.len() < 3 {
        assert!(Instant::now() < deadline, "three records within 10 s");
        if let Some(r) = stream.recv_timeout(Duration::from_secs(1)).unwrap() {
            taken.push(r.samples_taken);
        }
    }
    assert!(taken.windows(2).all(|w| w[1] >= w[0]), "{taken:?}");
    // A controller's ticks are no link records: refused before anything is sent.
    assert!(matches!(
        client.watch_link("slave/follow", 1),
        Err(RpcError::Remote(WireError::Call(
            CallError::WrongClass { .. }
        )))
    ));
    drop(stream);
    for n in [a, b, naming] {
        n.shutdown();
    }
}
