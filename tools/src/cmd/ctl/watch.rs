//! `ctl watch`: a controller's control ticks, or a channel's link records, one line (or one
//! JSON object) each, until `--count` or `--seconds`.

use std::io::Write;
use std::time::{Duration, Instant};

use penelope_protocol::client::{Streamed, Subscription};
use penelope_protocol::proto::{Class, LinkRecord, TelemetryRecord};
use penelope_runtime::objects::runtime::LINK_PERIOD;
use serde::Serialize;

use super::{Ctl, show};
use crate::cmd::usage;

/// When a watch ends.
struct Until {
    count: Option<u64>,
    limit: Option<Duration>,
}

/// A record `watch` prints: its time, its line for humans, and what the user should check when
/// none come.
trait Watched: Streamed + Serialize {
    /// What the records are, in messages.
    const WHAT: &'static str;
    /// What to check when none come.
    const HINT: &'static str;
    /// Its time, ns on the node's clock.
    fn time_ns(&self) -> u64;
    /// Its line, the time counted from `t0_ns`.
    fn line(&self, t0_ns: u64) -> String;
}

impl Watched for TelemetryRecord {
    const WHAT: &'static str = "telemetry";
    const HINT: &'static str = "is its control loop running?";
    fn time_ns(&self) -> u64 {
        self.time_ns
    }
    fn line(&self, t0_ns: u64) -> String {
        show::telemetry(self, t0_ns)
    }
}

impl Watched for LinkRecord {
    const WHAT: &'static str = "link records";
    const HINT: &'static str = "is a loop running on its end?";
    fn time_ns(&self) -> u64 {
        self.time_ns
    }
    fn line(&self, t0_ns: u64) -> String {
        show::link(self, t0_ns)
    }
}

impl Ctl {
    /// Watches the object at `path`: a channel's link (records every 100 ms times
    /// `decimation`), or a controller's (or robot's) ticks.
    pub(super) fn watch(
        &mut self,
        path: &str,
        decimation: u32,
        count: Option<u64>,
        seconds: Option<f64>,
        json: bool,
        in_script: bool,
    ) -> anyhow::Result<()> {
        if in_script && count.is_none() && seconds.is_none() {
            return Err(usage("in a script, `watch` needs --count or --seconds"));
        }
        let limit = match seconds {
            Some(s) if !(s.is_finite() && s > 0.0) => {
                return Err(usage(format!("--seconds must be > 0, got {s}")));
            }
            Some(s) => Some(Duration::from_secs_f64(s)),
            None => None,
        };
        let until = Until { count, limit };
        let client = self.client()?;
        let decimation = decimation.max(1);
        if client.locate(path)?.class == Class::Trajectory {
            let every = LINK_PERIOD.saturating_mul(decimation);
            let mut stream = client.watch_link(path, decimation)?;
            let what = format!("one record every {} ms", every.as_millis());
            // A record is due every period: silence for two of them (or the timeout) is a
            // stall, not a slow link.
            let stall = self.config.timeout.max(2 * every);
            follow(&mut stream, &until, &what, stall, json)
        } else {
            let mut stream = client.subscribe(path, decimation)?;
            let what = format!("one tick in {decimation}");
            follow(&mut stream, &until, &what, self.config.timeout, json)
        }
    }
}

/// Prints `stream`'s records until `until`; fails when none came for `stall`.
fn follow<R: Watched>(
    stream: &mut Subscription<R>,
    until: &Until,
    what: &str,
    stall: Duration,
    json: bool,
) -> anyhow::Result<()> {
    // Said once the node has acknowledged the subscription, also with `--json` (whose records
    // go to stdout): a script can wait for this line before it makes the node produce records.
    eprintln!(
        "watching {} ({what}){}",
        stream.path(),
        if until.count.is_none() && until.limit.is_none() {
            "; Ctrl-C to stop"
        } else {
            ""
        }
    );
    let start = Instant::now();
    let mut last = Instant::now();
    let mut t0 = None;
    let mut n = 0u64;
    let mut out = std::io::stdout().lock();
    loop {
        if until.count.is_some_and(|c| n >= c) {
            break;
        }
        let mut wait = Duration::from_millis(100);
        if let Some(limit) = until.limit {
            let left = limit.saturating_sub(start.elapsed());
            if left.is_zero() {
                break;
            }
            wait = wait.min(left);
        }
        match stream.recv_timeout(wait)? {
            Some(rec) => {
                n += 1;
                last = Instant::now();
                let t0 = *t0.get_or_insert(rec.time_ns());
                if json {
                    writeln!(out, "{}", serde_json::to_string(&rec)?)?;
                } else {
                    writeln!(out, "{}", rec.line(t0))?;
                }
                out.flush()?;
            }
            None if last.elapsed() >= stall => {
                anyhow::bail!(
                    "no {} from {} for {:.1} s: {}",
                    R::WHAT,
                    stream.path(),
                    stall.as_secs_f64(),
                    R::HINT
                );
            }
            None => {}
        }
    }
    if n == 0 {
        anyhow::bail!("no {} from {}: {}", R::WHAT, stream.path(), R::HINT);
    }
    if stream.dropped() > 0 && !json {
        eprintln!(
            "{} batch(es) dropped by the node because this side read too slowly",
            stream.dropped()
        );
    }
    Ok(())
}
