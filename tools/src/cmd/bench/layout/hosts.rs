//! Hosts made of Linux network namespaces: each host a namespace with its own address on one
//! private subnet, all joined by veth pairs to a bridge in a namespace of its own (the
//! "switch"), so that processes on different hosts talk over real interfaces and nothing leaves
//! the machine. Everything is removed when the [`Hosts`] is dropped, also after a failure or a
//! panic; processes started on the hosts are killed first.

use std::collections::VecDeque;
use std::io::{BufRead, BufReader};
use std::net::{IpAddr, Ipv4Addr};
use std::os::fd::AsFd;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};

/// The hosts' subnet: host `i` is `10.77.0.(i+1)/24`.
const SUBNET: [u8; 3] = [10, 77, 0];

/// Distinguishes the namespaces of several `Hosts` in one process.
static NEXT: AtomicU32 = AtomicU32::new(0);

/// Network namespaces standing for hosts.
pub struct Hosts {
    names: Vec<String>,
    switch: String,
    processes: Vec<Process>,
}

/// A process started on a host.
pub struct Process {
    /// What it is, for messages.
    pub label: String,
    child: Child,
    /// The last lines of its standard error (read all along, so a chatty process never blocks
    /// on a full pipe).
    stderr: Arc<Mutex<VecDeque<String>>>,
}

/// Lines of a process's standard error kept for messages.
const STDERR_LINES: usize = 12;

fn ip(args: &[&str]) -> anyhow::Result<()> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .context("running `ip` (iproute2): install it (apt-get install iproute2)")?;
    if !out.status.success() {
        bail!(
            "`ip {}` failed: {} (creating network namespaces needs root)",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(())
}

impl Hosts {
    /// Creates `count` hosts (1 to 8) joined by a bridge.
    ///
    /// # Errors
    /// When `ip` is missing or refuses (not root): the caller fails loudly.
    pub fn create(count: usize) -> anyhow::Result<Hosts> {
        if !(1..=8).contains(&count) {
            bail!("{count} hosts: between 1 and 8");
        }
        let tag = format!(
            "pen{}x{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        );
        let mut hosts = Hosts {
            names: Vec::new(),
            switch: format!("{tag}-sw"),
            processes: Vec::new(),
        };
        // From here on, Drop removes whatever was made.
        ip(&["netns", "add", &hosts.switch])?;
        ip(&["-n", &hosts.switch, "link", "add", "br0", "type", "bridge"])?;
        ip(&["-n", &hosts.switch, "link", "set", "br0", "up"])?;
        for i in 0..count {
            let name = format!("{tag}-h{i}");
            ip(&["netns", "add", &name])?;
            hosts.names.push(name.clone());
            let port = format!("p{i}");
            ip(&[
                "link",
                "add",
                "eth0",
                "netns",
                &name,
                "type",
                "veth",
                "peer",
                "name",
                &port,
                "netns",
                &hosts.switch,
            ])?;
            ip(&["-n", &hosts.switch, "link", "set", &port, "master", "br0"])?;
            ip(&["-n", &hosts.switch, "link", "set", &port, "up"])?;
            let addr = format!("{}/24", hosts.address(i));
            ip(&["-n", &name, "addr", "add", &addr, "dev", "eth0"])?;
            ip(&["-n", &name, "link", "set", "eth0", "up"])?;
            ip(&["-n", &name, "link", "set", "lo", "up"])?;
        }
        Ok(hosts)
    }

    /// Host `i`'s address.
    pub fn address(&self, i: usize) -> IpAddr {
        IpAddr::V4(Ipv4Addr::new(SUBNET[0], SUBNET[1], SUBNET[2], i as u8 + 1))
    }

    /// Starts `program args` on host `i` and waits (at most `deadline`) for a line of its
    /// standard output containing `ready`; the process is then kept (and killed on drop).
    ///
    /// # Errors
    /// When it cannot start, exits, or does not print `ready` in time (its standard error is
    /// in the message).
    pub fn start(
        &mut self,
        i: usize,
        label: &str,
        program: &std::path::Path,
        args: &[String],
        ready: &str,
        deadline: Duration,
    ) -> anyhow::Result<()> {
        let mut child = Command::new("ip")
            .args(["netns", "exec", &self.names[i]])
            .arg(program)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| format!("starting {label}"))?;
        let stdout = child.stdout.take().context("stdout")?;
        let tail = Arc::new(Mutex::new(VecDeque::new()));
        if let Some(err) = child.stderr.take() {
            let tail = tail.clone();
            std::thread::spawn(move || {
                for line in BufReader::new(err).lines() {
                    let Ok(line) = line else { break };
                    if let Ok(mut t) = tail.lock() {
                        if t.len() == STDERR_LINES {
                            t.pop_front();
                        }
                        t.push_back(line);
                    }
                }
            });
        }
        let stderr = tail;
        self.processes.push(Process {
            label: label.to_string(),
            child,
            stderr,
        });
        // A reader thread: the wait below is for a line, bounded by the deadline.
        let (tx, rx) = mpsc::channel();
        let want = ready.to_string();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if line.contains(&want) {
                    let _ = tx.send(());
                }
            }
        });
        let end = Instant::now() + deadline;
        loop {
            match rx.recv_timeout(Duration::from_millis(100)) {
                Ok(()) => return Ok(()),
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    let p = self.processes.last_mut().context("process")?;
                    let status = p.child.wait()?;
                    bail!("{label} exited ({status}): {}", p.take_stderr());
                }
                Err(mpsc::RecvTimeoutError::Timeout) if Instant::now() >= end => {
                    bail!("{label} did not print `{ready}` within {deadline:?}");
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
        }
    }

    /// Stops the processes, last started first: SIGTERM, then a bounded wait for each (past
    /// it, SIGKILL and an error). Their exit statuses, by label.
    ///
    /// # Errors
    /// A process that did not stop in time, or exited with a failure (its standard error in
    /// the message).
    pub fn stop_all(&mut self, deadline: Duration) -> anyhow::Result<Vec<(String, ExitStatus)>> {
        let mut statuses = Vec::new();
        let mut failures = Vec::new();
        while let Some(mut p) = self.processes.pop() {
            let pid = nix::unistd::Pid::from_raw(p.child.id() as i32);
            let _ = nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM);
            let end = Instant::now() + deadline;
            let status = loop {
                if let Some(s) = p.child.try_wait()? {
                    break Some(s);
                }
                if Instant::now() >= end {
                    let _ = p.child.kill();
                    let _ = p.child.wait();
                    break None;
                }
                std::thread::sleep(Duration::from_millis(20));
            };
            match status {
                Some(s) if s.success() => statuses.push((p.label.clone(), s)),
                Some(s) => failures.push(format!("{} exited {s}: {}", p.label, p.take_stderr())),
                None => failures.push(format!("{} did not stop within {deadline:?}", p.label)),
            }
        }
        if !failures.is_empty() {
            bail!("{}", failures.join("; "));
        }
        Ok(statuses)
    }

    /// Runs `f` on a thread inside host `i`'s namespace (sockets it makes belong to that host),
    /// and returns its result.
    ///
    /// # Errors
    /// When the namespace cannot be entered, or `f` fails.
    pub fn spawn_in<T: Send + 'static>(
        &self,
        i: usize,
        f: impl FnOnce() -> anyhow::Result<T> + Send + 'static,
    ) -> std::thread::JoinHandle<anyhow::Result<T>> {
        let path = format!("/run/netns/{}", self.names[i]);
        std::thread::spawn(move || {
            let file =
                std::fs::File::open(&path).with_context(|| format!("opening namespace {path}"))?;
            nix::sched::setns(file.as_fd(), nix::sched::CloneFlags::CLONE_NEWNET)
                .with_context(|| format!("entering namespace {path}"))?;
            f()
        })
    }
}

impl Process {
    fn take_stderr(&self) -> String {
        self.stderr
            .lock()
            .map(|t| t.iter().cloned().collect::<Vec<_>>().join(" | "))
            .unwrap_or_default()
    }
}

impl Drop for Hosts {
    fn drop(&mut self) {
        for p in &mut self.processes {
            let _ = p.child.kill();
            let _ = p.child.wait();
        }
        // Deleting a namespace deletes its end of each veth pair, and so the pair.
        for name in self.names.iter().chain(std::iter::once(&self.switch)) {
            let _ = Command::new("ip")
                .args(["netns", "del", name])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .status();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listed() -> String {
        let out = Command::new("ip").args(["netns", "list"]).output().unwrap();
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    #[test]
    fn hosts_reach_each_other_and_everything_goes_when_a_start_fails() {
        let mut hosts = Hosts::create(2).expect("namespaces (needs root and iproute2)");
        let names = hosts.names.clone();
        // A datagram from host 0 to host 1 crosses the bridge.
        let b = hosts.address(1);
        let server = hosts
            .spawn_in(1, move || {
                let s = std::net::UdpSocket::bind((b, 0))?;
                Ok((s.local_addr()?, s))
            })
            .join()
            .unwrap()
            .unwrap();
        let (to, socket) = server;
        let a = hosts.address(0);
        hosts
            .spawn_in(0, move || {
                let s = std::net::UdpSocket::bind((a, 0))?;
                s.send_to(b"hello", to)?;
                Ok(())
            })
            .join()
            .unwrap()
            .unwrap();
        socket
            .set_read_timeout(Some(Duration::from_secs(5)))
            .unwrap();
        let mut buf = [0u8; 16];
        let (n, from) = socket.recv_from(&mut buf).expect("the datagram arrives");
        assert_eq!(&buf[..n], b"hello");
        assert_eq!(from.ip(), a);
        // A process that exits at once is an error naming it, and dropping removes it all.
        let err = hosts
            .start(
                0,
                "false",
                std::path::Path::new("/bin/false"),
                &[],
                "never",
                Duration::from_secs(10),
            )
            .unwrap_err();
        assert!(err.to_string().contains("false exited"), "{err}");
        drop(hosts);
        let now = listed();
        for n in names {
            assert!(!now.contains(&n), "{n} is left in {now}");
        }
    }
}
