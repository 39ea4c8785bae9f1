//! End-to-end latencies read off a run's recordings, and the raw UDP echo they are judged
//! against.
//!
//! Both directions are found by matching what one side received to what the other side
//! measured, exactly (up to rounding), so no clock offset or model enters: the slave's
//! reference moves by the master's tool motion times the scale (rotation keeps lengths), and
//! the master's commanded force is the slave's sensed force times the force gain. The hosts of
//! `penelope bench layout` are namespaces of one machine, so both sides' times are on one
//! clock.

use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use nalgebra::Vector3;
use penelope_hal::Timestamp;
use penelope_runtime::dataplane::endpoint::{
    ControlBuffer, enable_kernel_stamps, receive_with_stamp,
};
use penelope_runtime::objects::tick::TickRecord;
use penelope_supervisor::runs::RunOutput;
use serde::Serialize;

/// How far back a match is looked for.
const WINDOW: Duration = Duration::from_millis(200);
/// Master samples a slave may have missed between two it took (newest wins).
const SKIPPED: usize = 12;
/// Relative tolerance of a match (rounding, not physics).
const MATCH: f64 = 1e-9;

/// Percentiles of a set of latencies, µs.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Percentiles {
    /// Median.
    pub p50_us: f64,
    /// 90th percentile.
    pub p90_us: f64,
    /// 99th percentile.
    pub p99_us: f64,
    /// Largest.
    pub max_us: f64,
    /// Values.
    pub samples: usize,
}

impl Percentiles {
    /// Of `values` (µs); zeros when there are none.
    pub fn of(mut values: Vec<f64>) -> Percentiles {
        values.retain(|v| v.is_finite());
        values.sort_by(f64::total_cmp);
        let at = |p: f64| {
            if values.is_empty() {
                return 0.0;
            }
            values[((values.len() - 1) as f64 * p).round() as usize]
        };
        Percentiles {
            p50_us: at(0.5),
            p90_us: at(0.9),
            p99_us: at(0.99),
            max_us: at(1.0),
            samples: values.len(),
        }
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= MATCH * a.abs().max(b.abs()) + 1e-15
}

fn us(later: Timestamp, earlier: Timestamp) -> f64 {
    later.saturating_since(earlier).as_secs_f64() * 1e6
}

/// The ticks of `ticks` (in time order) from [`WINDOW`] before `to` up to `to`.
fn window(ticks: &[TickRecord], to: Timestamp) -> &[TickRecord] {
    let from = Timestamp::from_nanos(to.as_nanos().saturating_sub(WINDOW.as_nanos() as u64));
    let a = ticks.partition_point(|t| t.sample.time < from);
    let b = ticks.partition_point(|t| t.sample.time <= to);
    &ticks[a..b.max(a)]
}

/// Master motion to slave command, µs: for each new slave reference, the time since the master
/// control tick that measured the pose it was made from.
pub fn motion_to_command(out: &RunOutput) -> Vec<f64> {
    let scale = out.info.mapping.scale;
    let mut latencies = Vec::new();
    let slave = &out.slave;
    for k in 1..slave.len() {
        let (prev, now) = (&slave[k - 1].sample, &slave[k].sample);
        let step: Vector3<f64> = now.reference_position - prev.reference_position;
        let moved = step.norm() / scale;
        // A new sample that moved the reference measurably (at rest, motions do not identify
        // their sample).
        if moved < 1e-6 {
            continue;
        }
        let master = window(&out.master, now.time);
        // The latest master tick whose motion since an earlier one equals the step.
        let found = (1..master.len()).rev().find(|&j| {
            let p = master[j].sample.tool_position;
            (j.saturating_sub(SKIPPED)..j)
                .any(|i| close((p - master[i].sample.tool_position).norm(), moved))
        });
        if let Some(j) = found {
            latencies.push(us(now.time, master[j].sample.time));
        }
    }
    latencies
}

/// Slave contact to master force, µs: for each new force the master commands in contact, the
/// time since the slave control tick that sensed it.
pub fn contact_to_force(out: &RunOutput) -> Vec<f64> {
    let gain = out.info.mapping.force_gain;
    let mut latencies = Vec::new();
    let master = &out.master;
    for k in 1..master.len() {
        let (prev, now) = (&master[k - 1].sample, &master[k].sample);
        let force = now.commanded_wrench.force;
        if force.norm() < 0.5 || force == prev.commanded_wrench.force {
            continue;
        }
        let slave = window(&out.slave, now.time);
        if let Some(s) = slave
            .iter()
            .rev()
            .find(|s| close(s.sample.wrench.force.norm() * gain, force.norm()))
        {
            latencies.push(us(now.time, s.sample.time));
        }
    }
    latencies
}

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
