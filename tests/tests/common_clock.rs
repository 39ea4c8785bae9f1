//! The system's common clock in recordings: a node whose naming service is another process
//! estimates that host's clock by exchanging times with it (`Call::Time`, when it registers and
//! with every renewal), and stamps its recordings' log times with the estimate, which `/clock`
//! records; the node that hosts the naming service, and a node on a simulated clock, are their
//! own common clock.
//!
//! The processes here share one machine's clock, so the true offset is zero: the estimate must
//! be within half its exchange's round trip of it (the bound of any four-timestamp method).

use std::path::PathBuf;

use penelope_hal::Transition;
use penelope_runtime::common_clock::ClockSource;
use penelope_runtime::objects::clock::ClockMode;
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig};

fn node(name: &str, clock: ClockMode, naming: NamingChoice) -> Node {
    let mut config = NodeConfig::new(name, naming);
    config.creator.rt.priority = None;
    config.creator.clock = clock;
    config.creator.records = Some(std::env::temp_dir());
    Node::start(config).unwrap()
}

fn scratch(name: &str) -> PathBuf {
    let p = std::env::temp_dir().join(format!("common-clock-{}-{name}.mcap", std::process::id()));
    let _ = std::fs::remove_file(&p);
    p
}

/// Records on `node` while an object is created, configured and destroyed; returns the
/// `/clock` messages and, for each `/lifecycle` message, its log time less its node time and
/// the offset the `/clock` message before it gave.
fn record(node: &Node, name: &str) -> (Vec<serde_json::Value>, Vec<(i64, i64)>) {
    let path = scratch(name);
    let creator = node.creator();
    let file = path.file_name().unwrap().to_str().unwrap();
    creator.record_start(file, &[]).unwrap();
    creator
        .create("trajectory/step", "hold", "goal = [0.1, 0, 0, 0, 0, 0]")
        .unwrap();
    creator.transition("hold", Transition::Configure).unwrap();
    creator.destroy("hold", true).unwrap();
    creator.record_stop().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    let (mut clocks, mut stamps) = (Vec::new(), Vec::new());
    let mut offset = None;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        match m.channel.topic.as_str() {
            "/clock" => {
                let schema = m.channel.schema.as_ref().expect("a schema");
                assert_eq!(schema.name, "penelope.CommonClock");
                offset = v["offset_ns"].as_i64().or(offset);
                let shift = m.log_time as i64 - v["time_ns"].as_i64().unwrap();
                assert_eq!(Some(shift), offset, "/clock is stamped like the rest: {v}");
                clocks.push(v);
            }
            "/lifecycle" => {
                let shift = m.log_time as i64 - v["time_ns"].as_i64().unwrap();
                stamps.push((shift, offset.expect("a /clock message first")));
            }
            _ => {}
        }
    }
    (clocks, stamps)
}

#[test]
fn recordings_are_stamped_on_the_naming_hosts_clock_as_each_node_estimates_it() {
    let naming = node("naming", ClockMode::RealTime, NamingChoice::Host);
    let at = NamingChoice::Remote(naming.address());
    let remote = node("slave", ClockMode::RealTime, at.clone());
    let simulated = node("sim", ClockMode::Simulated, at);

    // The remote node estimated the naming host's clock when it registered.
    let clock = remote.creator().common_clock();
    assert_eq!(
        clock.source(),
        &ClockSource::Naming {
            address: naming.address()
        }
    );
    let e = clock.estimate();
    assert!(e.exchanges >= 8, "{e:?}");
    eprintln!("the remote node's estimate: {e:?}");
    let (offset, round_trip) = (e.offset_ns.unwrap(), e.round_trip_ns.unwrap());
    assert!(
        offset.abs() <= round_trip / 2 + 1,
        "one machine, one clock: {e:?}"
    );

    let (clocks, stamps) = record(&remote, "remote");
    assert!(!clocks.is_empty() && !stamps.is_empty());
    for c in &clocks {
        assert_eq!(c["source"], "naming", "{c}");
        assert_eq!(c["address"], naming.address().to_string(), "{c}");
        let (o, rt) = (
            c["offset_ns"].as_i64().unwrap(),
            c["round_trip_ns"].as_i64().unwrap(),
        );
        assert!(o.abs() <= rt / 2 + 1, "{c}");
    }
    // Every message's log time is its node time plus the offset in force when written.
    for (shift, offset) in &stamps {
        assert_eq!(shift, offset);
    }

    // The naming service's own node, and a simulated one: their own clocks, exactly.
    for (n, name) in [(&naming, "naming"), (&simulated, "sim")] {
        assert_eq!(n.creator().common_clock().source(), &ClockSource::Own);
        let (clocks, stamps) = record(n, name);
        assert!(
            clocks
                .iter()
                .all(|c| c["source"] == "own" && c["offset_ns"] == 0)
        );
        assert!(stamps.iter().all(|&(shift, _)| shift == 0), "{stamps:?}");
    }
    for n in [remote, simulated, naming] {
        n.shutdown();
    }
}
