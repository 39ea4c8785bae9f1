//! What the end-to-end tests of the `penelope` binary share: child processes that are killed
//! when a test ends, free loopback ports, starting a process and waiting for its ready line,
//! and `penelope ctl` against a naming service.
//!
//! Each test file uses a part of it (`mod common;`), hence the `dead_code` allowance.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, TcpListener};
use std::path::PathBuf;
use std::process::{Child, Command, Output, Stdio};

/// The binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_penelope");

/// The child processes, killed when the test ends, passed or failed.
pub struct Children(pub Vec<Child>);

impl Drop for Children {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// A loopback address with a port nobody listens on (now).
pub fn free_port() -> SocketAddr {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
}

/// Starts `penelope ARGS` with its output discarded.
pub fn spawn(args: &[&str]) -> Child {
    Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

/// Starts `penelope ARGS` and returns it with the first stdout line containing `ready`.
pub fn start(args: &[&str], ready: &str) -> (Child, String) {
    let mut child = Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    // Bounded by the child: it either prints the line or exits (EOF).
    loop {
        line.clear();
        let n = out.read_line(&mut line).unwrap();
        assert!(n > 0, "{args:?} exited before printing {ready:?}");
        if line.contains(ready) {
            break;
        }
    }
    // Keep draining so the child never blocks on a full pipe.
    std::thread::spawn(move || std::io::copy(&mut out, &mut std::io::sink()));
    (child, line)
}

/// `penelope ctl --naming NAMING ARGS`, run to its end.
pub fn ctl(naming: SocketAddr, args: &[&str]) -> Output {
    Command::new(BIN)
        .arg("ctl")
        .arg("--naming")
        .arg(naming.to_string())
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

/// A process's stdout and stderr as text.
pub fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Writes `body` to `name` in this test process's scratch directory `penelope-TAG-PID`.
pub fn script(tag: &str, name: &str, body: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("penelope-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, body).unwrap();
    path
}
