//! Deterministic simulation of periodic loops: the runner steps every task in timestamp order on a
//! simulated clock, without sleeping, so a run is exactly repeatable.
//!
//! ```
//! use core::time::Duration;
//! use penelope_hal::Timestamp;
//! use penelope_rt_core::sim::{Flow, SimRunner, SimTask};
//!
//! let (mut slow, mut fast) = (0, 0);
//! let mut slow_fn = |_now: Timestamp| { slow += 1; Flow::Continue };
//! let mut fast_fn = |_now: Timestamp| { fast += 1; Flow::Continue };
//! let mut tasks = [
//!     SimTask::new(Duration::from_millis(4), &mut slow_fn),
//!     SimTask::new(Duration::from_millis(1), &mut fast_fn),
//! ];
//! let mut runner = SimRunner::new(Timestamp::ZERO);
//! let report = runner.run_until(&mut tasks, Timestamp::from_nanos(10_000_000));
//! assert_eq!(report.ticks, 3 + 10);
//! assert_eq!((slow, fast), (3, 10));
//! ```

use core::time::Duration;

use penelope_hal::Timestamp;

use crate::clock::SimClock;

/// What a periodic task wants after a tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    /// Run again next period.
    Continue,
    /// Stop this task.
    Stop,
}

/// One periodic task of a simulation: a period, the next instant it runs, and its body.
pub struct SimTask<'a> {
    period: Duration,
    offset: Duration,
    next: Option<Timestamp>,
    running: bool,
    body: &'a mut dyn FnMut(Timestamp) -> Flow,
}

impl<'a> SimTask<'a> {
    /// A task running `body` every `period` (a zero period is raised to 1 ns), first at the
    /// runner's start time.
    pub fn new(period: Duration, body: &'a mut dyn FnMut(Timestamp) -> Flow) -> Self {
        SimTask {
            period: period.max(Duration::from_nanos(1)),
            offset: Duration::ZERO,
            next: None,
            running: true,
            body,
        }
    }

    /// Delays the task's first run by `offset` after the runner's start (a phase shift).
    pub fn with_offset(mut self, offset: Duration) -> Self {
        self.offset = offset;
        self
    }

    /// The task's period.
    pub fn period(&self) -> Duration {
        self.period
    }
}

/// What a simulation run did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SimReport {
    /// Task bodies run, all tasks together.
    pub ticks: u64,
    /// The simulated time when the run ended.
    pub end: Timestamp,
}

/// Steps [`SimTask`]s in timestamp order on a [`SimClock`]. Ties run in the order of the task
/// slice, so a run is fully determined by its inputs.
#[derive(Debug, Default)]
pub struct SimRunner {
    clock: SimClock,
    start: Timestamp,
}

impl SimRunner {
    /// A runner whose clock starts at `start`.
    pub fn new(start: Timestamp) -> Self {
        SimRunner {
            clock: SimClock::new(start),
            start,
        }
    }

    /// The simulated clock (for code that wants a [`crate::clock::Clock`]).
    pub fn clock(&self) -> &SimClock {
        &self.clock
    }

    /// Runs every task whose next instant is before `end`, earliest first, and leaves the clock at
    /// `end` (or at the last tick, if every task stopped). Task times count from the runner's
    /// start; calling again continues where the previous call stopped.
    pub fn run_until(&mut self, tasks: &mut [SimTask<'_>], end: Timestamp) -> SimReport {
        let mut ticks = 0;
        let now = crate::clock::Clock::now(&self.clock);
        for task in tasks.iter_mut() {
            if task.next.is_none() {
                task.next = Some((self.start + task.offset).max(now));
            }
        }
        loop {
            let mut earliest: Option<usize> = None;
            for (i, task) in tasks.iter().enumerate() {
                let due = task.next.unwrap_or(end);
                if task.running
                    && due < end
                    && earliest.is_none_or(|e: usize| due < tasks[e].next.unwrap_or(end))
                {
                    earliest = Some(i);
                }
            }
            let Some(i) = earliest else { break };
            let task = &mut tasks[i];
            let now = task.next.unwrap_or(end);
            self.clock.set(now);
            ticks += 1;
            if (task.body)(now) == Flow::Stop {
                task.running = false;
            }
            task.next = Some(now + task.period);
        }
        if tasks.iter().any(|t| t.running) {
            self.clock.set(end);
        }
        SimReport {
            ticks,
            end: crate::clock::Clock::now(&self.clock),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ties_run_in_slice_order_and_stop_works() {
        let mut log = [(0u8, 0u64); 8];
        let mut n = 0;
        {
            let log_ref = core::cell::RefCell::new((&mut log, &mut n));
            let mut a = |t: Timestamp| {
                let mut g = log_ref.borrow_mut();
                let k = *g.1;
                g.0[k] = (b'a', t.as_nanos());
                *g.1 += 1;
                Flow::Continue
            };
            let mut b = |t: Timestamp| {
                let mut g = log_ref.borrow_mut();
                let k = *g.1;
                g.0[k] = (b'b', t.as_nanos());
                *g.1 += 1;
                if t.as_nanos() >= 120 {
                    Flow::Stop
                } else {
                    Flow::Continue
                }
            };
            let mut tasks = [
                SimTask::new(Duration::from_nanos(20), &mut a),
                SimTask::new(Duration::from_nanos(10), &mut b),
            ];
            let mut r = SimRunner::new(Timestamp::from_nanos(100));
            let rep = r.run_until(&mut tasks, Timestamp::from_nanos(150));
            assert_eq!(rep.end, Timestamp::from_nanos(150));
        }
        assert_eq!(
            &log[..n],
            &[
                (b'a', 100),
                (b'b', 100),
                (b'b', 110),
                (b'a', 120),
                (b'b', 120),
                (b'a', 140),
            ]
        );
    }
}
