//! A Net F/T emulator: answers the RDT protocol on a UDP port and streams records at the box's
//! rate (up to 7 kHz), each carrying the wrench of a contact model, with what a real transducer
//! adds (a gage offset that the software bias removes, Gaussian noise, saturation at full scale)
//! and injectable faults (random loss, bursts, silence, an error status, saturation).
//!
//! ```no_run
//! use penelope_drivers::netft::emulator::{EmulatorConfig, NetFtEmulator};
//!
//! // A steady 5 N push along the sensor's z axis.
//! let emu = NetFtEmulator::spawn(EmulatorConfig::default(), |_t| [0.0, 0.0, 5.0, 0.0, 0.0, 0.0])?;
//! println!("Net F/T emulator on {}", emu.local_addr());
//! emu.faults().burst(50); // lose the next 50 records
//! # Ok::<(), std::io::Error>(())
//! ```

use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nalgebra::Vector3;
use penelope_hal::{Frame, Pose, Timestamp, Twist};
use penelope_rt_core::clock::MonotonicClock;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::wire::{Calibration, Command, REQUEST_LEN, Record, Request, Status};
use crate::sim::Interaction;
use crate::sim::environment::Environment;

/// The fastest RDT output rate of a Net F/T, Hz.
pub const MAX_RATE_HZ: f64 = 7000.0;

/// Where the emulated transducer's load comes from: the wrench (Fx, Fy, Fz in N, Tx, Ty, Tz in
/// N·m) the robot exerts on the world, in the sensor frame, at `t` since the emulator started.
pub trait ContactSource: Send + 'static {
    /// The true wrench at `t`.
    fn wrench(&mut self, t: Duration) -> [f64; 6];
}

impl<F: FnMut(Duration) -> [f64; 6] + Send + 'static> ContactSource for F {
    fn wrench(&mut self, t: Duration) -> [f64; 6] {
        (self)(t)
    }
}

/// A contact source from an environment model probed at a tool pose: the same shapes a
/// `sensor/virtual` probes, at a pose `pose` reports (the robot's tool pose and linear
/// velocity in its base frame, e.g. from an emulated board's encoders), seen by a sensor
/// mounted at `mount` in the tool frame.
pub struct ProbedContact<P> {
    environment: Environment,
    mount: Pose,
    pose: P,
}

impl<P: FnMut() -> Option<(Pose, Vector3<f64>)> + Send + 'static> ProbedContact<P> {
    /// Probes `environment` at the pose `pose` returns (`None`: no pose yet, no load).
    pub fn new(environment: Environment, mount: Pose, pose: P) -> Self {
        ProbedContact {
            environment,
            mount,
            pose,
        }
    }
}

impl<P: FnMut() -> Option<(Pose, Vector3<f64>)> + Send + 'static> ContactSource
    for ProbedContact<P>
{
    fn wrench(&mut self, _t: Duration) -> [f64; 6] {
        let Some((tool, velocity)) = (self.pose)() else {
            return [0.0; 6];
        };
        let twist = Twist {
            linear: velocity,
            angular: Vector3::zeros(),
            frame: Frame::Base,
        };
        let on_tool = self
            .environment
            .wrench_on_tool(Timestamp::ZERO, &tool, &twist);
        // The sensor reads the robot pushing on the world: the opposite of the world's push,
        // rotated into the tool frame, then moved to the sensor frame.
        let r_t = tool.rotation.inverse();
        let in_tool = penelope_hal::Wrench {
            force: -(r_t * on_tool.force),
            torque: -(r_t * on_tool.torque),
            frame: Frame::Tool,
        };
        let s = in_tool.expressed_in(&self.mount, Frame::Sensor).to_vector();
        [s[0], s[1], s[2], s[3], s[4], s[5]]
    }
}

/// The tool pose and linear velocity (base frame) of a robot whose joints are the axes of an
/// emulated Galil DMC, read from its encoders as a node reads them: joint `j` is axis `j`,
/// `q = zero + counts / counts per radian` (encoder zero at `zero`, the robot's `start` pose in
/// the demos). For [`ProbedContact`], so that the sensor on an emulated arm meets the same
/// environment the operator is shown.
pub fn galil_tool_pose(
    observer: crate::galil::emulator::DmcObserver,
    model: crate::model::SerialRobotModel,
    zero: penelope_hal::JointVector,
) -> impl FnMut() -> Option<(Pose, Vector3<f64>)> + Send + 'static {
    use penelope_hal::{JacobianFrame, JointVector, Kinematics};
    move || {
        let n = model.joint_count();
        let (mut q, mut qd) = (zero, JointVector::zeros());
        let complete = observer.inspect(|dmc| {
            for j in 0..n {
                let Some(a) = dmc.axis(j) else { return false };
                let cpr = model.counts_per_radian(j);
                q[j] = zero[j] + a.position / cpr;
                qd[j] = a.velocity / cpr;
            }
            true
        });
        if !complete {
            return None;
        }
        let pose = model.forward(&q);
        let v = model.jacobian(&q, JacobianFrame::Base) * qd;
        Some((pose, Vector3::new(v[0], v[1], v[2])))
    }
}

/// Settings of a [`NetFtEmulator`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmulatorConfig {
    /// Where to answer (loopback, any free port by default).
    pub bind: SocketAddr,
    /// RDT output rate, Hz (clamped to 1..=[`MAX_RATE_HZ`]).
    pub rate_hz: f64,
    /// Counts per N and per N·m.
    pub calibration: Calibration,
    /// The unloaded transducer's offset (N, N·m), removed by a software bias.
    pub offset: [f64; 6],
    /// Noise standard deviation: force (N), torque (N·m).
    pub noise: [f64; 2],
    /// Full scale: force (N), torque (N·m); beyond it the record is clipped and flagged.
    pub full_scale: [f64; 2],
    /// Internal samples per record (how much `ft_sequence` advances per record).
    pub oversampling: u32,
    /// Seed of the noise and of random loss.
    pub seed: u64,
}

impl Default for EmulatorConfig {
    /// A Mini45-like transducer (290 N, 10 N·m) at 1 kHz on loopback, a small offset, low noise.
    fn default() -> Self {
        EmulatorConfig {
            bind: ([127, 0, 0, 1], 0).into(),
            rate_hz: 1000.0,
            calibration: Calibration::default(),
            offset: [0.3, -0.2, 0.5, 0.01, -0.005, 0.002],
            noise: [0.02, 0.0005],
            full_scale: [290.0, 10.0],
            oversampling: 7,
            seed: 1,
        }
    }
}

/// Faults to inject into a running emulator; every setter takes effect at the next record.
#[derive(Debug, Default)]
pub struct Faults {
    burst: AtomicU32,
    loss_ppm: AtomicU32,
    silent: AtomicBool,
    status: AtomicU32,
    saturate: AtomicBool,
    injected_at: AtomicU64,
}

impl Faults {
    /// Drops the next `records` records (their sequence numbers are used up, as a switch
    /// dropping them would).
    pub fn burst(&self, records: u32) {
        self.mark();
        self.burst.store(records, Ordering::Relaxed);
    }

    /// Drops each record with probability `p` (0..=1), seeded.
    pub fn random_loss(&self, p: f64) {
        self.mark();
        let ppm = (p.clamp(0.0, 1.0) * 1e6).round() as u32;
        self.loss_ppm.store(ppm, Ordering::Relaxed);
    }

    /// Stops sending (`true`) or resumes (`false`) without being told to: a pulled cable.
    pub fn silence(&self, silent: bool) {
        self.mark();
        self.silent.store(silent, Ordering::Relaxed);
    }

    /// Sends `status` in every record (0: healthy again).
    pub fn status(&self, status: u32) {
        self.mark();
        self.status.store(status, Ordering::Relaxed);
    }

    /// Saturates every channel at full scale, with the out-of-range status bits.
    pub fn saturate(&self, on: bool) {
        self.mark();
        self.saturate.store(on, Ordering::Relaxed);
    }

    /// Clears every fault.
    pub fn clear(&self) {
        self.burst.store(0, Ordering::Relaxed);
        self.loss_ppm.store(0, Ordering::Relaxed);
        self.silent.store(false, Ordering::Relaxed);
        self.status.store(0, Ordering::Relaxed);
        self.saturate.store(false, Ordering::Relaxed);
    }

    /// When the last fault was injected (`CLOCK_MONOTONIC`), if any was.
    pub fn injected_at(&self) -> Option<Timestamp> {
        match self.injected_at.load(Ordering::Relaxed) {
            0 => None,
            ns => Some(Timestamp::from_nanos(ns)),
        }
    }

    fn mark(&self) {
        self.injected_at
            .store(MonotonicClock::read().as_nanos().max(1), Ordering::Relaxed);
    }
}

/// What the emulator did, so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct EmulatorCounters {
    /// Records sent.
    pub sent: u64,
    /// Records dropped by an injected fault.
    pub dropped: u64,
    /// Requests received and understood.
    pub requests: u64,
    /// Datagrams received that were not a request.
    pub bad_requests: u64,
    /// Software biases taken.
    pub biases: u64,
    /// Whether it is streaming now.
    pub streaming: bool,
}

#[derive(Debug, Default)]
struct Shared {
    stop: AtomicBool,
    sent: AtomicU64,
    dropped: AtomicU64,
    requests: AtomicU64,
    bad_requests: AtomicU64,
    biases: AtomicU64,
    streaming: AtomicBool,
    /// The last true force's magnitude, in µN (what the contact model gave, before noise).
    force_micro_n: AtomicU64,
}

/// A running emulator; dropping it stops it.
pub struct NetFtEmulator {
    local: SocketAddr,
    shared: Arc<Shared>,
    faults: Arc<Faults>,
    thread: Option<JoinHandle<()>>,
}

impl NetFtEmulator {
    /// Binds `config.bind` and serves the RDT protocol from a thread, loading the transducer
    /// with `source`.
    ///
    /// # Errors
    /// The bind error, or the thread's spawn error.
    pub fn spawn(config: EmulatorConfig, source: impl ContactSource) -> io::Result<Self> {
        let socket = UdpSocket::bind(config.bind)?;
        socket.set_nonblocking(true)?;
        let local = socket.local_addr()?;
        let shared = Arc::new(Shared::default());
        let faults = Arc::new(Faults::default());
        let mut server = Server {
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            config: EmulatorConfig {
                rate_hz: config.rate_hz.clamp(1.0, MAX_RATE_HZ),
                ..config
            },
            socket,
            shared: shared.clone(),
            faults: faults.clone(),
            source: Box::new(source),
            client: None,
            remaining: None,
            bias: [0.0; 6],
            rdt_sequence: 0,
            ft_sequence: 0,
            started: Instant::now(),
        };
        let thread = std::thread::Builder::new()
            .name("netft-sim".into())
            .spawn(move || server.run())?;
        Ok(NetFtEmulator {
            local,
            shared,
            faults,
            thread: Some(thread),
        })
    }

    /// The address it answers at.
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }

    /// Its fault injector.
    pub fn faults(&self) -> &Faults {
        &self.faults
    }

    /// Its counters.
    pub fn counters(&self) -> EmulatorCounters {
        let s = &self.shared;
        EmulatorCounters {
            sent: s.sent.load(Ordering::Relaxed),
            dropped: s.dropped.load(Ordering::Relaxed),
            requests: s.requests.load(Ordering::Relaxed),
            bad_requests: s.bad_requests.load(Ordering::Relaxed),
            biases: s.biases.load(Ordering::Relaxed),
            streaming: s.streaming.load(Ordering::Relaxed),
        }
    }

    /// The magnitude of the last true force the contact model gave, N.
    pub fn true_force_n(&self) -> f64 {
        self.shared.force_micro_n.load(Ordering::Relaxed) as f64 * 1e-6
    }

    /// Whether the server thread runs.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Stops the server.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for NetFtEmulator {
    fn drop(&mut self) {
        self.halt();
    }
}

struct Server {
    config: EmulatorConfig,
    socket: UdpSocket,
    shared: Arc<Shared>,
    faults: Arc<Faults>,
    source: Box<dyn ContactSource>,
    rng: ChaCha8Rng,
    client: Option<SocketAddr>,
    remaining: Option<u32>,
    bias: [f64; 6],
    rdt_sequence: u32,
    ft_sequence: u32,
    started: Instant,
}

/// The most records sent in one catch-up after the thread was late (a real box does not
/// queue a backlog either).
const MAX_CATCH_UP: u64 = 16;

impl Server {
    fn run(&mut self) {
        let period = Duration::from_secs_f64(1.0 / self.config.rate_hz);
        let mut epoch = Instant::now();
        let mut due: u64 = 0;
        while !self.shared.stop.load(Ordering::Relaxed) {
            self.serve_requests(&mut epoch, &mut due);
            if self.client.is_none() {
                std::thread::sleep(Duration::from_micros(500));
                continue;
            }
            // Records due by now on the absolute schedule; a late wake sends the backlog, up
            // to a bound, so the rate holds on a busy host.
            let elapsed = epoch.elapsed().as_secs_f64();
            let target = (elapsed * self.config.rate_hz) as u64 + 1;
            if target.saturating_sub(due) > MAX_CATCH_UP {
                due = target - MAX_CATCH_UP;
            }
            while due < target && self.client.is_some() {
                self.send_record();
                due += 1;
            }
            let next = epoch + period.mul_f64(due as f64);
            let now = Instant::now();
            if next > now {
                std::thread::sleep((next - now).min(Duration::from_millis(1)));
            }
        }
    }

    fn serve_requests(&mut self, epoch: &mut Instant, due: &mut u64) {
        let mut buf = [0u8; 64];
        // Bounded: a flood of requests cannot starve the stream.
        for _ in 0..32 {
            let (n, from) = match self.socket.recv_from(&mut buf) {
                Ok(x) => x,
                Err(_) => return,
            };
            let request = match Request::decode(&buf[..n.min(64)]) {
                Ok(r) if n == REQUEST_LEN => r,
                _ => {
                    self.shared.bad_requests.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
            };
            self.shared.requests.fetch_add(1, Ordering::Relaxed);
            match request.command {
                Command::Stop => {
                    self.client = None;
                    self.shared.streaming.store(false, Ordering::Relaxed);
                }
                Command::StartRealtime | Command::StartBuffered | Command::StartMultiUnit => {
                    if self.client != Some(from) {
                        *epoch = Instant::now();
                        *due = 0;
                    }
                    self.client = Some(from);
                    self.remaining = (request.sample_count > 0).then_some(request.sample_count);
                    self.shared.streaming.store(true, Ordering::Relaxed);
                }
                Command::SetSoftwareBias => {
                    let raw = self.raw(self.started.elapsed());
                    self.bias = raw;
                    self.shared.biases.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    }

    fn gaussian(&mut self) -> f64 {
        let u1: f64 = self.rng.random::<f64>().max(f64::MIN_POSITIVE);
        let u2: f64 = self.rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (2.0 * core::f64::consts::PI * u2).cos()
    }

    /// The transducer's raw output at `t`: load + offset + noise.
    fn raw(&mut self, t: Duration) -> [f64; 6] {
        let load = self.source.wrench(t);
        let force = (load[0] * load[0] + load[1] * load[1] + load[2] * load[2]).sqrt();
        self.shared
            .force_micro_n
            .store((force * 1e6).min(1e15) as u64, Ordering::Relaxed);
        let mut out = [0.0; 6];
        for (i, o) in out.iter_mut().enumerate() {
            let sigma = self.config.noise[usize::from(i >= 3)];
            let l = if load[i].is_finite() { load[i] } else { 0.0 };
            *o = l + self.config.offset[i] + sigma * self.gaussian();
        }
        out
    }

    fn send_record(&mut self) {
        let t = self.started.elapsed();
        let raw = self.raw(t);
        self.rdt_sequence = self.rdt_sequence.wrapping_add(1);
        self.ft_sequence = self.ft_sequence.wrapping_add(self.config.oversampling);
        let mut status = self.faults.status.load(Ordering::Relaxed);
        let mut values = [0.0; 6];
        let forced = self.faults.saturate.load(Ordering::Relaxed);
        for (i, v) in values.iter_mut().enumerate() {
            let scale = self.config.full_scale[usize::from(i >= 3)];
            let x = raw[i] - self.bias[i];
            if forced || x.abs() > scale {
                status |= Status::ERROR | Status::FT_OUT_OF_RANGE;
                *v = if forced {
                    scale
                } else {
                    x.clamp(-scale, scale)
                };
            } else {
                *v = x;
            }
        }
        let record = Record {
            rdt_sequence: self.rdt_sequence,
            ft_sequence: self.ft_sequence,
            status: Status(status),
            counts: self.config.calibration.to_counts(&values),
        };
        let Some(to) = self.client else { return };
        if let Some(left) = self.remaining.as_mut() {
            *left -= 1;
            if *left == 0 {
                self.client = None;
                self.remaining = None;
                self.shared.streaming.store(false, Ordering::Relaxed);
            }
        }
        if self.lose() {
            self.shared.dropped.fetch_add(1, Ordering::Relaxed);
            return;
        }
        if self.socket.send_to(&record.encode(), to).is_ok() {
            self.shared.sent.fetch_add(1, Ordering::Relaxed);
        }
    }

    fn lose(&mut self) -> bool {
        if self.faults.silent.load(Ordering::Relaxed) {
            return true;
        }
        let burst = self.faults.burst.load(Ordering::Relaxed);
        if burst > 0 {
            self.faults.burst.store(burst - 1, Ordering::Relaxed);
            return true;
        }
        let ppm = self.faults.loss_ppm.load(Ordering::Relaxed);
        ppm > 0 && self.rng.random_range(0..1_000_000u32) < ppm
    }
}
