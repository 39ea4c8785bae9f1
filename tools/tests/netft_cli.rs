//! `penelope netft-sim` and `penelope netft` as a user runs them: the emulator on a free
//! loopback port (it prints the address), then `read`, `bias` and `monitor` against it; bad
//! input exits 2 with a message, an absent box exits 1.

use penelope_testkit::process::Penelope;
use std::io::{BufRead, BufReader};
use std::process::{Child, Output, Stdio};

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

/// The emulator on a free port, and the address it printed (a bounded read of its first line).
struct Sim {
    child: Child,
    addr: String,
}

impl Sim {
    fn spawn() -> Sim {
        let mut child = PENELOPE
            .command()
            .args([
                "netft-sim",
                "--bind",
                "127.0.0.1:0",
                "--rate",
                "2000",
                "--plane",
                "0,0,-0.002,0,0,1,1000,0",
                "--duration",
                "30",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        Sim {
            child,
            addr: line.trim().to_string(),
        }
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn netft(addr: &str, args: &[&str]) -> Output {
    PENELOPE
        .command()
        .args(["netft", "--addr", addr])
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn netft_reads_biases_and_monitors_the_emulator() {
    let sim = Sim::spawn();
    assert!(sim.addr.starts_with("127.0.0.1:"), "{}", sim.addr);

    let o = netft(&sim.addr, &["read", "--json"]);
    assert!(o.status.success(), "{o:?}");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["force"].as_array().unwrap().len(), 3);
    assert_eq!(v["status"], 0);
    assert!(v["rdt_sequence"].as_u64().unwrap() > 0);

    let o = netft(&sim.addr, &["bias"]);
    assert!(o.status.success(), "{o:?}");
    assert!(String::from_utf8_lossy(&o.stdout).contains("bias sent"));

    let o = netft(
        &sim.addr,
        &["monitor", "--count", "2", "--interval-ms", "100"],
    );
    assert!(o.status.success(), "{o:?}");
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(out.lines().count(), 2, "{out}");
    assert!(out.contains("rec/s") && out.contains("missed"), "{out}");
}

#[test]
fn bad_input_exits_2_and_an_absent_box_exits_1() {
    let o = netft("not-an-address", &["read"]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let o = netft("127.0.0.1:9", &["--counts-per-force", "0", "read"]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let o = PENELOPE
        .command()
        .args(["netft-sim", "--rate", "9000"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    // Nobody streams from a bound but silent port: a clear error, exit 1.
    let silent = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let o = netft(
        &silent.local_addr().unwrap().to_string(),
        &["--timeout-ms", "2", "read"],
    );
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("no RDT record"),
        "{o:?}"
    );
    // An IP address alone means the box's own port, 49152 (nothing listens there on loopback
    // here: the read times out, the address is not refused).
    let o = netft("127.0.0.1", &["--timeout-ms", "2", "read"]);
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("no RDT record from 127.0.0.1:49152"),
        "{o:?}"
    );
}
