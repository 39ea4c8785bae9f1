//! Runs a [`Dmc`] on a pseudo-terminal: a client opens [`PtyEmulator::path`] like a serial
//! device.

use std::os::fd::{AsFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nix::errno::Errno;
use nix::fcntl::{FcntlArg, OFlag, fcntl};
use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
use nix::sys::termios::{SetArg, cfmakeraw, tcgetattr, tcsetattr};

use super::{Dmc, DmcConfig};

/// How to run the emulator.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct PtyOptions {
    /// The emulated controller.
    pub dmc: DmcConfig,
    /// Pace both directions as a serial line at this baud rate (10 bits per byte); `None` runs as
    /// fast as the pseudo-terminal goes.
    pub baud: Option<u32>,
    /// Print this unsolicited message (as a board program would) every period.
    pub unsolicited: Option<(Duration, Vec<u8>)>,
}

#[derive(Debug, Default)]
struct Shared {
    stop: AtomicBool,
    unplug: AtomicBool,
    line_closed: AtomicBool,
    bytes_in: AtomicU64,
    bytes_out: AtomicU64,
}

/// An emulated DMC on a pseudo-terminal, served by its own thread until stopped or dropped.
///
/// The controller keeps running (servo samples, programs, the arm) whether or not a host talks
/// to it, and after [`unplug`](PtyEmulator::unplug); [`inspect`](PtyEmulator::inspect) reads
/// it at any time.
#[derive(Debug)]
pub struct PtyEmulator {
    path: PathBuf,
    shared: Arc<Shared>,
    dmc: Arc<Mutex<Dmc>>,
    thread: Option<JoinHandle<()>>,
}

impl PtyEmulator {
    /// Opens a pseudo-terminal pair and starts serving it.
    ///
    /// # Errors
    /// When the operating system refuses a pseudo-terminal or a thread.
    pub fn spawn(options: PtyOptions) -> std::io::Result<PtyEmulator> {
        let pty = nix::pty::openpty(None, None).map_err(std::io::Error::from)?;
        let path = nix::unistd::ttyname(pty.slave.as_fd()).map_err(std::io::Error::from)?;
        // Raw mode on the device side: no echo, no line editing, no CR/LF translation (a client
        // such as serialport sets this too; a plain `open` would not).
        let mut t = tcgetattr(pty.slave.as_fd()).map_err(std::io::Error::from)?;
        cfmakeraw(&mut t);
        tcsetattr(pty.slave.as_fd(), SetArg::TCSANOW, &t).map_err(std::io::Error::from)?;
        fcntl(pty.master.as_fd(), FcntlArg::F_SETFL(OFlag::O_NONBLOCK))
            .map_err(std::io::Error::from)?;
        let shared = Arc::new(Shared::default());
        let thread_shared = Arc::clone(&shared);
        let dmc = Arc::new(Mutex::new(Dmc::new(options.dmc.clone())));
        let thread_dmc = Arc::clone(&dmc);
        let thread = std::thread::Builder::new()
            .name("galil-sim".into())
            .spawn(move || serve(pty.master, pty.slave, options, &thread_shared, &thread_dmc))?;
        Ok(PtyEmulator {
            path,
            shared,
            dmc,
            thread: Some(thread),
        })
    }

    /// Reads the emulated controller (its clock, axes, variables, arm) as it is now.
    pub fn inspect<T>(&self, f: impl FnOnce(&Dmc) -> T) -> T {
        let dmc = self.dmc.lock().unwrap_or_else(PoisonError::into_inner);
        f(&dmc)
    }

    /// A handle that reads the emulated controller from another thread (another emulated
    /// device whose state depends on the axes, such as a force sensor on the arm), for as long
    /// as the handle lives.
    pub fn observer(&self) -> DmcObserver {
        DmcObserver {
            dmc: Arc::clone(&self.dmc),
        }
    }

    /// The device path to open (`/dev/pts/N`).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Makes the device disappear: the pseudo-terminal is closed, as when a USB adapter or the
    /// cable is pulled. Clients see a hang-up on their next read or write; the controller itself
    /// keeps running (a board program still turns motors off).
    pub fn unplug(&self) {
        self.shared.unplug.store(true, Ordering::SeqCst);
    }

    /// Bytes received and sent so far.
    pub fn bytes(&self) -> (u64, u64) {
        (
            self.shared.bytes_in.load(Ordering::Relaxed),
            self.shared.bytes_out.load(Ordering::Relaxed),
        )
    }

    /// True while the pseudo-terminal is open (until [`unplug`](PtyEmulator::unplug) took
    /// effect).
    pub fn is_plugged(&self) -> bool {
        !self.shared.line_closed.load(Ordering::SeqCst)
    }

    /// True while the serving thread runs.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Stops serving and closes the pseudo-terminal.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for PtyEmulator {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// The longest step the emulated controller's clock takes between two looks of its thread.
/// A thread that stalled longer (a loaded machine) pauses the emulated controller for the rest
/// of the stall: otherwise its watchdog timers would count the emulator's own stall as host
/// silence, which a real DMC, never descheduled, does not see.
const MAX_CLOCK_STEP: Duration = Duration::from_millis(10);

/// The emulated controller's clock: wall time since the start, minus the stalls of the serving
/// thread beyond [`MAX_CLOCK_STEP`].
struct EmulatorClock {
    start: Instant,
    paused: Duration,
    last: Duration,
}

impl EmulatorClock {
    fn new() -> Self {
        EmulatorClock {
            start: Instant::now(),
            paused: Duration::ZERO,
            last: Duration::ZERO,
        }
    }

    fn now(&mut self) -> Duration {
        let mut now = self.start.elapsed().saturating_sub(self.paused);
        if now > self.last + MAX_CLOCK_STEP {
            self.paused += now - self.last - MAX_CLOCK_STEP;
            now = self.last + MAX_CLOCK_STEP;
        }
        self.last = now;
        now
    }
}

/// Seconds per byte on a line at `baud` (start + 8 data + stop bits).
fn byte_time(baud: u32) -> Duration {
    Duration::from_secs_f64(10.0 / f64::from(baud.max(1)))
}

fn sleep_until(t: Instant) {
    let now = Instant::now();
    if t > now {
        std::thread::sleep(t - now);
    }
}

fn serve(master: OwnedFd, slave: OwnedFd, options: PtyOptions, shared: &Shared, dmc: &Mutex<Dmc>) {
    let start = Instant::now();
    let mut clock = EmulatorClock::new();
    let lock = || dmc.lock().unwrap_or_else(PoisonError::into_inner);
    let mut buf = [0u8; 512];
    let mut out = Vec::new();
    let mut rx_clock = start;
    let mut tx_clock = start;
    let mut next_unsolicited = options
        .unsolicited
        .as_ref()
        .map(|(period, _)| start + *period);
    while !shared.stop.load(Ordering::SeqCst) {
        if shared.unplug.load(Ordering::SeqCst) {
            break;
        }
        let mut fds = [PollFd::new(master.as_fd(), PollFlags::POLLIN)];
        let ready = poll(&mut fds, PollTimeout::from(2u8)).unwrap_or(0);
        let mut dmc = lock();
        // The controller runs on its own: servo samples and programs, talked to or not.
        dmc.advance(clock.now());
        if ready > 0 {
            match nix::unistd::read(master.as_fd(), &mut buf) {
                Ok(n) if n > 0 => {
                    shared.bytes_in.fetch_add(n as u64, Ordering::Relaxed);
                    if let Some(baud) = options.baud {
                        rx_clock = rx_clock.max(Instant::now()) + byte_time(baud) * n as u32;
                        sleep_until(rx_clock);
                    }
                    dmc.input(&buf[..n], clock.now(), &mut out);
                }
                // No client has the device open, or a spurious wake-up.
                _ => {
                    drop(dmc);
                    std::thread::sleep(Duration::from_millis(2));
                    continue;
                }
            }
        } else if dmc.idle() {
            // Quiet line: queued unsolicited output goes out on its own.
            dmc.flush_unsolicited(&mut out);
        }
        if let (Some(due), Some((period, msg))) = (next_unsolicited, &options.unsolicited)
            && Instant::now() >= due
        {
            dmc.queue_unsolicited(msg);
            next_unsolicited = Some(due.max(Instant::now() - *period) + *period);
        }
        drop(dmc);
        if !out.is_empty() {
            write_out(&master, &out, options.baud, &mut tx_clock, shared);
            out.clear();
        }
    }
    drop(master);
    drop(slave);
    shared.line_closed.store(true, Ordering::SeqCst);
    // Unplugged (or stopping): the controller runs on without a line until stopped.
    while !shared.stop.load(Ordering::SeqCst) {
        lock().advance(clock.now());
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Writes `out` to the master side, paced when asked; gives up on output nobody reads for 1 s.
fn write_out(
    master: &OwnedFd,
    out: &[u8],
    baud: Option<u32>,
    tx_clock: &mut Instant,
    shared: &Shared,
) {
    let chunk_len = if baud.is_some() { 16 } else { out.len().max(1) };
    for chunk in out.chunks(chunk_len) {
        if let Some(baud) = baud {
            *tx_clock = (*tx_clock).max(Instant::now()) + byte_time(baud) * chunk.len() as u32;
            sleep_until(*tx_clock);
        }
        let mut rest = chunk;
        let give_up = Instant::now() + Duration::from_secs(1);
        while !rest.is_empty() {
            if shared.stop.load(Ordering::SeqCst) || shared.unplug.load(Ordering::SeqCst) {
                return;
            }
            match nix::unistd::write(master.as_fd(), rest) {
                Ok(n) => {
                    shared.bytes_out.fetch_add(n as u64, Ordering::Relaxed);
                    rest = &rest[n..];
                }
                Err(Errno::EAGAIN) | Err(Errno::EINTR) => {
                    if Instant::now() > give_up {
                        return;
                    }
                    let mut fds = [PollFd::new(master.as_fd(), PollFlags::POLLOUT)];
                    let _ = poll(&mut fds, PollTimeout::from(5u8));
                }
                Err(_) => return,
            }
        }
    }
}

/// A reading handle on a [`PtyEmulator`]'s controller ([`PtyEmulator::observer`]).
#[derive(Clone, Debug)]
pub struct DmcObserver {
    dmc: Arc<Mutex<Dmc>>,
}

impl DmcObserver {
    /// Reads the emulated controller as it is now (locks it briefly: not for a real-time
    /// thread).
    pub fn inspect<T>(&self, f: impl FnOnce(&Dmc) -> T) -> T {
        let dmc = self.dmc.lock().unwrap_or_else(PoisonError::into_inner);
        f(&dmc)
    }
}
