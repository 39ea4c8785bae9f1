//! The simulated clock's world: the same per-tick bodies a creator's loop threads would run,
//! stepped in timestamp order by whoever calls [`SimWorld::advance`]: faster than real time,
//! and the same result for the same objects and inputs every time ([`ClockMode::Simulated`](super::clock::ClockMode::Simulated)).
//!
//! On the simulated clock, events at the same instant run communication tasks first, then
//! sensor feeds, then control tasks (as priorities would order them on one core), and within
//! each, by controller name: so neither creation order nor the path the objects came by
//! (a system file, `ctl` verbs) changes a run.

use std::collections::BTreeMap;
use std::sync::atomic::Ordering;
use std::time::Duration;

use penelope_hal::Timestamp;
use penelope_rt_core::exec::{Flow, Tick};

use super::clock::SimulatedTime;
use super::runtime::{Pump, Running, SensorFeed, StoppedLoop};

/// A per-tick body of a loop thread, as the executor calls it.
pub type TickBody = Box<dyn FnMut(Tick) -> Flow + Send>;

/// One active controller on the simulated clock.
pub struct SteppedLoop {
    control: TickBody,
    comm: TickBody,
    feed: Option<SensorFeed>,
    pump: Pump,
    periods: [Duration; 3],
    next: [Timestamp; 3],
    ticks: [u64; 3],
    running: [bool; 2],
    /// Event-driven handoff: the communication body gets an early tick just before each
    /// control tick (what arrived is handed on) and just after it (the new sample is sent).
    event_driven: bool,
}

/// The phases of an instant, in the order they run.
const COMM: usize = 0;
const FEED: usize = 1;
const CONTROL: usize = 2;

impl SteppedLoop {
    /// A loop whose first ticks are at `now`: the control and communication bodies (the same
    /// closures a thread would run), its sensor feed, its telemetry pump, and the periods of
    /// the control task, the communication task and the feed.
    pub fn new(
        now: Timestamp,
        control: TickBody,
        comm: TickBody,
        feed: Option<SensorFeed>,
        pump: Pump,
        periods: (Duration, Duration, Duration),
    ) -> Self {
        SteppedLoop {
            control,
            comm,
            feed,
            pump,
            periods: [periods.1, periods.2, periods.0],
            next: [now; 3],
            ticks: [0; 3],
            running: [true; 2],
            event_driven: false,
        }
    }

    /// Steps an event-driven communication task as its thread's doorbell and socket would
    /// wake it: early, just before and just after each control tick.
    pub fn event_driven(mut self, event_driven: bool) -> Self {
        self.event_driven = event_driven;
        self
    }

    /// An early tick of the communication body at `at`.
    fn early_comm(&mut self, at: Timestamp) {
        if self.event_driven && self.running[0] {
            let tick = Tick {
                early: true,
                ..self.tick(COMM, at)
            };
            self.running[0] = (self.comm)(tick) == Flow::Continue;
        }
    }

    fn tick(&self, phase: usize, at: Timestamp) -> Tick {
        Tick {
            index: self.ticks[phase],
            deadline: at,
            woke: at,
            period: self.periods[phase],
            overruns: 0,
            previous_exec: Duration::ZERO,
            early: false,
        }
    }

    fn run(&mut self, phase: usize) {
        let at = self.next[phase];
        let tick = self.tick(phase, at);
        match phase {
            COMM if self.running[0] => {
                self.running[0] = (self.comm)(tick) == Flow::Continue;
            }
            FEED => {
                if let Some(f) = self.feed.as_mut() {
                    f.step(at);
                }
            }
            CONTROL if self.running[1] => {
                self.early_comm(at);
                self.running[1] = (self.control)(tick) == Flow::Continue;
                self.early_comm(at);
            }
            _ => {}
        }
        self.ticks[phase] += 1;
        self.next[phase] = at + self.periods[phase];
    }

    /// Stops the loop at `now` the way its threads stop: with `running`'s `Deactivate` in its
    /// command ring, one more control tick applies it (amplifiers off, or the board's servo
    /// holding) unless the loop already failed; then both bodies hand their tasks back.
    pub fn stop(
        mut self,
        running: &Running,
        now: Timestamp,
        mode: Option<super::runtime::StopMode>,
    ) -> StoppedLoop {
        // One more control tick takes a `Deactivate` in.
        if mode == Some(super::runtime::StopMode::Deactivate) && self.running[1] {
            let tick = self.tick(CONTROL, now);
            self.running[1] = (self.control)(tick) == Flow::Continue;
        }
        running.control_stop.store(true, Ordering::Release);
        running.comm_stop.store(true, Ordering::Release);
        for phase in [CONTROL, COMM] {
            let tick = self.tick(phase, now);
            let body = if phase == CONTROL {
                &mut self.control
            } else {
                &mut self.comm
            };
            let _ = body(tick);
        }
        self.pump.drain();
        StoppedLoop {
            control: running.control_back.try_recv().ok(),
            comm: running.comm_back.try_recv().ok(),
        }
    }
}

/// Every loop of a creator on the simulated clock, and the clock.
#[derive(Default)]
pub struct SimWorld {
    now: Timestamp,
    loops: BTreeMap<String, SteppedLoop>,
}

/// How much simulated time passes between two drains of the telemetry rings (well inside
/// the rings' four seconds at 1 kHz).
const DRAIN_EVERY: Duration = Duration::from_millis(50);

impl SimWorld {
    /// The simulated clock's time.
    pub fn now(&self) -> Timestamp {
        self.now
    }

    /// Adds controller `name`'s loop.
    pub fn add(&mut self, name: &str, stepped: SteppedLoop) {
        self.loops.insert(name.to_string(), stepped);
    }

    /// Takes controller `name`'s loop out.
    pub fn remove(&mut self, name: &str) -> Option<SteppedLoop> {
        self.loops.remove(name)
    }

    /// Runs every event before `now + by` in order (instant, then phase, then controller name),
    /// draining the telemetry rings as it goes, and leaves the clock at `now + by`.
    pub fn advance(&mut self, by: Duration) -> Timestamp {
        let end = self.now + by;
        let mut drain_at = self.now + DRAIN_EVERY;
        loop {
            let mut earliest: Option<(Timestamp, usize, &String)> = None;
            for (name, l) in &self.loops {
                for phase in [COMM, FEED, CONTROL] {
                    let due = l.next[phase];
                    if phase == FEED && l.feed.is_none() {
                        continue;
                    }
                    let key = (due, phase, name);
                    if due < end && earliest.is_none_or(|e| key < e) {
                        earliest = Some(key);
                    }
                }
            }
            let Some((at, phase, name)) = earliest else {
                break;
            };
            if at >= drain_at {
                self.drain();
                drain_at = at + DRAIN_EVERY;
                continue;
            }
            let name = name.clone();
            if let Some(l) = self.loops.get_mut(&name) {
                l.run(phase);
            }
        }
        self.drain();
        self.now = end;
        end
    }

    fn drain(&mut self) {
        for l in self.loops.values_mut() {
            l.pump.drain();
        }
    }
}

impl SimulatedTime for SimWorld {
    fn now(&self) -> Timestamp {
        SimWorld::now(self)
    }
}
