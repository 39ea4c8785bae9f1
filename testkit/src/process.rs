//! `penelope` child processes.
//!
//! A test names the binary it runs (`env!("CARGO_BIN_EXE_penelope")` in the tools crate's
//! tests) once, as a [`Penelope`], and starts processes from it. A started process is waited for
//! by its ready line, never by time; [`Children`] kills whatever a test started when it ends,
//! passed or failed.

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::process::{Child, Command, Output, Stdio};

/// The `penelope` binary under test.
#[derive(Clone, Copy, Debug)]
pub struct Penelope(&'static str);

impl Penelope {
    /// The binary at `path` (a test's `env!("CARGO_BIN_EXE_penelope")`).
    pub const fn at(path: &'static str) -> Penelope {
        Penelope(path)
    }

    /// The binary's path.
    pub fn path(&self) -> &'static str {
        self.0
    }

    /// A command running the binary, to add arguments to.
    pub fn command(&self) -> Command {
        Command::new(self.0)
    }

    /// Starts `penelope ARGS` with its input and output discarded.
    pub fn spawn(&self, args: &[&str]) -> Child {
        self.command()
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("start {} {args:?}: {e}", self.0))
    }

    /// Starts `penelope ARGS` and returns it with the first line of its output that contains
    /// `ready`; the rest of its output is drained (so it never blocks on a full pipe).
    ///
    /// Panics if the process exits before printing such a line.
    pub fn start(&self, args: &[&str], ready: &str) -> (Child, String) {
        let mut child = self
            .command()
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap_or_else(|e| panic!("start {} {args:?}: {e}", self.0));
        let mut out = BufReader::new(child.stdout.take().expect("piped stdout"));
        let mut line = String::new();
        // Bounded by the child: it either prints the line or exits (end of file).
        loop {
            line.clear();
            let n = out.read_line(&mut line).expect("read the child's output");
            assert!(n > 0, "{args:?} exited before printing {ready:?}");
            if line.contains(ready) {
                break;
            }
        }
        std::thread::spawn(move || std::io::copy(&mut out, &mut std::io::sink()));
        (child, line)
    }

    /// `penelope ctl --naming NAMING ARGS`, run to its end.
    pub fn ctl(&self, naming: SocketAddr, args: &[&str]) -> Output {
        self.command()
            .arg("ctl")
            .arg("--naming")
            .arg(naming.to_string())
            .args(args)
            .stdin(Stdio::null())
            .output()
            .unwrap_or_else(|e| panic!("run {} ctl {args:?}: {e}", self.0))
    }
}

/// Child processes, killed when the test ends, passed or failed.
#[derive(Default)]
pub struct Children(pub Vec<Child>);

impl Drop for Children {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// A finished process's standard output and error as text.
pub fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    // `sh` stands in for `penelope`: what is tested is the waiting and the killing.
    const SH: Penelope = Penelope::at("/bin/sh");

    #[test]
    fn start_returns_the_ready_line_and_children_are_killed() {
        let (child, line) = SH.start(&["-c", "echo starting; echo ready at 1; sleep 60"], "ready");
        assert_eq!(line.trim(), "ready at 1");
        let pid = child.id();
        drop(Children(vec![child]));
        // Reaped by the drop: the pid names no process of ours any more.
        let status = std::fs::read_to_string(format!("/proc/{pid}/status"));
        assert!(status.is_err() || !status.unwrap().contains("State:\tS"));
    }

    #[test]
    #[should_panic(expected = "exited before printing")]
    fn a_process_that_exits_before_its_ready_line_fails_the_test() {
        SH.start(&["-c", "echo nothing"], "ready");
    }

    #[test]
    fn text_reads_both_streams() {
        let o = SH
            .command()
            .args(["-c", "echo out; echo err >&2"])
            .output()
            .unwrap();
        assert_eq!(text(&o), ("out\n".into(), "err\n".into()));
    }
}
