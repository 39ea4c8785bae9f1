//! The Net F/T driver: an I/O thread that owns the UDP socket, and the real-time side that
//! reads what it published.
//!
//! ```text
//!  Net F/T (UDP 49152) ──RDT records──> I/O thread ──LatestCell<NetFtSample>──> NetFtReader (control thread)
//!        ^ start / stop / bias requests     │ counters (atomics) ──> NetFt::counters (supervisor)
//!        └──────────────────────────────────┘
//! ```
//!
//! The I/O thread decodes every datagram, counts what is wrong with it (wrong size, out of
//! order, records missed by RDT sequence), applies the calibration and publishes the newest
//! sample, stamped on `CLOCK_MONOTONIC` when it arrived, to every reader's cell. A
//! [`NetFtReader`] is what a control loop holds: one wait-free cell read per call, and a typed
//! [`NetFtError`] for a silent link, an error status, saturation or a burst of loss, so the
//! loop notes a sensor error and uses no wrench (a master then displays zero force).

use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nalgebra::Vector3;
use penelope_hal::{Error, ErrorKind, ForceSensor, Frame, Pose, Sensor, Timestamp, Wrench};
use penelope_rt_core::cell::{ArcLatestReader, ArcLatestWriter, latest};
use penelope_rt_core::clock::MonotonicClock;

use super::wire::{Calibration, Command, RECORD_LEN, Record, Request, Status, records_missed};

/// A record this many or fewer behind the last one is taken as reordered (refused); further
/// behind, after a silence of at least the timeout, as the first of a restarted box's new
/// sequence (a reboot restarts the RDT sequence at 0; a network reorders by a few records).
pub const REORDER_WINDOW: u32 = 64;

/// The most readers (control loops, one at a time, and tools) one sensor feeds.
pub const MAX_READERS: usize = 4;

/// The receive buffer asked for, bytes (a loopback datagram costs about 1 KiB of it).
const RECEIVE_BUFFER: usize = 2 << 20;

/// Cells the I/O thread feeds: the owner's monitor and [`MAX_READERS`] readers.
const CELLS: usize = MAX_READERS + 1;

/// A box's RDT address as a person writes it: `ip:port`, `[v6]:port`, or an IP address
/// alone, which means the box's own port [`RDT_PORT`](super::wire::RDT_PORT) (49152). No
/// host names: resolving one could block the caller.
///
/// ```
/// use penelope_drivers::netft::sensor::parse_address;
/// assert_eq!(parse_address("192.168.1.1").unwrap().to_string(), "192.168.1.1:49152");
/// assert_eq!(parse_address("127.0.0.1:7000").unwrap().port(), 7000);
/// assert_eq!(parse_address("fe80::1").unwrap().to_string(), "[fe80::1]:49152");
/// assert!(parse_address("box.lab:49152").is_err());
/// ```
///
/// # Errors
/// [`AddressError`] saying what was expected.
pub fn parse_address(text: &str) -> Result<SocketAddr, AddressError> {
    let text = text.trim();
    if let Ok(address) = text.parse::<SocketAddr>() {
        return Ok(address);
    }
    let bare = text
        .strip_prefix('[')
        .and_then(|t| t.strip_suffix(']'))
        .unwrap_or(text);
    match bare.parse::<std::net::IpAddr>() {
        Ok(ip) => Ok(SocketAddr::new(ip, super::wire::RDT_PORT)),
        Err(_) => Err(AddressError(text.chars().take(80).collect())),
    }
}

/// An RDT address that is neither `ip:port` nor an IP address.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AddressError(String);

impl core::fmt::Display for AddressError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{:?} is not a box's address: give ip:port, or an IP address alone for port {} \
             (e.g. 192.168.1.1 or 192.168.1.1:{})",
            self.0,
            super::wire::RDT_PORT,
            super::wire::RDT_PORT
        )
    }
}

impl std::error::Error for AddressError {}

/// Settings of a [`NetFt`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NetFtConfig {
    /// The box's RDT address (port [`super::wire::RDT_PORT`] on a real box).
    pub address: SocketAddr,
    /// Counts per newton and per newton-metre (the box's `cfgcpf`, `cfgcpt`).
    pub calibration: Calibration,
    /// The sensor frame's pose in the robot's tool frame (m, rotation).
    pub mount: Pose,
    /// A reading older than this is refused ([`NetFtError::Timeout`]); the I/O thread also asks
    /// the box to stream again after this long without a record.
    pub timeout: Duration,
    /// More records missed in one gap than this is a fault ([`NetFtError::Loss`]), held for
    /// [`timeout`](Self::timeout) after the gap so that a loop reading slower than the box
    /// sends still sees it. Smaller gaps are counted only.
    pub max_gap: u32,
    /// Ask the box for a software bias once streaming starts.
    pub bias_on_start: bool,
}

impl NetFtConfig {
    /// A box at `address` with the usual calibration (1 000 000 counts per N and N·m), a
    /// 20 ms timeout and faults on gaps of more than 4 records.
    pub fn new(address: SocketAddr) -> Self {
        NetFtConfig {
            address,
            calibration: Calibration::default(),
            mount: Pose::identity(),
            timeout: Duration::from_millis(20),
            max_gap: 4,
            bias_on_start: false,
        }
    }
}

/// A fault the I/O thread attaches to a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SampleFault {
    /// The box reported an error (status bit 31), with its status word.
    Status(u32),
    /// The box reported a force, torque or gage out of range (saturated), with its status word.
    Saturated(u32),
    /// More than `max_gap` records were lost in one gap (how many).
    Loss(u32),
}

/// One decoded record, as the I/O thread publishes it.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct NetFtSample {
    /// When it arrived (`CLOCK_MONOTONIC`).
    pub stamp: Timestamp,
    /// Its RDT sequence number.
    pub rdt_sequence: u32,
    /// Its status word.
    pub status: Status,
    /// Fx, Fy, Fz (N), Tx, Ty, Tz (N·m) in the sensor frame, calibrated.
    pub values: [f64; 6],
    /// A fault in force at this sample.
    pub fault: Option<SampleFault>,
}

/// Why a [`NetFtReader`] has no wrench.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NetFtError {
    /// No record arrived yet.
    NoData,
    /// The newest record is older than the timeout: the stream stopped or the link is down.
    Timeout,
    /// The box reports an error (its status word).
    Status(u32),
    /// A force, torque or gage is out of range (the status word).
    Saturated(u32),
    /// A burst of lost records (how many in the gap).
    Loss(u32),
    /// A calibrated value was NaN or infinite (never passed on).
    NonFinite,
}

impl From<SampleFault> for NetFtError {
    fn from(f: SampleFault) -> Self {
        match f {
            SampleFault::Status(s) => NetFtError::Status(s),
            SampleFault::Saturated(s) => NetFtError::Saturated(s),
            SampleFault::Loss(n) => NetFtError::Loss(n),
        }
    }
}

impl Error for NetFtError {
    fn kind(&self) -> ErrorKind {
        match self {
            NetFtError::NoData | NetFtError::Timeout => ErrorKind::Timeout,
            NetFtError::Status(_) => ErrorKind::Device,
            NetFtError::Saturated(_) => ErrorKind::OutOfLimits,
            NetFtError::Loss(_) => ErrorKind::Communication,
            NetFtError::NonFinite => ErrorKind::NonFinite,
        }
    }
}

impl core::fmt::Display for NetFtError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            NetFtError::NoData => f.write_str("no record from the Net F/T yet"),
            NetFtError::Timeout => f.write_str("the Net F/T stream timed out"),
            NetFtError::Status(s) => write!(f, "the Net F/T reports an error (status {s:#010x})"),
            NetFtError::Saturated(s) => write!(f, "the Net F/T is saturated (status {s:#010x})"),
            NetFtError::Loss(n) => write!(f, "{n} Net F/T records lost in one gap"),
            NetFtError::NonFinite => f.write_str("a Net F/T value is NaN or infinite"),
        }
    }
}

impl std::error::Error for NetFtError {}

/// The I/O thread's counters, shared with its owner.
#[derive(Debug, Default)]
struct Counters {
    datagrams: AtomicU64,
    records: AtomicU64,
    malformed: AtomicU64,
    out_of_order: AtomicU64,
    restarts: AtomicU64,
    missed: AtomicU64,
    gaps: AtomicU64,
    loss_faults: AtomicU64,
    status_errors: AtomicU64,
    saturated: AtomicU64,
    timeouts: AtomicU64,
    requests: AtomicU64,
    biases: AtomicU64,
}

/// A snapshot of a sensor's counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct NetFtCounters {
    /// Datagrams received.
    pub datagrams: u64,
    /// Good records published.
    pub records: u64,
    /// Datagrams that were not a record (wrong size), refused.
    pub malformed: u64,
    /// Records older than or equal to the last one (duplicated or reordered), refused.
    pub out_of_order: u64,
    /// Sequences restarted (the box rebooted: a large backward jump after a silence), each
    /// taken as the new sequence at once.
    pub restarts: u64,
    /// Records missed, by RDT sequence number.
    pub missed: u64,
    /// Gaps in the sequence (bursts of one or more missed records).
    pub gaps: u64,
    /// Gaps longer than `max_gap`: loss faults.
    pub loss_faults: u64,
    /// Records with the error bit set.
    pub status_errors: u64,
    /// Records with a saturation bit set.
    pub saturated: u64,
    /// Silences longer than the timeout (each one counted once).
    pub timeouts: u64,
    /// Requests sent (start, stop, bias).
    pub requests: u64,
    /// Software biases requested.
    pub biases: u64,
}

impl Counters {
    fn snapshot(&self) -> NetFtCounters {
        let g = |a: &AtomicU64| a.load(Ordering::Relaxed);
        NetFtCounters {
            datagrams: g(&self.datagrams),
            records: g(&self.records),
            malformed: g(&self.malformed),
            out_of_order: g(&self.out_of_order),
            restarts: g(&self.restarts),
            missed: g(&self.missed),
            gaps: g(&self.gaps),
            loss_faults: g(&self.loss_faults),
            status_errors: g(&self.status_errors),
            saturated: g(&self.saturated),
            timeouts: g(&self.timeouts),
            requests: g(&self.requests),
            biases: g(&self.biases),
        }
    }
}

fn bump(a: &AtomicU64) {
    a.fetch_add(1, Ordering::Relaxed);
}

/// A Net F/T being streamed: owns the I/O thread; dropping it stops the stream.
pub struct NetFt {
    config: NetFtConfig,
    local: SocketAddr,
    counters: Arc<Counters>,
    stop: Arc<AtomicBool>,
    bias: Arc<AtomicBool>,
    readers: Sender<ArcLatestWriter<NetFtSample>>,
    /// The owner's own reader (slot 0 of the I/O thread's cells, never replaced), for tools and
    /// `describe`: behind a lock, since it is read from non-real-time threads only.
    monitor: std::sync::Mutex<NetFtReader>,
    thread: Option<JoinHandle<()>>,
}

impl NetFt {
    /// Binds a UDP socket, asks the box at `config.address` to stream, and starts the I/O
    /// thread.
    ///
    /// # Errors
    /// The socket's bind or connect error, or the thread's spawn error.
    pub fn open(config: NetFtConfig) -> io::Result<NetFt> {
        if !config.calibration.is_valid() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "counts per force and per torque must be finite and positive",
            ));
        }
        let bind: SocketAddr = if config.address.is_ipv4() {
            ([0, 0, 0, 0], 0).into()
        } else {
            (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
        };
        let socket = UdpSocket::bind(bind)?;
        // Room for a quarter second at 7 kHz, so that a descheduled I/O thread (a busy host)
        // loses nothing; the kernel may cap it (net.core.rmem_max), which only costs headroom.
        let _ = nix::sys::socket::setsockopt(
            &socket,
            nix::sys::socket::sockopt::RcvBuf,
            &RECEIVE_BUFFER,
        );
        socket.connect(config.address)?;
        // Short enough to notice a stop or a bias request promptly, long enough not to spin.
        socket.set_read_timeout(Some(
            (config.timeout / 4).clamp(Duration::from_millis(1), Duration::from_millis(10)),
        ))?;
        let local = socket.local_addr()?;
        let counters = Arc::new(Counters::default());
        let stop = Arc::new(AtomicBool::new(false));
        let bias = Arc::new(AtomicBool::new(config.bias_on_start));
        let (readers, new_readers) = channel();
        let (monitor_writer, monitor) = latest();
        let mut writers = heapless::Vec::new();
        let _ = writers.push(monitor_writer);
        let io = IoThread {
            config,
            socket,
            counters: counters.clone(),
            stop: stop.clone(),
            bias: bias.clone(),
            new_readers,
            writers,
            last_sequence: None,
            last_good: None,
            loss_until: None,
        };
        let thread = std::thread::Builder::new()
            .name("netft-io".into())
            .spawn(move || io.run())?;
        Ok(NetFt {
            config,
            local,
            counters,
            stop,
            bias,
            readers,
            monitor: std::sync::Mutex::new(NetFtReader {
                cell: monitor,
                timeout: config.timeout,
                mount: config.mount,
                tare: [0.0; 6],
                last: None,
            }),
            thread: Some(thread),
        })
    }

    /// The newest sample as published, unchecked (for tools and `describe`; a control loop
    /// holds its own [`reader`](Self::reader)).
    pub fn latest(&self) -> Option<NetFtSample> {
        self.monitor
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .sample()
    }

    /// The newest wrench, checked as a loop would check it at `now` (for tools).
    ///
    /// # Errors
    /// As [`NetFtReader::read`].
    pub fn read(&self, now: Timestamp) -> Result<Wrench, NetFtError> {
        self.monitor
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .read(now)
    }

    /// A new reader of this sensor (call outside the control thread: it allocates a cell). The
    /// I/O thread feeds at most [`MAX_READERS`] readers besides the owner's own; a newer one
    /// replaces the oldest.
    pub fn reader(&self) -> NetFtReader {
        let (writer, reader) = latest();
        // A closed channel means the thread ended: the reader then times out, as it should.
        let _ = self.readers.send(writer);
        NetFtReader {
            cell: reader,
            timeout: self.config.timeout,
            mount: self.config.mount,
            tare: [0.0; 6],
            last: None,
        }
    }

    /// Asks the box to take its present reading as zero (its software bias), from the I/O
    /// thread at its next turn.
    pub fn request_bias(&self) {
        self.bias.store(true, Ordering::Relaxed);
    }

    /// The counters so far.
    pub fn counters(&self) -> NetFtCounters {
        self.counters.snapshot()
    }

    /// The settings.
    pub fn config(&self) -> &NetFtConfig {
        &self.config
    }

    /// The local address the stream arrives at.
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }

    /// Whether the I/O thread runs.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Waits until at least `records` good records arrived in total, polling every
    /// millisecond, for at most `within`. Returns whether they did.
    pub fn wait_for_records(&self, records: u64, within: Duration) -> bool {
        let deadline = Instant::now() + within;
        loop {
            if self.counters.records.load(Ordering::Relaxed) >= records {
                return true;
            }
            if Instant::now() >= deadline || !self.is_running() {
                return false;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Stops the stream (a stop request to the box) and the I/O thread.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for NetFt {
    fn drop(&mut self) {
        self.halt();
    }
}

impl core::fmt::Debug for NetFt {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("NetFt")
            .field("address", &self.config.address)
            .field("local", &self.local)
            .finish_non_exhaustive()
    }
}

struct IoThread {
    config: NetFtConfig,
    socket: UdpSocket,
    counters: Arc<Counters>,
    stop: Arc<AtomicBool>,
    bias: Arc<AtomicBool>,
    new_readers: Receiver<ArcLatestWriter<NetFtSample>>,
    writers: heapless::Vec<ArcLatestWriter<NetFtSample>, CELLS>,
    last_sequence: Option<u32>,
    /// When the last good record arrived (to tell a restarted box from reordering).
    last_good: Option<Timestamp>,
    loss_until: Option<(Timestamp, u32)>,
}

impl IoThread {
    fn send(&self, command: Command) {
        // A refused send (no route, the box away) shows as a timeout; the next start retries.
        let _ = self.socket.send(&Request::new(command, 0).encode());
        bump(&self.counters.requests);
        if command == Command::SetSoftwareBias {
            bump(&self.counters.biases);
        }
    }

    fn run(mut self) {
        self.send(Command::StartRealtime);
        let mut last_record = Instant::now();
        let mut timed_out = false;
        // One byte more than a record, so that a longer datagram is seen as such.
        let mut buf = [0u8; RECORD_LEN + 1];
        while !self.stop.load(Ordering::Relaxed) {
            self.take_new_readers();
            if self.bias.swap(false, Ordering::Relaxed) {
                self.send(Command::SetSoftwareBias);
            }
            // An error is a read timeout, or the box's port unreachable (ICMP on a connected
            // socket): both show as silence, handled below.
            if let Ok(n) = self.socket.recv(&mut buf) {
                bump(&self.counters.datagrams);
                if self.on_datagram(&buf[..n]) {
                    last_record = Instant::now();
                    timed_out = false;
                }
            }
            if last_record.elapsed() > self.config.timeout {
                if !timed_out {
                    bump(&self.counters.timeouts);
                    timed_out = true;
                }
                // The box may have rebooted or never heard us: ask again, once per timeout.
                self.send(Command::StartRealtime);
                last_record = Instant::now();
            }
        }
        self.send(Command::Stop);
    }

    fn take_new_readers(&mut self) {
        loop {
            match self.new_readers.try_recv() {
                Ok(w) => {
                    if self.writers.is_full() {
                        // Slot 0 is the owner's monitor: the oldest loop's reader goes.
                        self.writers.remove(1);
                    }
                    let _ = self.writers.push(w);
                }
                Err(TryRecvError::Empty | TryRecvError::Disconnected) => return,
            }
        }
    }

    /// Decodes and publishes one datagram; `true` for a good record.
    fn on_datagram(&mut self, datagram: &[u8]) -> bool {
        let Ok(record) = Record::decode(datagram) else {
            bump(&self.counters.malformed);
            return false;
        };
        let stamp = MonotonicClock::read();
        if let Some(last) = self.last_sequence {
            let step = record.rdt_sequence.wrapping_sub(last);
            let behind = last.wrapping_sub(record.rdt_sequence);
            let silence = self
                .last_good
                .map_or(Duration::MAX, |t| stamp.saturating_since(t));
            let restarted = (step == 0 || step > u32::MAX / 2)
                && behind > REORDER_WINDOW
                && silence >= self.config.timeout;
            if restarted {
                // The box rebooted: its new sequence starts here (no loss counted).
                bump(&self.counters.restarts);
            } else if step == 0 || step > u32::MAX / 2 {
                bump(&self.counters.out_of_order);
                return false;
            }
            let missed = if restarted {
                0
            } else {
                records_missed(last, record.rdt_sequence)
            };
            if missed > 0 {
                self.counters
                    .missed
                    .fetch_add(u64::from(missed), Ordering::Relaxed);
                bump(&self.counters.gaps);
                if missed > self.config.max_gap {
                    bump(&self.counters.loss_faults);
                    self.loss_until = Some((stamp + self.config.timeout, missed));
                }
            }
        }
        self.last_sequence = Some(record.rdt_sequence);
        self.last_good = Some(stamp);
        bump(&self.counters.records);
        let status = record.status;
        let fault = if status.is_saturated() {
            bump(&self.counters.saturated);
            Some(SampleFault::Saturated(status.0))
        } else if status.is_error() {
            bump(&self.counters.status_errors);
            Some(SampleFault::Status(status.0))
        } else {
            match self.loss_until {
                Some((until, missed)) if stamp < until => Some(SampleFault::Loss(missed)),
                _ => None,
            }
        };
        let sample = NetFtSample {
            stamp,
            rdt_sequence: record.rdt_sequence,
            status,
            values: self.config.calibration.to_si(&record.counts),
            fault,
        };
        for w in self.writers.iter_mut() {
            w.write(sample);
        }
        true
    }
}

/// The real-time side of a [`NetFt`]: the newest sample, checked, as a wrench in the sensor
/// frame (the wrench the robot exerts on the world, the project's wrist-sensor sign).
#[derive(Debug)]
pub struct NetFtReader {
    cell: ArcLatestReader<NetFtSample>,
    timeout: Duration,
    mount: Pose,
    tare: [f64; 6],
    last: Option<NetFtSample>,
}

impl NetFtReader {
    /// The newest sample as published, unchecked (for tools and telemetry).
    ///
    /// # Real-time
    /// Wait-free, no allocation.
    pub fn sample(&mut self) -> Option<NetFtSample> {
        if let Some(s) = self.cell.latest() {
            self.last = Some(s);
        }
        self.last
    }
}

impl Sensor for NetFtReader {
    type Error = NetFtError;
    type Reading = Wrench;

    /// The newest wrench, if it is younger than the timeout and carries no fault.
    ///
    /// # Real-time
    /// One wait-free cell read, no allocation, no system call, constant time.
    fn read(&mut self, now: Timestamp) -> Result<Wrench, NetFtError> {
        let s = self.sample().ok_or(NetFtError::NoData)?;
        if now.saturating_since(s.stamp) > self.timeout {
            return Err(NetFtError::Timeout);
        }
        if let Some(f) = s.fault {
            return Err(f.into());
        }
        let v = s.values;
        let t = self.tare;
        let w = Wrench {
            force: Vector3::new(v[0] - t[0], v[1] - t[1], v[2] - t[2]),
            torque: Vector3::new(v[3] - t[3], v[4] - t[4], v[5] - t[5]),
            frame: Frame::Sensor,
        };
        if !w.is_finite() {
            return Err(NetFtError::NonFinite);
        }
        Ok(w)
    }
}

impl ForceSensor for NetFtReader {
    fn mount(&self) -> Pose {
        self.mount
    }

    /// A host-side tare (no request to the box: the control thread sends nothing); the box's
    /// own software bias is [`NetFt::request_bias`].
    fn tare(&mut self, now: Timestamp) -> Result<(), NetFtError> {
        self.tare = [0.0; 6];
        let w = self.read(now)?.to_vector();
        for (t, v) in self.tare.iter_mut().zip(w.iter()) {
            *t = *v;
        }
        Ok(())
    }
}
