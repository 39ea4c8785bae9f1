//! The round trip of one remote call from Rust: `RobotProxy::forward_kinematics` on a robot of
//! a running node, timed call by call with [`Instant`]: the Rust side of the Python client's
//! benchmark (`scripts/bench-python`), which times the same call from Python.
//!
//! ```text
//! cargo run --release -p penelope-protocol --example fk_round_trip -- \
//!     NAMING_ADDR ROBOT_PATH CALLS [SECRET_FILE]
//! ```
//!
//! Prints one JSON object: the calls and the round trip's mean, p50, p99 and max, ns.

use std::time::Instant;

use penelope_hal::JointVector;
use penelope_protocol::client::Client;
use penelope_protocol::net::conn::ClientConfig;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [naming, robot, calls, rest @ ..] = args.as_slice() else {
        return Err("usage: fk_round_trip NAMING_ADDR ROBOT_PATH CALLS [SECRET_FILE]".into());
    };
    let calls: usize = calls.parse()?;
    if calls == 0 {
        return Err("CALLS must be at least 1".into());
    }
    let mut config = ClientConfig::new("fk-round-trip");
    if let Some(file) = rest.first() {
        let mut secret = std::fs::read(file)?;
        while secret.last().is_some_and(|b| *b == b'\n' || *b == b'\r') {
            secret.pop();
        }
        config.secret = Some(secret.into());
    }
    let client = Client::connect(naming.parse()?, config)?;
    let robot = client.robot(robot)?;
    let mut q = JointVector::zeros();
    for (i, x) in q.iter_mut().take(6).enumerate() {
        *x = 0.1 * (i as f64 + 1.0);
    }
    // Warm up: the joint count, the connection to the node, the caches.
    for _ in 0..calls.min(200) {
        robot.forward_kinematics(Some(&q))?;
    }
    let mut ns: Vec<u64> = Vec::with_capacity(calls);
    for _ in 0..calls {
        let t = Instant::now();
        let pose = robot.forward_kinematics(Some(&q))?;
        ns.push(u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX));
        std::hint::black_box(pose);
    }
    ns.sort_unstable();
    let at = |p: f64| ns[((ns.len() - 1) as f64 * p).round() as usize];
    let mean = ns.iter().sum::<u64>() as f64 / ns.len().max(1) as f64;
    println!(
        "{{\"calls\": {}, \"mean_ns\": {mean:.0}, \"p50_ns\": {}, \"p99_ns\": {}, \"max_ns\": {}}}",
        ns.len(),
        at(0.5),
        at(0.99),
        ns.last().copied().unwrap_or(0)
    );
    Ok(())
}
