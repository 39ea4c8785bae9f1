//! The bounds of a server that must hold under attack: who gets a connection slot, and how many
//! requests a connection may make.
//!
//! # Admission
//! Connections that have not finished their handshake (*pending*) and sessions (past it) have
//! separate pools, so silent, slow or flooding connections, which never finish a handshake
//! without the secret, can never take a session's slot:
//! - pending: at most [`Admission::max_pending`] in all and [`Admission::max_pending_per_peer`]
//!   per IP address. At either bound a newcomer is admitted and another pending connection (of
//!   the same address at the per-address bound, else of the address holding most) is evicted,
//!   in this order of preference: a *silent* one (no valid hello yet, no byte waiting) older than
//!   [`GRACE`], the oldest first; a silent one younger than that, the youngest first (a flood
//!   churns its own newest connections, while a connection that just arrived keeps [`GRACE`] to
//!   say its hello); one that sent bytes but no valid hello, the oldest first; the oldest. The
//!   evicted connection gets [`WireError::TooManyConnections`] and is closed. So a silent
//!   connection holds a slot only until newer ones arrive or its handshake time runs out, and an
//!   operator's connection, which says its hello at once and finishes in a round trip, gets
//!   through floods of silent connections from any address and through any flood of another
//!   address. What it cannot outlast is a flood from its own address of connections that say a
//!   valid hello and then stall;
//! - sessions: at most `max_sessions`, of which `admin_reserve` only for [`Role::Admin`]
//!   sessions, so that members holding the system secret cannot lock the administrator out.
//!
//! Threads follow: one per pending connection and two per session.

use std::collections::VecDeque;
use std::net::{IpAddr, Shutdown, TcpStream};
use std::os::fd::AsFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use nix::poll::{PollFd, PollFlags, PollTimeout, poll};

use crate::proto::{Role, WireError};

/// A pending connection, as admission tracks it.
struct Pending {
    id: u64,
    peer: IpAddr,
    evicted: Arc<AtomicBool>,
    /// The connection said a valid hello (evicted after the silent ones).
    greeted: Arc<AtomicBool>,
    /// When it was admitted.
    since: Instant,
    /// A handle on the socket, to wake its thread when evicted.
    stream: TcpStream,
}

#[derive(Default)]
struct State {
    /// Oldest first.
    pending: VecDeque<Pending>,
    sessions: u32,
}

/// Connection slots of one server (see the module's rules).
pub struct Admission {
    /// Pending connections at most, in all.
    pub max_pending: u32,
    /// Pending connections at most per IP address.
    pub max_pending_per_peer: u32,
    /// Sessions at most, in all.
    pub max_sessions: u32,
    /// Of `max_sessions`, the slots only [`Role::Admin`] sessions may take.
    pub admin_reserve: u32,
    state: Mutex<State>,
}

impl std::fmt::Debug for Admission {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = self.lock();
        f.debug_struct("Admission")
            .field("pending", &s.pending.len())
            .field("sessions", &s.sessions)
            .finish()
    }
}

/// What [`Admission::admit`] did.
#[derive(Debug)]
pub struct Admitted {
    /// Set when this connection is evicted later: its thread ends it.
    pub evicted: Arc<AtomicBool>,
    /// To set once the connection said a valid hello: it is then evicted after silent ones.
    pub greeted: Arc<AtomicBool>,
    /// Connections evicted to make room for this one.
    pub evictions: u32,
}

impl Admission {
    /// Slots for `max_sessions` sessions (of which `admin_reserve` for administrators) and
    /// `max_pending` pending connections (`max_pending_per_peer` per address).
    pub fn new(max_sessions: u32, admin_reserve: u32, max_pending: u32, per_peer: u32) -> Self {
        Admission {
            max_pending: max_pending.max(1),
            max_pending_per_peer: per_peer.max(1),
            max_sessions,
            admin_reserve: admin_reserve.min(max_sessions),
            state: Mutex::new(State::default()),
        }
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Admits a new pending connection `id` from `peer`, evicting others as the bounds require.
    /// `stream` is a handle on its socket.
    pub fn admit(&self, id: u64, peer: IpAddr, stream: TcpStream) -> Admitted {
        self.admit_at(id, peer, stream, Instant::now())
    }

    /// [`admit`](Self::admit) at time `now` (for tests: ages are measured from it).
    pub fn admit_at(&self, id: u64, peer: IpAddr, stream: TcpStream, now: Instant) -> Admitted {
        let mut s = self.lock();
        let mut evictions = 0;
        let of_peer = |s: &State, ip: IpAddr| s.pending.iter().filter(|p| p.peer == ip).count();
        while of_peer(&s, peer) >= self.max_pending_per_peer as usize {
            let at = victim(&s, peer, now);
            evict(&mut s, at);
            evictions += 1;
        }
        while s.pending.len() >= self.max_pending as usize {
            // A connection of the address that holds most.
            let busiest = s
                .pending
                .iter()
                .map(|p| p.peer)
                .max_by_key(|ip| of_peer(&s, *ip))
                .unwrap_or(peer);
            let at = victim(&s, busiest, now);
            evict(&mut s, at);
            evictions += 1;
        }
        let evicted = Arc::new(AtomicBool::new(false));
        let greeted = Arc::new(AtomicBool::new(false));
        s.pending.push_back(Pending {
            id,
            peer,
            evicted: evicted.clone(),
            greeted: greeted.clone(),
            since: now,
            stream,
        });
        Admitted {
            evicted,
            greeted,
            evictions,
        }
    }

    /// The pending connection `id` ended without becoming a session.
    pub fn abandon(&self, id: u64) {
        let mut s = self.lock();
        s.pending.retain(|p| p.id != id);
    }

    /// The pending connection `id` finished its handshake as `role`: a session slot, or
    /// [`WireError::TooManyConnections`] (the connection is no longer pending either way).
    ///
    /// # Errors
    /// [`WireError::TooManyConnections`] when the sessions this role may take are all in use.
    pub fn open_session(&self, id: u64, role: Role) -> Result<(), WireError> {
        let mut s = self.lock();
        s.pending.retain(|p| p.id != id);
        let limit = if role == Role::Admin {
            self.max_sessions
        } else {
            self.max_sessions - self.admin_reserve
        };
        if s.sessions >= limit {
            return Err(WireError::TooManyConnections { limit });
        }
        s.sessions += 1;
        Ok(())
    }

    /// A session ended.
    pub fn close_session(&self) {
        let mut s = self.lock();
        s.sessions = s.sessions.saturating_sub(1);
    }

    /// Pending connections and sessions now.
    pub fn counts(&self) -> (u32, u32) {
        let s = self.lock();
        (s.pending.len() as u32, s.sessions)
    }
}

/// How long a connection that just arrived is spared, while silent ones older than this are
/// there to evict: time to say its hello.
pub const GRACE: Duration = Duration::from_millis(250);

/// Which pending connection of `peer` to evict (the module's order of preference; should `peer`
/// hold none, the oldest of all).
fn victim(s: &State, peer: IpAddr, now: Instant) -> usize {
    let of_peer = || s.pending.iter().enumerate().filter(|(_, p)| p.peer == peer);
    let greeted = |p: &Pending| p.greeted.load(Ordering::Acquire);
    let silent = |p: &Pending| !greeted(p) && !readable(&p.stream);
    let old = |p: &Pending| now.saturating_duration_since(p.since) >= GRACE;
    of_peer()
        .find(|(_, p)| silent(p) && old(p))
        .or_else(|| of_peer().rfind(|(_, p)| silent(p)))
        .or_else(|| of_peer().find(|(_, p)| !greeted(p)))
        .or_else(|| of_peer().next())
        .map_or(0, |(at, _)| at)
}

/// Whether bytes (or the end of the stream) wait on `stream`, without reading or waiting.
fn readable(stream: &TcpStream) -> bool {
    let mut fds = [PollFd::new(stream.as_fd(), PollFlags::POLLIN)];
    matches!(poll(&mut fds, PollTimeout::ZERO), Ok(n) if n > 0)
}

fn evict(s: &mut State, at: usize) {
    if let Some(p) = s.pending.remove(at) {
        p.evicted.store(true, Ordering::Release);
        // Wake its thread (a read returns at once); it sends the error and closes.
        let _ = p.stream.shutdown(Shutdown::Read);
    }
}

/// Requests per second with bursts up to one second's worth.
#[derive(Debug)]
pub struct TokenBucket {
    /// The rate, requests per second.
    pub rate: u32,
    tokens: f64,
    last: Instant,
}

impl TokenBucket {
    /// A full bucket of `rate` requests per second.
    pub fn new(rate: u32) -> Self {
        TokenBucket {
            rate,
            tokens: f64::from(rate.max(1)),
            last: Instant::now(),
        }
    }

    /// Takes a token at `now`; `false` if none is left.
    pub fn take(&mut self, now: Instant) -> bool {
        let rate = f64::from(self.rate.max(1));
        let dt = now.saturating_duration_since(self.last).as_secs_f64();
        self.last = now;
        self.tokens = (self.tokens + dt * rate).min(rate);
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use std::net::TcpListener;

    use super::*;

    fn socket(l: &TcpListener) -> TcpStream {
        TcpStream::connect(l.local_addr().unwrap()).unwrap()
    }

    #[test]
    fn silent_pending_connections_make_room_per_peer_and_in_all() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let a: IpAddr = "10.0.0.1".parse().unwrap();
        let b: IpAddr = "10.0.0.2".parse().unwrap();
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let adm = Admission::new(4, 1, 3, 2);
        let a1 = adm.admit_at(1, a, socket(&l), at(0));
        let a2 = adm.admit_at(2, a, socket(&l), at(10));
        assert_eq!(adm.counts(), (2, 0));
        // A third from `a`, a second later: a's oldest silent one goes.
        let a3 = adm.admit_at(3, a, socket(&l), at(1000));
        assert_eq!(a3.evictions, 1);
        assert!(a1.evicted.load(Ordering::Acquire));
        assert!(!a2.evicted.load(Ordering::Acquire));
        // The oldest said its hello; the other is silent but young: the youngest silent goes.
        a2.greeted.store(true, Ordering::Release);
        let a4 = adm.admit_at(4, a, socket(&l), at(1010));
        assert!(a3.evicted.load(Ordering::Acquire));
        assert!(!a2.evicted.load(Ordering::Acquire));
        // `b` fills the pool, then its second connection evicts from `a` (which holds most): its
        // silent one, now old.
        let b1 = adm.admit_at(5, b, socket(&l), at(1020));
        assert_eq!(b1.evictions, 0);
        let b2 = adm.admit_at(6, b, socket(&l), at(2000));
        assert_eq!(b2.evictions, 1);
        assert!(a4.evicted.load(Ordering::Acquire));
        assert!(!a2.evicted.load(Ordering::Acquire));
        assert_eq!(adm.counts(), (3, 0));
        // Sessions: three for anyone, the fourth only for an administrator.
        for id in [2, 5, 6] {
            adm.open_session(id, Role::Node).unwrap();
        }
        assert_eq!(
            adm.open_session(7, Role::Reader),
            Err(WireError::TooManyConnections { limit: 3 })
        );
        adm.open_session(8, Role::Admin).unwrap();
        assert!(adm.open_session(9, Role::Admin).is_err());
        adm.close_session();
        assert_eq!(adm.counts(), (0, 3));
    }

    #[test]
    fn a_connection_whose_hello_is_waiting_is_not_taken_for_a_silent_one() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let ip: IpAddr = "10.0.0.1".parse().unwrap();
        let adm = Admission::new(4, 0, 8, 2);
        let talking = socket(&l);
        let (mut server_end, _) = l.accept().unwrap();
        std::io::Write::write_all(&mut server_end, b"hello").unwrap();
        let silent = socket(&l);
        // Wait (bounded) until the bytes are there to read.
        let deadline = Instant::now() + Duration::from_secs(2);
        while !readable(&talking) {
            assert!(Instant::now() < deadline, "the bytes never arrived");
            std::thread::sleep(Duration::from_millis(1));
        }
        let first = adm.admit(1, ip, talking);
        let second = adm.admit(2, ip, silent);
        let third = adm.admit(3, ip, socket(&l));
        assert_eq!(third.evictions, 1);
        assert!(
            !first.evicted.load(Ordering::Acquire),
            "it has its hello waiting"
        );
        assert!(second.evicted.load(Ordering::Acquire));
    }

    #[test]
    fn the_token_bucket_allows_a_burst_then_the_rate() {
        let t0 = Instant::now();
        let mut b = TokenBucket::new(10);
        b.last = t0;
        let allowed = (0..20).filter(|_| b.take(t0)).count();
        assert_eq!(allowed, 10);
        assert!(b.take(t0 + Duration::from_millis(150)));
        assert!(!b.take(t0 + Duration::from_millis(150)));
    }
}
