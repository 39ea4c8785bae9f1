//! Waiting for a condition, never for a length of time.
//!
//! A test on a loaded two-core machine cannot know how long a process takes to start or a
//! thread to be scheduled; it can only poll what it waits for. The bound is generous: it ends a
//! test that would otherwise hang, and is never what makes a test pass.

use std::time::{Duration, Instant};

/// How long [`wait_until`] waits before it declares the condition never met.
pub const PATIENCE: Duration = Duration::from_secs(20);

/// How often a condition is polled: short against the times tests measure, long enough not to
/// steal a core from the code under test.
pub const POLL: Duration = Duration::from_millis(1);

/// Polls `done` until it holds; panics naming `what` after [`PATIENCE`].
pub fn wait_until(what: &str, done: impl FnMut() -> bool) {
    wait_within(PATIENCE, what, done);
}

/// Polls `done` until it holds; panics naming `what` after `patience`. Returns how long it took.
pub fn wait_within(patience: Duration, what: &str, mut done: impl FnMut() -> bool) -> Duration {
    let start = Instant::now();
    while !done() {
        assert!(
            start.elapsed() < patience,
            "never happened within {patience:?}: {what}"
        );
        std::thread::sleep(POLL);
    }
    start.elapsed()
}

/// Polls `get` until it returns a value; panics naming `what` after [`PATIENCE`].
pub fn wait_for<T>(what: &str, mut get: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + PATIENCE;
    loop {
        if let Some(v) = get() {
            return v;
        }
        assert!(
            Instant::now() < deadline,
            "never happened within {PATIENCE:?}: {what}"
        );
        std::thread::sleep(POLL);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_condition_met_later_is_waited_for() {
        let mut polls = 0;
        let took = wait_within(Duration::from_secs(5), "the third poll", || {
            polls += 1;
            polls == 3
        });
        assert_eq!(polls, 3);
        assert!(took >= 2 * POLL);
        assert_eq!(wait_for("a value", || Some(7)), 7);
    }

    #[test]
    #[should_panic(expected = "never happened within")]
    fn a_condition_never_met_fails_the_test() {
        wait_within(Duration::from_millis(20), "nothing", || false);
    }
}
