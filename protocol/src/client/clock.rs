//! The system's common clock as a client's host sees it.
//!
//! The common clock is the monotonic clock of the naming service's host (the nodes estimate
//! their offset to it, and stamp frames, telemetry and recordings on it). A view that says
//! "video 62 ms behind the hand" compares a frame's capture instant, on the common clock, with
//! the instant it displays the frame, on its own host's clock: on another host than the naming
//! service's the two differ by however long apart the hosts booted. So a client estimates its
//! own offset the way a node does: [`Call::Time`] exchanges with four timestamps through the
//! filter of [`LinkClock`] (the exchange with the least round trip of the last eight), and
//! [`CommonClockView`] keeps the estimate fresh on a thread of its own while it lives.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread::JoinHandle;
use std::time::Duration;

use super::Client;
use crate::link_clock::{FILTER_LEN, LinkClock};
use crate::net::conn::RpcError;
use crate::proto::{Call, Reply};

/// How often a [`CommonClockView`] makes one more exchange: clocks of two hosts drift apart by
/// tens of microseconds a second at most, well under what a view shows.
pub const REFRESH: Duration = Duration::from_secs(1);

/// This host's `CLOCK_MONOTONIC` now, ns (the clock the nodes stamp with, before their offset).
pub fn monotonic_now_ns() -> u64 {
    nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC)
        .map(|t| {
            u64::try_from(t.tv_sec())
                .unwrap_or(0)
                .saturating_mul(1_000_000_000)
                .saturating_add(u64::try_from(t.tv_nsec()).unwrap_or(0))
        })
        .unwrap_or(0)
}

fn now_i64() -> i64 {
    i64::try_from(monotonic_now_ns()).unwrap_or(i64::MAX)
}

/// The server at `address`'s receive and answer times of one [`Call::Time`] (`t2`, `t3` of a
/// four-timestamp exchange, on its clock): what a node's and a client's exchanges both ask.
///
/// # Errors
/// The transport's, or [`RpcError::Protocol`] for an answer that is not a time.
pub fn ask_time(client: &Client, address: SocketAddr) -> Result<(i64, i64), RpcError> {
    match client.call_at(address, Call::Time)? {
        Reply::Time {
            received_ns,
            sent_ns,
        } => Ok((received_ns, sent_ns)),
        other => Err(RpcError::Protocol(format!(
            "{address} answered a time call with {other:?}"
        ))),
    }
}

/// One exchange of times with the server at `address`, taken into `clock` (`seq`: its number).
fn exchange(
    client: &Client,
    address: SocketAddr,
    clock: &mut LinkClock,
    seq: u64,
) -> Result<(), RpcError> {
    let t1 = now_i64();
    clock.note_sent(seq, t1);
    let (t2, t3) = ask_time(client, address)?;
    let t4 = now_i64();
    clock
        .note_answer(seq, t2, t3, t4)
        .map(drop)
        .map_err(|e| RpcError::Protocol(format!("{address}'s time answer refused: {e}")))
}

/// [`FILTER_LEN`] exchanges with the server at `address` into a new filter; an implausible
/// answer is skipped (the filter counts it), a transport error ends it.
///
/// # Errors
/// The transport's, or [`RpcError::Protocol`] when no answer was a plausible time.
fn estimate(client: &Client, address: SocketAddr) -> Result<LinkClock, RpcError> {
    let mut clock = LinkClock::new();
    let mut refused = None;
    for seq in 0..FILTER_LEN as u64 {
        match exchange(client, address, &mut clock, seq) {
            Ok(()) => {}
            Err(e @ RpcError::Protocol(_)) => refused = Some(e),
            Err(e) => return Err(e),
        }
    }
    match clock.offset() {
        Some(_) => Ok(clock),
        None => {
            Err(refused.unwrap_or_else(|| RpcError::Protocol(format!("no time from {address}"))))
        }
    }
}

/// The clock of the server at `address` less this host's monotonic clock, ns, and the round
/// trip of the exchange it comes from: [`FILTER_LEN`] exchanges, the least round trip's wins.
///
/// # Errors
/// The transport's, or [`RpcError::Protocol`] when no answer was a plausible time.
pub fn offset_to(client: &Client, address: SocketAddr) -> Result<(i64, i64), RpcError> {
    let clock = estimate(client, address)?;
    Ok((
        clock.offset().unwrap_or_default(),
        clock.delay().unwrap_or_default(),
    ))
}

/// The common clock on this host, kept fresh: an estimate of the naming service's clock less
/// this host's, refreshed every [`REFRESH`] by a thread that ends when the view is dropped.
/// A failed refresh keeps the last estimate (logged at debug level).
#[derive(Debug)]
pub struct CommonClockView {
    offset_ns: Arc<AtomicI64>,
    stop: Option<mpsc::Sender<()>>,
    refresher: Option<JoinHandle<()>>,
}

impl CommonClockView {
    /// Estimates the common clock through `client`'s naming service ([`FILTER_LEN`] exchanges
    /// now), then keeps it fresh every `refresh`.
    ///
    /// # Errors
    /// As [`offset_to`]: the first estimate failed.
    pub fn follow(client: &Client, refresh: Duration) -> Result<Self, RpcError> {
        let address = client.naming_address();
        let mut clock = estimate(client, address)?;
        let mut seq = FILTER_LEN as u64;
        let first = clock.offset().unwrap_or_default();
        let offset_ns = Arc::new(AtomicI64::new(first));
        let (stop, stopped) = mpsc::channel();
        let (shared, client) = (offset_ns.clone(), client.clone());
        let refresher = std::thread::Builder::new()
            .name("common-clock".into())
            .spawn(move || {
                while let Err(RecvTimeoutError::Timeout) = stopped.recv_timeout(refresh) {
                    match exchange(&client, address, &mut clock, seq) {
                        Ok(()) => {
                            if let Some(offset) = clock.offset() {
                                shared.store(offset, Ordering::Release);
                            }
                        }
                        Err(e) => log::debug!("common clock: no exchange with {address}: {e}"),
                    }
                    seq += 1;
                }
            })
            .map_err(|e| RpcError::Protocol(format!("cannot start the clock's thread: {e}")))?;
        Ok(CommonClockView {
            offset_ns,
            stop: Some(stop),
            refresher: Some(refresher),
        })
    }

    /// A view whose offset is fixed (tests, and a process on the naming service's host that
    /// knows it is the common clock: `0`).
    pub fn fixed(offset_ns: i64) -> Self {
        CommonClockView {
            offset_ns: Arc::new(AtomicI64::new(offset_ns)),
            stop: None,
            refresher: None,
        }
    }

    /// Whether this view refreshes its estimate (made by [`follow`](Self::follow)).
    pub fn is_followed(&self) -> bool {
        self.refresher.is_some()
    }

    /// The common clock less this host's monotonic clock, ns.
    pub fn offset_ns(&self) -> i64 {
        self.offset_ns.load(Ordering::Acquire)
    }

    /// This host's monotonic time `local_ns` on the common clock.
    pub fn to_common(&self, local_ns: u64) -> u64 {
        local_ns.saturating_add_signed(self.offset_ns())
    }

    /// Now, on the common clock.
    pub fn now_ns(&self) -> u64 {
        self.to_common(monotonic_now_ns())
    }
}

impl Drop for CommonClockView {
    fn drop(&mut self) {
        drop(self.stop.take());
        if let Some(refresher) = self.refresher.take() {
            let _ = refresher.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::conn::ClientConfig;
    use crate::net::server::{Server, ServerConfig};
    use crate::proto::{CallError, WireError};
    use crate::service::{Service, Session};

    /// A naming service whose host booted the given nanoseconds before this one (its clock
    /// reads that much more), and which answers nothing but the time.
    struct BootedEarlier(i64);

    impl Service for BootedEarlier {
        fn call(&self, _: &Session, call: Call) -> Result<Reply, WireError> {
            match call {
                Call::Time => {
                    let now = now_i64() + self.0;
                    Ok(Reply::Time {
                        received_ns: now,
                        sent_ns: now,
                    })
                }
                _ => Err(WireError::Call(CallError::NotReady("time only".into()))),
            }
        }
    }

    const AHEAD_NS: i64 = 3_600_000_000_000;

    fn naming_ahead() -> (Server, Client) {
        let server = Server::bind(
            "127.0.0.1:0".parse().unwrap(),
            ServerConfig::new("naming"),
            Arc::new(BootedEarlier(AHEAD_NS)),
        )
        .unwrap();
        let client = Client::connect(server.local_addr(), ClientConfig::new("view")).unwrap();
        (server, client)
    }

    #[test]
    fn a_view_on_another_host_reads_the_naming_hosts_clock_to_within_its_round_trip() {
        let (_server, client) = naming_ahead();
        let (offset, round_trip) = offset_to(&client, client.naming_address()).unwrap();
        assert!(round_trip >= 0);
        // The exchange's error is at most half its round trip (plus the clock reads' order).
        assert!(
            (offset - AHEAD_NS).abs() <= round_trip / 2 + 1_000,
            "offset {offset}, round trip {round_trip}"
        );
        let view = CommonClockView::follow(&client, Duration::from_millis(5)).unwrap();
        assert!(view.is_followed());
        let local = monotonic_now_ns();
        let common = view.now_ns();
        let apart = i64::try_from(common - local).unwrap();
        assert!((apart - AHEAD_NS).abs() < 50_000_000, "{apart}");
        // Its refresher ends with it.
        drop(view);
    }

    #[test]
    fn a_fixed_view_adds_its_offset_and_a_monotonic_clock_moves_forward() {
        let view = CommonClockView::fixed(-5_000);
        assert_eq!(view.to_common(1_000_000), 995_000);
        assert!(!view.is_followed());
        let (a, b) = (monotonic_now_ns(), monotonic_now_ns());
        assert!(a > 0 && b >= a);
    }

    #[test]
    fn a_server_that_will_not_tell_the_time_is_a_typed_error() {
        let server = Server::bind(
            "127.0.0.1:0".parse().unwrap(),
            ServerConfig::new("mute"),
            Arc::new(Mute),
        )
        .unwrap();
        let client = Client::connect(server.local_addr(), ClientConfig::new("view")).unwrap();
        assert!(matches!(
            CommonClockView::follow(&client, REFRESH),
            Err(RpcError::Remote(_))
        ));
    }

    struct Mute;

    impl Service for Mute {
        fn call(&self, _: &Session, _: Call) -> Result<Reply, WireError> {
            Err(WireError::Call(CallError::NotReady("no time here".into())))
        }
    }
}
