//! The periodic executor (Linux, feature `std`): one thread per loop, SCHED_FIFO, pinned, memory
//! locked, sleeping to absolute deadlines on `CLOCK_MONOTONIC`.
//!
//! Each period the thread sleeps with `clock_nanosleep(TIMER_ABSTIME)` to its deadline, measures
//! how late it woke (the wake-up latency, as cyclictest does), calls the body with a [`Tick`],
//! measures the body's execution time, and moves the deadline on by one period. Deadlines are
//! absolute, so they never drift. When a body overruns past the next deadline the overrun is
//! counted and the missed deadlines are skipped (not run late in a burst). A thread given a
//! [`TickPhase`] puts its deadlines on a grid of the system's common clock instead (`k·period +
//! phase`), so that threads on different hosts tick at known phases to each other.
//!
//! Before the first tick the thread asks for its real-time rights: SCHED_FIFO at the configured
//! priority, the CPU affinity, `mlockall(MCL_CURRENT | MCL_FUTURE)`, a prefaulted stack, and
//! `/dev/cpu_dma_latency` held at 0 for the life of the process. Where the OS refuses one, it says
//! so once per process on stderr, naming the fix, and runs on without it; [`RtStatus`] tells what
//! was applied.
//!
//! ```no_run
//! use std::time::Duration;
//! use penelope_rt_core::exec::{self, Flow, PeriodicConfig};
//!
//! let config = PeriodicConfig::new("control", Duration::from_millis(1)).priority(80).cpu(1);
//! let mut thread = exec::spawn(config, |tick| {
//!     // ... one control tick at tick.deadline ...
//!     if tick.index == 9_999 { Flow::Stop } else { Flow::Continue }
//! })
//! .expect("spawn");
//! let report = thread.join().expect("thread ran");
//! println!("p99 wake-up latency {:?}", report.latency.summary().p99);
//! ```

use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use penelope_hal::Timestamp;

use crate::cell::{ArcLatestReader, ArcLatestWriter, latest};
use crate::clock::{MonotonicClock, sleep_until};
pub use crate::sim::Flow;
use crate::stats::{DurationStats, LatencyHistogram};
use crate::wake::{WakeOn, Woken};

mod rt_settings;
mod tick_phase;
pub use rt_settings::{apply_rt, hold_dma_latency, set_fifo};
pub use tick_phase::{CommonOffset, TickGrid, TickPhase};

/// How a periodic thread runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PeriodicConfig {
    /// Thread name (shown by `ps -L`, `top -H`; at most 15 bytes are kept by Linux).
    pub name: String,
    /// The period.
    pub period: Duration,
    /// SCHED_FIFO priority 1 to 99, or `None` for normal scheduling.
    pub priority: Option<u8>,
    /// Pin the thread to this CPU, or `None` to let it float.
    pub cpu: Option<usize>,
    /// Lock the process's memory (`mlockall`) before the first tick.
    pub lock_memory: bool,
    /// Bytes of stack to touch before the first tick, so no page fault happens later.
    pub prefault_stack: usize,
    /// The thread's stack size, bytes (must exceed `prefault_stack` plus what the body uses).
    pub stack_size: usize,
    /// Hold `/dev/cpu_dma_latency` at 0 (keeps idle CPUs out of deep sleep states).
    pub hold_dma_latency: bool,
    /// Tick at this phase of the period on the common clock ([`TickPhase`]), or `None` to
    /// tick one period after the start and every period from there.
    pub tick_phase: Option<TickPhase>,
}

impl PeriodicConfig {
    /// `name` every `period`: FIFO priority 80, no pinning, memory locked, 256 KiB of stack
    /// prefaulted out of 1 MiB, `cpu_dma_latency` held.
    pub fn new(name: impl Into<String>, period: Duration) -> Self {
        PeriodicConfig {
            name: name.into(),
            period,
            priority: Some(80),
            cpu: None,
            lock_memory: true,
            prefault_stack: 256 * 1024,
            stack_size: 1024 * 1024,
            hold_dma_latency: true,
            tick_phase: None,
        }
    }

    /// Ticks at `phase` into each period of the common clock ([`TickPhase`]).
    pub fn tick_phase(mut self, phase: TickPhase) -> Self {
        self.tick_phase = Some(phase);
        self
    }

    /// Sets the SCHED_FIFO priority (1 to 99).
    pub fn priority(mut self, priority: u8) -> Self {
        self.priority = Some(priority);
        self
    }

    /// Normal (non-real-time) scheduling.
    pub fn normal_priority(mut self) -> Self {
        self.priority = None;
        self
    }

    /// Pins the thread to `cpu`.
    pub fn cpu(mut self, cpu: usize) -> Self {
        self.cpu = Some(cpu);
        self
    }

    /// Checks the configuration.
    ///
    /// # Errors
    /// [`ExecError::Config`] for a zero period, a priority outside 1 to 99, or a stack smaller
    /// than the prefault size plus 64 KiB.
    pub fn validate(&self) -> Result<(), ExecError> {
        if self.period.is_zero() {
            return Err(ExecError::Config("period must be above zero"));
        }
        if self.priority.is_some_and(|p| !(1..=99).contains(&p)) {
            return Err(ExecError::Config("SCHED_FIFO priority must be 1 to 99"));
        }
        if self.stack_size < self.prefault_stack + 64 * 1024 {
            return Err(ExecError::Config(
                "stack must exceed the prefault size by 64 KiB",
            ));
        }
        Ok(())
    }
}

/// One period, as handed to the body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tick {
    /// 0 for the first tick; skipped deadlines are not counted.
    pub index: u64,
    /// The scheduled instant of this tick (`CLOCK_MONOTONIC`): pass it to logic as `now`.
    pub deadline: Timestamp,
    /// When the thread actually woke.
    pub woke: Timestamp,
    /// The period.
    pub period: Duration,
    /// Overruns so far.
    pub overruns: u64,
    /// Execution time of the previous tick (zero for the first).
    pub previous_exec: Duration,
    /// An early tick: a [`WakeOn`] source woke the thread before its deadline
    /// ([`spawn_woken`]); `deadline` and `woke` are then the instant it woke, and the period's
    /// schedule and statistics are left alone.
    pub early: bool,
}

impl Tick {
    /// How late the thread woke: `woke - deadline`.
    pub fn latency(&self) -> Duration {
        self.woke.saturating_since(self.deadline)
    }
}

/// Whether one real-time setting took effect.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Setting {
    /// Not asked for by the configuration.
    #[default]
    NotRequested,
    /// In effect.
    Applied,
    /// Refused by the OS (the `errno`, 0 when unknown).
    Refused(i32),
}

impl Setting {
    /// True for [`Setting::Applied`].
    pub fn is_applied(self) -> bool {
        self == Setting::Applied
    }
}

/// Which real-time settings took effect for a thread.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct RtStatus {
    /// SCHED_FIFO priority.
    pub fifo: Setting,
    /// CPU pinning.
    pub affinity: Setting,
    /// `mlockall`.
    pub memory_locked: Setting,
    /// `/dev/cpu_dma_latency` held at 0.
    pub dma_latency: Setting,
}

/// Figures a running thread publishes after every tick (constant-size, for a latest-value cell).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct LiveStats {
    /// Ticks run.
    pub ticks: u64,
    /// Ticks whose end passed the next deadline.
    pub overruns: u64,
    /// Deadlines skipped because of overruns.
    pub skipped: u64,
    /// The last tick's wake-up latency.
    pub last_latency: Duration,
    /// Largest wake-up latency so far.
    pub max_latency: Duration,
    /// Mean wake-up latency so far.
    pub mean_latency: Duration,
    /// The last tick's execution time.
    pub last_exec: Duration,
    /// Largest execution time so far.
    pub max_exec: Duration,
}

/// Everything a periodic thread measured, returned when it stops.
#[derive(Clone, Debug)]
pub struct RunReport {
    /// Ticks run.
    pub ticks: u64,
    /// Ticks whose end passed the next deadline.
    pub overruns: u64,
    /// Deadlines skipped because of overruns.
    pub skipped: u64,
    /// Wake-up latency histogram (1 µs buckets to 10 ms).
    pub latency: Box<LatencyHistogram>,
    /// Execution time of the body.
    pub exec: DurationStats,
    /// The real-time settings in effect.
    pub rt: RtStatus,
    /// The first deadline.
    pub started: Timestamp,
    /// When the thread stopped.
    pub stopped: Timestamp,
}

/// Why a periodic thread could not be started or joined.
#[derive(Debug)]
pub enum ExecError {
    /// A bad [`PeriodicConfig`].
    Config(&'static str),
    /// The thread could not be created.
    Spawn(std::io::Error),
    /// The body panicked.
    Panicked,
}

impl fmt::Display for ExecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExecError::Config(m) => write!(f, "periodic thread configuration: {m}"),
            ExecError::Spawn(e) => write!(f, "cannot spawn periodic thread: {e}"),
            ExecError::Panicked => f.write_str("periodic thread panicked"),
        }
    }
}

impl std::error::Error for ExecError {}

/// A running periodic thread.
#[derive(Debug)]
pub struct PeriodicThread {
    stop: Arc<AtomicBool>,
    handle: JoinHandle<RunReport>,
    live: ArcLatestReader<LiveStats>,
}

impl PeriodicThread {
    /// Asks the thread to stop after its current tick.
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// True once the thread has ended.
    pub fn is_finished(&self) -> bool {
        self.handle.is_finished()
    }

    /// The latest figures the thread published (`None` before its first tick).
    pub fn live(&mut self) -> Option<LiveStats> {
        self.live.latest()
    }

    /// Waits for the thread to end (after [`stop`](PeriodicThread::stop) or a [`Flow::Stop`]) and
    /// returns what it measured.
    ///
    /// # Errors
    /// [`ExecError::Panicked`] if the body panicked.
    pub fn join(self) -> Result<RunReport, ExecError> {
        self.handle.join().map_err(|_| ExecError::Panicked)
    }

    /// [`stop`](PeriodicThread::stop), then [`join`](PeriodicThread::join).
    ///
    /// # Errors
    /// As [`join`](PeriodicThread::join).
    pub fn stop_and_join(self) -> Result<RunReport, ExecError> {
        self.stop();
        self.join()
    }
}

/// Spawns a periodic thread running `body` every `config.period` until it returns [`Flow::Stop`]
/// or [`PeriodicThread::stop`] is called.
///
/// # Errors
/// [`ExecError::Config`] or [`ExecError::Spawn`]. Refused real-time rights are not errors: they
/// are warned about once and reported in [`RunReport::rt`].
pub fn spawn<F>(config: PeriodicConfig, body: F) -> Result<PeriodicThread, ExecError>
where
    F: FnMut(Tick) -> Flow + Send + 'static,
{
    spawn_thread(config, None, body)
}

/// [`spawn`], woken also before a deadline by `wake` (a doorbell another thread rings, a socket
/// with data): the body is then called with [`Tick::early`] set, at most
/// [`WakeOn::max_early_wakes`] times a period ([`MAX_EARLY_WAKES`](crate::wake::MAX_EARLY_WAKES) by default); the periodic
/// ticks keep their schedule.
///
/// # Errors
/// As [`spawn`].
pub fn spawn_woken<F>(
    config: PeriodicConfig,
    wake: WakeOn,
    body: F,
) -> Result<PeriodicThread, ExecError>
where
    F: FnMut(Tick) -> Flow + Send + 'static,
{
    spawn_thread(config, Some(wake), body)
}

/// [`spawn`] and [`spawn_woken`].
fn spawn_thread<F>(
    config: PeriodicConfig,
    wake: Option<WakeOn>,
    body: F,
) -> Result<PeriodicThread, ExecError>
where
    F: FnMut(Tick) -> Flow + Send + 'static,
{
    config.validate()?;
    let stop = Arc::new(AtomicBool::new(false));
    let (writer, live) = latest::<LiveStats>();
    let thread_stop = stop.clone();
    let handle = std::thread::Builder::new()
        .name(config.name.clone())
        .stack_size(config.stack_size)
        .spawn(move || run_loop(&config, &thread_stop, Some(writer), wake.as_ref(), body))
        .map_err(ExecError::Spawn)?;
    Ok(PeriodicThread { stop, handle, live })
}

/// Runs `body` periodically in the calling thread (whose scheduling, affinity and stack this
/// changes) until it returns [`Flow::Stop`] or `stop` becomes true.
///
/// # Errors
/// [`ExecError::Config`] for a bad configuration.
pub fn run_current<F>(
    config: &PeriodicConfig,
    stop: &AtomicBool,
    body: F,
) -> Result<RunReport, ExecError>
where
    F: FnMut(Tick) -> Flow,
{
    config.validate()?;
    Ok(run_loop(config, stop, None, None, body))
}

fn run_loop<F>(
    config: &PeriodicConfig,
    stop: &AtomicBool,
    mut live: Option<ArcLatestWriter<LiveStats>>,
    wake: Option<&WakeOn>,
    mut body: F,
) -> RunReport
where
    F: FnMut(Tick) -> Flow,
{
    let rt = apply_rt(config);
    // Everything the loop needs is allocated here, before the first tick.
    let mut latency: Box<LatencyHistogram> = Box::default();
    let mut exec = DurationStats::new();
    let mut stats = LiveStats::default();
    let period = config.period;
    // A phased thread's deadlines are on the common clock's grid, and follow its offset.
    let mut grid = config
        .tick_phase
        .as_ref()
        .map(|p| (TickGrid::new(period, p.phase), &*p.offset));
    let mut deadline = match &grid {
        Some((g, offset)) => g.first(MonotonicClock::read(), offset.get()),
        None => MonotonicClock::read() + period,
    };
    let started = deadline;
    let mut index = 0u64;
    let mut previous_exec = Duration::ZERO;
    let mut latency_sum: u128 = 0;
    let mut early_wakes = 0u32;
    while !stop.load(Ordering::Relaxed) {
        if let Some(wake) = wake
            && early_wakes < wake.max_early_wakes
            && wake.wait_until(deadline) == Woken::Early
        {
            // Outside the schedule: no latency, overrun or execution figures for it.
            early_wakes += 1;
            let now = MonotonicClock::read();
            let flow = body(Tick {
                index,
                deadline: now,
                woke: now,
                period,
                overruns: stats.overruns,
                previous_exec,
                early: true,
            });
            if flow == Flow::Stop {
                break;
            }
            continue;
        }
        early_wakes = 0;
        sleep_until(deadline);
        let woke = MonotonicClock::read();
        let late = woke.saturating_since(deadline);
        latency.record(late);
        let flow = body(Tick {
            index,
            deadline,
            woke,
            period,
            overruns: stats.overruns,
            previous_exec,
            early: false,
        });
        let end = MonotonicClock::read();
        previous_exec = end.saturating_since(woke);
        exec.record(previous_exec);
        index += 1;

        let ran = deadline;
        deadline = next_deadline(ran, period, end, &mut stats);
        if let Some((g, offset)) = grid.as_mut() {
            deadline = g.follow(ran, end, deadline, offset.get());
        }
        note_tick(&mut stats, index, late, previous_exec, &mut latency_sum);
        if let Some(w) = live.as_mut() {
            w.write(stats);
        }
        if flow == Flow::Stop {
            break;
        }
    }
    RunReport {
        ticks: stats.ticks,
        overruns: stats.overruns,
        skipped: stats.skipped,
        latency,
        exec,
        rt,
        started,
        stopped: MonotonicClock::read(),
    }
}

/// The deadline after `deadline` for a tick that ended at `end`: one period on, or on an
/// overrun the first deadline still ahead (every one already passed is skipped and counted in
/// `stats`).
#[inline]
fn next_deadline(
    deadline: Timestamp,
    period: Duration,
    end: Timestamp,
    stats: &mut LiveStats,
) -> Timestamp {
    let mut next = deadline + period;
    if end >= next {
        // Overrun: skip every deadline already passed; resume at the first one ahead.
        let behind = end.saturating_since(next).as_nanos();
        let missed = u64::try_from(behind / period.as_nanos()).unwrap_or(u64::MAX) + 1;
        stats.overruns += 1;
        stats.skipped += missed;
        let jump = u64::try_from(period.as_nanos())
            .unwrap_or(u64::MAX)
            .saturating_mul(missed);
        next = Timestamp::from_nanos(next.as_nanos().saturating_add(jump));
    }
    next
}

/// Notes tick number `index` (from 1) in the live figures: its wake-up latency `late` (summed
/// into `latency_sum` for the mean) and its execution time `exec`.
#[inline]
fn note_tick(
    stats: &mut LiveStats,
    index: u64,
    late: Duration,
    exec: Duration,
    latency_sum: &mut u128,
) {
    stats.ticks = index;
    stats.last_latency = late;
    stats.max_latency = stats.max_latency.max(late);
    *latency_sum += late.as_nanos();
    stats.mean_latency =
        Duration::from_nanos(u64::try_from(*latency_sum / u128::from(index)).unwrap_or(u64::MAX));
    stats.last_exec = exec;
    stats.max_exec = stats.max_exec.max(exec);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_counts_and_stops() {
        let config = PeriodicConfig {
            lock_memory: false,
            hold_dma_latency: false,
            ..PeriodicConfig::new("test-exec", Duration::from_micros(500)).normal_priority()
        };
        let mut seen = Vec::with_capacity(100);
        let stop = AtomicBool::new(false);
        let report = run_current(&config, &stop, |tick| {
            seen.push((tick.index, tick.deadline));
            if tick.index == 49 {
                Flow::Stop
            } else {
                Flow::Continue
            }
        })
        .unwrap();
        assert_eq!(report.ticks, 50);
        assert_eq!(report.latency.count(), 50);
        assert_eq!(report.exec.count(), 50);
        // Deadlines are absolute multiples of the period from the start (skips allowed on a
        // loaded machine, never drift).
        for w in seen.windows(2) {
            let gap = w[1].1.as_nanos() - w[0].1.as_nanos();
            assert_eq!(gap % 500_000, 0, "deadline drifted: gap {gap} ns");
        }
        assert_eq!(report.rt.fifo, Setting::NotRequested);
    }

    /// The deadlines (this host's clock) of a thread stepped as [`run_loop`] steps them, on a
    /// simulated clock: its host's clock `host_ahead_ns` ahead of the common one, the offset
    /// estimate it reads at tick `k` from `estimate(k)`, each tick's execution time from
    /// `exec(k)` (an overrun when above the period).
    fn simulated_deadlines(
        phase: Duration,
        host_ahead_ns: u64,
        ticks: usize,
        estimate: impl Fn(usize) -> i64,
        exec: impl Fn(usize) -> u64,
    ) -> (Vec<Timestamp>, u64, LiveStats) {
        let period = Duration::from_millis(1);
        let mut grid = TickGrid::new(period, phase);
        let mut stats = LiveStats::default();
        // Started at 7.3 ms of the common clock.
        let mut deadline = grid.first(
            Timestamp::from_nanos(7_300_000 + host_ahead_ns),
            estimate(0),
        );
        let mut seen = Vec::with_capacity(ticks);
        for k in 0..ticks {
            seen.push(deadline);
            let ran = deadline;
            let end = ran + Duration::from_nanos(exec(k));
            deadline = next_deadline(ran, period, end, &mut stats);
            deadline = grid.follow(ran, end, deadline, estimate(k));
        }
        (seen, grid.rephased(), stats)
    }

    #[test]
    fn a_slave_phased_half_a_period_ticks_half_a_period_after_its_master_on_the_common_clock() {
        const T: i64 = 1_000_000;
        // The master's host is the common clock; the slave's runs 3.7 s ahead of it, and its
        // estimate is first 40 µs off (then 5 µs off, jittering by 2 µs after tick 4000).
        let ahead = 3_700_000_000u64;
        let slave_estimate = |k: usize| -> i64 {
            let truth = -(ahead as i64);
            if k < 4_000 {
                truth + 40_000
            } else {
                truth + 5_000 + (k % 3) as i64 * 1_000
            }
        };
        // Execution times of 50 to 450 µs, with an overrun of 2.4 ms now and then.
        let exec = |seed: u64| {
            move |k: usize| {
                let k = k as u64 ^ seed;
                if k.is_multiple_of(997) {
                    2_400_000
                } else {
                    50_000 + (k * 7919) % 400_000
                }
            }
        };
        let n = 20_000;
        let (master, master_rephased, master_stats) =
            simulated_deadlines(Duration::ZERO, 0, n, |_| 0, exec(1));
        let (slave, slave_rephased, slave_stats) = simulated_deadlines(
            Duration::from_nanos(T as u64 / 2),
            ahead,
            n,
            slave_estimate,
            exec(2),
        );
        assert!(master_stats.overruns > 10 && slave_stats.overruns > 10);
        assert_eq!(master_rephased, 0);
        assert_eq!(slave_rephased, 1, "once, when the estimate moved 35 µs");
        let on_common = |t: &Timestamp, host_ahead: u64| t.as_nanos() as i64 - host_ahead as i64;
        let master: Vec<i64> = master.iter().map(|t| on_common(t, 0)).collect();
        let slave: Vec<i64> = slave.iter().map(|t| on_common(t, ahead)).collect();
        // Every slave tick sits half a period after the master's grid, within the estimate's
        // error (40 µs, then 5 to 7 µs), skipped ticks or not; every master tick on its grid.
        let mut checked = 0;
        for (k, s) in slave.iter().enumerate() {
            let after_master = (s - master[0]).rem_euclid(T);
            let bound = if k <= 4_000 { 40_000 } else { 7_000 };
            assert!(
                (after_master - T / 2).abs() <= bound,
                "slave tick {k} at {after_master} ns after the master's grid"
            );
            checked += 1;
        }
        assert_eq!(checked, n);
        assert!(master.iter().all(|m| (m - master[0]) % T == 0));
        // The ticks the master actually ran: each slave tick between two of them falls half a
        // period after the one before it, within the error.
        let mut pairs = 0;
        for s in &slave[4_001..] {
            let i = master.partition_point(|m| m <= s);
            if i == 0 || i == master.len() || master[i] - master[i - 1] != T {
                continue;
            }
            assert!((s - master[i - 1] - T / 2).abs() <= 7_000);
            pairs += 1;
        }
        assert!(
            pairs > 15_000,
            "{pairs} slave ticks between consecutive master ticks"
        );
        // Never two ticks closer than half a period, re-phase or not.
        for w in slave.windows(2).chain(master.windows(2)) {
            assert!(w[1] - w[0] >= T / 2, "ticks {} ns apart", w[1] - w[0]);
        }
    }

    #[test]
    fn phased_threads_tick_on_the_common_clocks_grid_and_follow_a_new_offset() {
        let period = Duration::from_millis(2);
        let config = |name: &str, phase: Duration, offset: &Arc<CommonOffset>| PeriodicConfig {
            lock_memory: false,
            hold_dma_latency: false,
            ..PeriodicConfig::new(name, period)
                .normal_priority()
                .tick_phase(TickPhase::new(phase, offset.clone()))
        };
        let offset = Arc::new(CommonOffset::new(250_000));
        let run = |phase: Duration, moved_at: u64| {
            let offset = offset.clone();
            let cfg = config("test-phase", phase, &offset);
            let (tx, rx) = std::sync::mpsc::channel();
            let t = spawn(cfg, move |tick| {
                if tick.index == moved_at {
                    // A new estimate, 0.6 ms on (only the slave's thread moves it).
                    offset.set(850_000);
                }
                let _ = tx.send(tick.deadline);
                if tick.index == 59 {
                    Flow::Stop
                } else {
                    Flow::Continue
                }
            })
            .unwrap();
            t.join().unwrap();
            rx.try_iter().collect::<Vec<_>>()
        };
        let master = run(Duration::ZERO, u64::MAX);
        let grid_pos = |t: &Timestamp, offset: u64, phase: u64| {
            (t.as_nanos() + offset + 2_000_000 - phase) % 2_000_000
        };
        assert_eq!(master.len(), 60);
        assert!(
            master.iter().all(|t| grid_pos(t, 250_000, 0) == 0),
            "{master:?}"
        );
        let slave = run(Duration::from_millis(1), 30);
        // Before the new estimate: on the grid of the old offset; after: of the new one.
        assert!(
            slave[..31]
                .iter()
                .all(|t| grid_pos(t, 250_000, 1_000_000) == 0)
        );
        assert!(
            slave[31..]
                .iter()
                .all(|t| grid_pos(t, 850_000, 1_000_000) == 0)
        );
        for w in slave.windows(2) {
            assert!(w[1].saturating_since(w[0]) >= period / 2);
        }
    }

    #[test]
    fn overruns_are_counted_and_skipped() {
        let config = PeriodicConfig {
            lock_memory: false,
            hold_dma_latency: false,
            ..PeriodicConfig::new("test-overrun", Duration::from_millis(1)).normal_priority()
        };
        let stop = AtomicBool::new(false);
        let report = run_current(&config, &stop, |tick| {
            if tick.index == 2 {
                std::thread::sleep(Duration::from_micros(3500));
            }
            if tick.index == 5 {
                Flow::Stop
            } else {
                Flow::Continue
            }
        })
        .unwrap();
        assert!(report.overruns >= 1);
        assert!(report.skipped >= 3, "skipped {}", report.skipped);
    }

    #[test]
    fn spawned_thread_publishes_live_stats_and_stops_on_request() {
        let config = PeriodicConfig {
            lock_memory: false,
            hold_dma_latency: false,
            ..PeriodicConfig::new("test-spawn", Duration::from_millis(1)).normal_priority()
        };
        let mut t = spawn(config, |_| Flow::Continue).unwrap();
        while t.live().is_none_or(|s| s.ticks < 5) {
            std::thread::sleep(Duration::from_millis(2));
        }
        let report = t.stop_and_join().unwrap();
        assert!(report.ticks >= 5);
        assert!(PeriodicConfig::new("x", Duration::ZERO).validate().is_err());
        assert!(matches!(
            PeriodicConfig::new("x", Duration::from_millis(1))
                .priority(100)
                .validate(),
            Err(ExecError::Config(_))
        ));
    }

    #[test]
    fn a_ring_wakes_the_thread_early_and_the_schedule_stays() {
        use crate::wake::Doorbell;
        let config = PeriodicConfig {
            lock_memory: false,
            hold_dma_latency: false,
            ..PeriodicConfig::new("test-woken", Duration::from_millis(200)).normal_priority()
        };
        let bell = Arc::new(Doorbell::new().unwrap());
        let (tx, rx) = std::sync::mpsc::channel();
        let started = MonotonicClock::read();
        let t = spawn_woken(config, WakeOn::doorbell(bell.clone()), move |tick| {
            let _ = tx.send(tick);
            Flow::Continue
        })
        .unwrap();
        bell.ring();
        let first = rx.recv().unwrap();
        // Rung before the first deadline (200 ms after the start): an early tick, at once.
        assert!(first.early, "{first:?}");
        assert_eq!(first.index, 0);
        assert!(first.woke.saturating_since(started) < Duration::from_millis(200));
        // Then the periodic ticks, on their absolute schedule.
        let second = rx.recv().unwrap();
        let third = rx.recv().unwrap();
        assert!(!second.early && !third.early);
        assert_eq!(
            third.deadline.as_nanos() - second.deadline.as_nanos(),
            200_000_000
        );
        let report = t.stop_and_join().unwrap();
        assert!(report.ticks >= 2);
    }

    /// The early and periodic ticks of a thread woken by a socket that stays readable, over
    /// three periods, with `per_period` ticks of a faster loop in its period (its cap).
    fn ticks_of_an_unread_socket(per_period: Option<u32>) -> Vec<bool> {
        use crate::wake::Doorbell;
        use std::os::fd::AsFd;
        let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        std::net::UdpSocket::bind("127.0.0.1:0")
            .unwrap()
            .send_to(b"x", socket.local_addr().unwrap())
            .unwrap();
        let mut wake = WakeOn::doorbell(Arc::new(Doorbell::new().unwrap()))
            .and_readable(socket.as_fd())
            .unwrap();
        if let Some(n) = per_period {
            wake = wake.per_period(n);
        }
        let config = PeriodicConfig {
            lock_memory: false,
            hold_dma_latency: false,
            ..PeriodicConfig::new("test-unread", Duration::from_millis(20)).normal_priority()
        };
        let mut ticks = Vec::with_capacity(64);
        let (tx, rx) = std::sync::mpsc::channel();
        let t = spawn_woken(config, wake, move |tick| {
            ticks.push(tick.early);
            // The datagram is never read: the socket stays readable.
            if ticks.iter().filter(|e| !**e).count() == 3 {
                let _ = tx.send(std::mem::take(&mut ticks));
                return Flow::Stop;
            }
            Flow::Continue
        })
        .unwrap();
        let ticks = rx.recv().unwrap();
        t.join().unwrap();
        ticks
    }

    #[test]
    fn a_socket_left_unread_wakes_the_thread_at_most_max_early_wakes_a_period() {
        use crate::wake::MAX_EARLY_WAKES;
        // Each period: MAX_EARLY_WAKES early ticks, then the periodic one.
        let mut period = vec![true; MAX_EARLY_WAKES as usize];
        period.push(false);
        assert_eq!(ticks_of_an_unread_socket(None), period.repeat(3));
    }

    #[test]
    fn the_cap_scales_with_the_ticks_of_the_loop_that_rings() {
        use crate::wake::MAX_EARLY_WAKES;
        // Two control ticks per communication period: twice the early wakes, then the periodic
        // tick; never more, however long the socket stays readable.
        let mut period = vec![true; 2 * MAX_EARLY_WAKES as usize];
        period.push(false);
        assert_eq!(ticks_of_an_unread_socket(Some(2)), period.repeat(3));
    }
}
