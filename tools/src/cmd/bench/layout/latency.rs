//! End-to-end latencies read off a run's recordings (the supervisor's
//! [`runs::latency`](penelope_supervisor::runs::latency), shared with the demo's report), and the
//! raw UDP echo they are judged against. The hosts of `penelope bench layout` are namespaces of
//! one machine, so both sides' times are on one clock.

use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use penelope_runtime::dataplane::endpoint::{
    ControlBuffer, enable_kernel_stamps, receive_with_stamp,
};
pub use penelope_supervisor::runs::latency::{EndToEnd, Percentiles, end_to_end};

/// A raw UDP echo: the baseline of the data plane's one-way trip. The server stamps each
/// datagram's arrival as the kernel saw it (`SO_TIMESTAMPNS`) and sends it back in the answer,
/// so the client measures exactly what the data plane's trips measure: from the clock read
/// before the send to the kernel's arrival stamp, on the machine's one clock (the hosts are
/// namespaces of one machine), without authentication, encoding or a communication thread.
pub struct Echo {
    stop: Arc<AtomicBool>,
}

/// The echo's threads' SCHED_FIFO priority: that of the nodes' communication threads (the
/// demo's control priority 80, less 10), so the baseline is as favoured as what it judges.
pub const ECHO_PRIORITY: u8 = 70;

/// The size of an echo datagram: about a data-plane sample's (header, pose, wrench, tag).
pub const ECHO_BYTES: usize = 200;

/// `CLOCK_REALTIME` now, ns (the clock of the kernel's receive stamps).
fn realtime_ns() -> i64 {
    nix::time::clock_gettime(nix::time::ClockId::CLOCK_REALTIME)
        .map(|t| t.tv_sec() * 1_000_000_000 + t.tv_nsec())
        .unwrap_or(0)
}

impl Echo {
    /// An echo server on `socket` (bound on one host) until the returned handle is dropped.
    ///
    /// # Errors
    /// When the socket cannot be set up.
    pub fn serve(socket: UdpSocket) -> std::io::Result<Echo> {
        socket.set_read_timeout(Some(Duration::from_millis(100)))?;
        enable_kernel_stamps(&socket)?;
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        std::thread::spawn(move || {
            let _ = penelope_rt_core::exec::set_fifo(ECHO_PRIORITY);
            let mut buf = [0u8; 2048];
            let mut control = ControlBuffer::default();
            while !flag.load(Ordering::Relaxed) {
                if let Ok((n, from, Some(stamp))) =
                    receive_with_stamp(&socket, &mut buf, &mut control)
                    && n >= 24
                {
                    buf[16..24].copy_from_slice(&stamp.to_le_bytes());
                    let _ = socket.send_to(&buf[..n], from);
                }
            }
        });
        Ok(Echo { stop })
    }
}

impl Drop for Echo {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// One-way trips, µs, of `count` echoes to `server` from `socket`, one every `every` (from the
/// clock read before each send to the server's kernel stamp); echoes lost (no answer within
/// 100 ms) are counted in the second value. The calling thread takes [`ECHO_PRIORITY`].
///
/// # Errors
/// When the socket cannot be set up.
pub fn ping(
    socket: &UdpSocket,
    server: SocketAddr,
    count: usize,
    every: Duration,
) -> std::io::Result<(Vec<f64>, usize)> {
    socket.set_read_timeout(Some(Duration::from_millis(100)))?;
    // (Without the right to, it runs at normal priority, as would the nodes.)
    let _ = penelope_rt_core::exec::set_fifo(ECHO_PRIORITY);
    let mut out = Vec::with_capacity(count);
    let mut lost = 0;
    let mut buf = [0u8; 2048];
    let mut payload = [0u8; ECHO_BYTES];
    for k in 0..count {
        let started = Instant::now();
        payload[..8].copy_from_slice(&(k as u64).to_le_bytes());
        let sent_ns = realtime_ns();
        payload[8..16].copy_from_slice(&sent_ns.to_le_bytes());
        socket.send_to(&payload, server)?;
        // Answers to earlier (lost, late) echoes are skipped: only this one's counts.
        let arrived = loop {
            match socket.recv_from(&mut buf) {
                Ok((n, _)) if n >= 24 && buf[..8] == payload[..8] => {
                    let mut stamp = [0u8; 8];
                    stamp.copy_from_slice(&buf[16..24]);
                    break Some(i64::from_le_bytes(stamp));
                }
                Ok(_) => continue,
                Err(_) => break None,
            }
        };
        match arrived {
            Some(stamp) => out.push((stamp - sent_ns) as f64 / 1e3),
            None => lost += 1,
        }
        std::thread::sleep(every.saturating_sub(started.elapsed()));
    }
    Ok((out, lost))
}
