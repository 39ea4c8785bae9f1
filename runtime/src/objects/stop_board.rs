//! The stop latches of a node's running loops, kept apart from the object registry so that an
//! e-stop reaches them without the registry lock (which a slow `create` or call may hold) and
//! without any command queue (which may be full).
//!
//! Activation adds a loop's [`StopLatch`], stopping the loop removes it; both hold this board's
//! own small lock for one map operation only. An e-stop takes that lock just long enough to
//! bump the latches it names and copy them out, then waits (bounded) for the loops to act.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use penelope_rt_core::stop::StopLatch;

use penelope_protocol::proto::StopReport;

/// How long an e-stop waits for its loops' next ticks before answering (a loop ticks every
/// millisecond or so; one that has not ticked by then is reported `pending`).
pub const STOP_ACK_WAIT: Duration = Duration::from_millis(50);

/// The latches of the running loops, by controller name.
#[derive(Debug, Default)]
pub struct StopBoard {
    loops: Mutex<BTreeMap<String, Arc<StopLatch>>>,
}

/// Requests made by one e-stop: each loop's latch and its request number.
type Requests = Vec<(String, Arc<StopLatch>, u32)>;

impl StopBoard {
    /// Adds (or replaces) controller `name`'s latch: its loop started.
    pub fn insert(&self, name: &str, latch: Arc<StopLatch>) {
        self.loops
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(name.to_string(), latch);
    }

    /// Removes controller `name`'s latch: its loop stopped.
    pub fn remove(&self, name: &str) {
        self.loops
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(name);
    }

    /// Requests the e-stop of controller `name`'s loop; `false` when no loop of that name runs.
    /// Waits up to `wait` for the loop to latch it and says whether it did.
    pub fn stop(&self, name: &str, wait: Duration) -> Option<bool> {
        let requests: Requests = {
            let loops = self.loops.lock().unwrap_or_else(PoisonError::into_inner);
            let latch = loops.get(name)?;
            vec![(name.to_string(), latch.clone(), latch.request())]
        };
        let (stopped, _) = wait_for(requests, wait);
        Some(!stopped.is_empty())
    }

    /// Requests the e-stop of every running loop, waits up to `wait` for them to latch it, and
    /// says which did.
    pub fn stop_all(&self, node: &str, wait: Duration) -> StopReport {
        let requests: Requests = {
            let loops = self.loops.lock().unwrap_or_else(PoisonError::into_inner);
            loops
                .iter()
                .map(|(name, latch)| (name.clone(), latch.clone(), latch.request()))
                .collect()
        };
        let (stopped, pending) = wait_for(requests, wait);
        StopReport {
            node: node.to_string(),
            stopped,
            pending,
        }
    }

    /// The names of the loops that can be stopped.
    pub fn names(&self) -> Vec<String> {
        self.loops
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .keys()
            .cloned()
            .collect()
    }
}

/// Polls `requests` until every loop acted on its own or `wait` passed: (acted, not yet).
fn wait_for(requests: Requests, wait: Duration) -> (Vec<String>, Vec<String>) {
    let deadline = Instant::now() + wait;
    loop {
        let done = requests.iter().all(|(_, l, n)| l.acted_on(*n));
        if done || Instant::now() >= deadline {
            break;
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    let mut stopped = Vec::new();
    let mut pending = Vec::new();
    for (name, latch, n) in requests {
        if latch.acted_on(n) {
            stopped.push(name);
        } else {
            pending.push(name);
        }
    }
    (stopped, pending)
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_rt_core::control::{CommandSource, ControlCommand, NoCommands};
    use penelope_rt_core::stop::StopAwareCommands;

    #[test]
    fn a_stop_reaches_only_registered_loops_and_reports_who_acted() {
        let board = StopBoard::default();
        let a = Arc::new(StopLatch::new());
        let b = Arc::new(StopLatch::new());
        board.insert("a", a.clone());
        board.insert("b", b.clone());
        let mut port_a = StopAwareCommands::new(NoCommands, a.clone());
        assert_eq!(board.stop("nobody", Duration::ZERO), None);
        // Nobody ticks: the request stands, unacknowledged.
        assert_eq!(board.stop("a", Duration::ZERO), Some(false));
        assert_eq!(port_a.next_command(), Some(ControlCommand::EStop));
        let report = std::thread::scope(|s| {
            let ticker = s.spawn(move || {
                // Loop `a` ticks; `b` never does.
                let deadline = Instant::now() + Duration::from_secs(5);
                while Instant::now() < deadline {
                    if port_a.next_command() == Some(ControlCommand::EStop) {
                        return true;
                    }
                    std::thread::yield_now();
                }
                false
            });
            let report = board.stop_all("n", Duration::from_secs(1));
            assert!(ticker.join().unwrap());
            report
        });
        assert_eq!(report.stopped, vec!["a".to_string()]);
        assert_eq!(report.pending, vec!["b".to_string()]);
        board.remove("a");
        assert_eq!(board.names(), vec!["b".to_string()]);
    }
}
