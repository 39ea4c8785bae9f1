//! Background loads: CPU stress (stress-ng) and a competing loopback TCP flood.

use std::io::{Read, Write};
use std::net::{Ipv4Addr, TcpListener, TcpStream};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};

/// The background load of one measurement.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Load {
    /// No added load.
    Idle,
    /// `stress-ng --cpu 2` (one worker per CPU of a 2-core machine; `--cpu-workers` to change).
    Cpu,
    /// A loopback TCP flood: `--flood-streams` sender/receiver thread pairs at full speed.
    Net,
    /// `cpu` and `net` at once.
    All,
}

impl Load {
    /// The lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Load::Idle => "idle",
            Load::Cpu => "cpu",
            Load::Net => "net",
            Load::All => "all",
        }
    }

    fn cpu(self) -> bool {
        matches!(self, Load::Cpu | Load::All)
    }

    fn net(self) -> bool {
        matches!(self, Load::Net | Load::All)
    }
}

/// A running load; stopped when dropped.
pub struct Running {
    stress: Option<crate::cmd::bench::StressNg>,
    flood: Option<Flood>,
    /// What runs, for the report.
    pub description: String,
}

impl Running {
    /// Starts `load` with `cpu_workers` stress-ng CPU workers and `streams` flood streams.
    ///
    /// # Errors
    /// stress-ng missing or failing to start, sockets failing.
    pub fn start(load: Load, cpu_workers: usize, streams: usize) -> anyhow::Result<Running> {
        let mut parts = Vec::new();
        let stress = if load.cpu() {
            parts.push(format!("stress-ng --cpu {cpu_workers}"));
            Some(crate::cmd::bench::StressNg::start(
                &["--cpu", &cpu_workers.to_string()],
                Duration::from_millis(300),
            )?)
        } else {
            None
        };
        let flood = if load.net() {
            parts.push(format!(
                "loopback TCP flood, {streams} stream(s) of 64 KiB writes"
            ));
            Some(Flood::start(streams)?)
        } else {
            None
        };
        if load != Load::Idle {
            // Let the load reach its steady state.
            std::thread::sleep(Duration::from_secs(1));
        }
        Ok(Running {
            stress,
            flood,
            description: if parts.is_empty() {
                "none".into()
            } else {
                parts.join(" + ")
            },
        })
    }

    /// Stops the load; the flood's average rate, bytes/s, if one ran.
    pub fn stop(mut self) -> Option<f64> {
        self.stress.take();
        self.flood.take().map(Flood::stop)
    }
}

/// Checks that the tools `load` needs are installed, before anything is measured.
///
/// # Errors
/// stress-ng missing, with how to install it.
pub fn check(load: Load) -> anyhow::Result<()> {
    if load.cpu() {
        let ok = Command::new("stress-ng")
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            bail!(
                "--load {} needs stress-ng, which is not installed: `sudo apt-get install -y stress-ng` \
                 (or choose --load idle or net)",
                load.name()
            );
        }
    }
    Ok(())
}

/// Sender and receiver threads blasting TCP over loopback.
struct Flood {
    stop: Arc<AtomicBool>,
    bytes: Arc<AtomicU64>,
    started: Instant,
    threads: Vec<JoinHandle<()>>,
}

impl Flood {
    fn start(streams: usize) -> anyhow::Result<Flood> {
        let stop = Arc::new(AtomicBool::new(false));
        let bytes = Arc::new(AtomicU64::new(0));
        let mut threads = Vec::new();
        for i in 0..streams {
            let listener = TcpListener::bind((Ipv4Addr::LOCALHOST, 0)).context("flood listener")?;
            let addr = listener.local_addr()?;
            let counted = bytes.clone();
            threads.push(
                std::thread::Builder::new()
                    .name(format!("flood-rx-{i}"))
                    .spawn(move || {
                        let Ok((mut s, _)) = listener.accept() else {
                            return;
                        };
                        let mut buf = vec![0u8; 64 * 1024];
                        while let Ok(n) = s.read(&mut buf) {
                            if n == 0 {
                                return;
                            }
                            counted.fetch_add(n as u64, Ordering::Relaxed);
                        }
                    })?,
            );
            let mut tx = TcpStream::connect(addr).context("flood connect")?;
            let stopping = stop.clone();
            threads.push(
                std::thread::Builder::new()
                    .name(format!("flood-tx-{i}"))
                    .spawn(move || {
                        let chunk = vec![0xa5u8; 64 * 1024];
                        while !stopping.load(Ordering::Relaxed) {
                            if tx.write_all(&chunk).is_err() {
                                return;
                            }
                        }
                    })?,
            );
        }
        Ok(Flood {
            stop,
            bytes,
            started: Instant::now(),
            threads,
        })
    }

    fn stop(mut self) -> f64 {
        self.halt();
        self.bytes.load(Ordering::Relaxed) as f64 / self.started.elapsed().as_secs_f64()
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

impl Drop for Flood {
    fn drop(&mut self) {
        self.halt();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_moves_bytes_and_stops() {
        let flood = Flood::start(1).unwrap();
        std::thread::sleep(Duration::from_millis(100));
        assert!(flood.stop() > 0.0);
    }
}
