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
//!   evicted connection gets [`ProtocolError::TooManyConnections`] and is closed. So a silent
//!   connection holds a slot only until newer ones arrive or its handshake time runs out, and an
//!   operator's connection, which says its hello at once and finishes in a round trip, gets
//!   through floods of silent connections from any address and through any flood of another
//!   address. What it cannot outlast is a flood from its own address of connections that say a
//!   valid hello and then stall;
//! - sessions: at most `max_sessions`, of which `admin_reserve` only for [`Role::Admin`]
//!   sessions, so that members holding the system secret cannot lock the administrator out. A
//!   connection becomes a session only once it has proven the secret with a message an
//!   eavesdropper cannot replay (see `server/handshake.rs`). When the sessions a newcomer may
//!   take are all in use, and its address holds fewer than [`Admission::sessions_per_peer`], a
//!   session of the address holding most beyond that quota is evicted for it (the one idle the
//!   longest; never an administrator's) before anyone is refused: one address cannot keep
//!   another out by holding every slot, idle or not, while an address under its quota keeps
//!   what it holds.
//!
//! Threads follow: one per pending connection and two per session.

use std::collections::VecDeque;
use std::net::{IpAddr, Shutdown, TcpStream};
use std::os::fd::AsFd;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use nix::poll::{PollFd, PollFlags, PollTimeout, poll};

use crate::proto::{ProtocolError, Role, WireError};

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

/// A session (a connection past its handshake), as admission tracks it.
struct SessionSlot {
    id: u64,
    peer: IpAddr,
    role: Role,
    evicted: Arc<AtomicBool>,
    /// Milliseconds (of the server's clock) of the last frame in either direction.
    activity: Arc<AtomicU64>,
    stream: TcpStream,
}

#[derive(Default)]
struct State {
    /// Oldest first.
    pending: VecDeque<Pending>,
    sessions: Vec<SessionSlot>,
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
    /// Sessions of one IP address that are safe from eviction when the pool is full (an
    /// address may hold more while there is room).
    pub sessions_per_peer: u32,
    state: Mutex<State>,
}

impl std::fmt::Debug for Admission {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = self.lock();
        f.debug_struct("Admission")
            .field("pending", &s.pending.len())
            .field("sessions", &s.sessions.len())
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
    /// `max_pending` pending connections (`max_pending_per_peer` per address); no session is
    /// evicted for another until its address holds more than `sessions_per_peer`.
    pub fn new(
        max_sessions: u32,
        admin_reserve: u32,
        max_pending: u32,
        per_peer: u32,
        sessions_per_peer: u32,
    ) -> Self {
        Admission {
            max_pending: max_pending.max(1),
            max_pending_per_peer: per_peer.max(1),
            max_sessions,
            admin_reserve: admin_reserve.min(max_sessions),
            sessions_per_peer: sessions_per_peer.max(1),
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

    /// The pending connection `id` proved who it is as `role`: a session slot (evicting a
    /// session of an address over its quota if the pool is full, see the module's rules), or
    /// [`ProtocolError::TooManyConnections`] (the connection is no longer pending either way).
    /// `activity` is the session's clock of its last frame (the longest idle is evicted first).
    ///
    /// # Errors
    /// [`ProtocolError::TooManyConnections`] when the sessions this role may take are all in use
    /// and none may be evicted for it; [`ProtocolError::Unexpected`] if `id` was not pending (it
    /// was evicted meanwhile).
    pub fn open_session(
        &self,
        id: u64,
        role: Role,
        activity: Arc<AtomicU64>,
    ) -> Result<(), WireError> {
        let mut s = self.lock();
        let Some(at) = s.pending.iter().position(|p| p.id == id) else {
            return Err(WireError::Protocol(ProtocolError::TooManyConnections {
                limit: self.max_pending,
            }));
        };
        let Some(p) = s.pending.remove(at) else {
            return Err(WireError::Protocol(ProtocolError::TooManyConnections {
                limit: self.max_pending,
            }));
        };
        let limit = if role == Role::Admin {
            self.max_sessions
        } else {
            self.max_sessions - self.admin_reserve
        };
        let in_use = |s: &State| {
            if role == Role::Admin {
                s.sessions.len()
            } else {
                // Admin sessions use the reserve first.
                let admins = s.sessions.iter().filter(|x| x.role == Role::Admin).count();
                s.sessions.len() - admins.min(self.admin_reserve as usize)
            }
        };
        if in_use(&s) >= limit as usize {
            match self.session_victim(&s, p.peer) {
                Some(v) => {
                    let victim = s.sessions.swap_remove(v);
                    victim.evicted.store(true, Ordering::Release);
                    // Wake its reader (a read returns at once): it says why and closes.
                    let _ = victim.stream.shutdown(Shutdown::Read);
                    log::warn!(
                        "session {} of {} ({} sessions) evicted for {}",
                        victim.id,
                        victim.peer,
                        of_peer_sessions(&s, victim.peer) + 1,
                        p.peer
                    );
                }
                None => {
                    return Err(WireError::Protocol(ProtocolError::TooManyConnections {
                        limit,
                    }));
                }
            }
        }
        s.sessions.push(SessionSlot {
            id,
            peer: p.peer,
            role,
            evicted: p.evicted,
            activity,
            stream: p.stream,
        });
        Ok(())
    }

    /// The session to evict for a newcomer from `peer`: none if `peer` already holds its quota;
    /// else, of the address holding most sessions beyond the quota, its session idle the longest
    /// (administrators' sessions are never evicted).
    fn session_victim(&self, s: &State, peer: IpAddr) -> Option<usize> {
        let quota = self.sessions_per_peer as usize;
        if of_peer_sessions(s, peer) >= quota {
            return None;
        }
        let busiest = s
            .sessions
            .iter()
            .filter(|x| x.role != Role::Admin)
            .map(|x| x.peer)
            .max_by_key(|ip| of_peer_sessions(s, *ip))?;
        if of_peer_sessions(s, busiest) <= quota {
            return None;
        }
        s.sessions
            .iter()
            .enumerate()
            .filter(|(_, x)| x.peer == busiest && x.role != Role::Admin)
            .min_by_key(|(_, x)| x.activity.load(Ordering::Relaxed))
            .map(|(at, _)| at)
    }

    /// The session `id` ended (a no-op for one already evicted).
    pub fn close_session(&self, id: u64) {
        let mut s = self.lock();
        s.sessions.retain(|x| x.id != id);
    }

    /// Pending connections and sessions now.
    pub fn counts(&self) -> (u32, u32) {
        let s = self.lock();
        (s.pending.len() as u32, s.sessions.len() as u32)
    }
}

fn of_peer_sessions(s: &State, peer: IpAddr) -> usize {
    s.sessions.iter().filter(|x| x.peer == peer).count()
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

/// Failed handshakes per IP address: a token bucket per address (`burst` tokens, `per_s` back
/// a second) that each failure empties by one; an address with no token left is refused before
/// its secret is checked, so guessing a secret online runs at `per_s` guesses a second per
/// address instead of as fast as the node can answer. Addresses whose bucket is full again are
/// forgotten, so the table stays small.
pub struct AuthThrottle {
    burst: f64,
    per_s: f64,
    table: Mutex<std::collections::HashMap<IpAddr, (f64, Instant)>>,
}

impl std::fmt::Debug for AuthThrottle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AuthThrottle")
            .field("burst", &self.burst)
            .field("per_s", &self.per_s)
            .finish()
    }
}

/// Addresses tracked before the full buckets are swept out.
const THROTTLE_SWEEP_AT: usize = 4096;

impl AuthThrottle {
    /// `burst` failures at once per address, then `per_s` a second.
    pub fn new(burst: u32, per_s: f64) -> Self {
        let per_s = if per_s.is_finite() && per_s > 0.0 {
            per_s
        } else {
            1.0
        };
        AuthThrottle {
            burst: f64::from(burst.max(1)),
            per_s,
            table: Mutex::new(std::collections::HashMap::new()),
        }
    }

    fn tokens(&self, entry: (f64, Instant), now: Instant) -> f64 {
        let dt = now.saturating_duration_since(entry.1).as_secs_f64();
        (entry.0 + dt * self.per_s).min(self.burst)
    }

    /// Whether `peer` may try a handshake at `now` (it has a failure left to spend).
    pub fn allows(&self, peer: IpAddr, now: Instant) -> bool {
        let table = self.table.lock().unwrap_or_else(|p| p.into_inner());
        table.get(&peer).is_none_or(|e| self.tokens(*e, now) >= 1.0)
    }

    /// `peer` failed a handshake at `now`.
    pub fn failed(&self, peer: IpAddr, now: Instant) {
        let mut table = self.table.lock().unwrap_or_else(|p| p.into_inner());
        if table.len() >= THROTTLE_SWEEP_AT {
            table.retain(|_, e| self.tokens(*e, now) < self.burst);
        }
        let tokens = table
            .get(&peer)
            .map_or(self.burst, |e| self.tokens(*e, now));
        table.insert(peer, ((tokens - 1.0).max(0.0), now));
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
        let adm = Admission::new(4, 1, 3, 2, 2);
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
        let clock = || Arc::new(AtomicU64::new(0));
        for id in [2, 5, 6] {
            adm.open_session(id, Role::Node, clock()).unwrap();
        }
        adm.admit_at(7, b, socket(&l), at(3000));
        adm.admit_at(8, a, socket(&l), at(3000));
        adm.admit_at(9, a, socket(&l), at(3000));
        // `b` holds its quota of two: nothing is evicted for it.
        assert_eq!(
            adm.open_session(7, Role::Reader, clock()),
            Err(WireError::Protocol(ProtocolError::TooManyConnections {
                limit: 3
            }))
        );
        adm.open_session(8, Role::Admin, clock()).unwrap();
        assert!(adm.open_session(9, Role::Admin, clock()).is_err());
        adm.close_session(8);
        assert_eq!(adm.counts(), (0, 3));
    }

    #[test]
    fn a_full_pool_evicts_the_longest_idle_session_of_an_address_over_its_quota() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let c: IpAddr = "10.0.0.3".parse().unwrap();
        let d: IpAddr = "10.0.0.4".parse().unwrap();
        let adm = Admission::new(4, 1, 8, 8, 1);
        let mut flags = Vec::new();
        for (id, idle_since) in [(1, 30), (2, 10), (3, 20)] {
            flags.push(adm.admit(id, c, socket(&l)).evicted);
            adm.open_session(id, Role::Reader, Arc::new(AtomicU64::new(idle_since)))
                .unwrap();
        }
        // `c` holds every slot but the reserve; `d` (under its quota) takes the idlest one.
        adm.admit(4, d, socket(&l));
        adm.open_session(4, Role::Reader, Arc::new(AtomicU64::new(0)))
            .unwrap();
        assert!(
            flags[1].load(Ordering::Acquire),
            "session 2 was idle longest"
        );
        assert!(!flags[0].load(Ordering::Acquire) && !flags[2].load(Ordering::Acquire));
        // `d` now holds its quota, `c` is over it: neither gets another slot from the other.
        adm.admit(5, d, socket(&l));
        assert!(
            adm.open_session(5, Role::Reader, Arc::new(AtomicU64::new(0)))
                .is_err()
        );
        adm.admit(6, c, socket(&l));
        assert!(
            adm.open_session(6, Role::Reader, Arc::new(AtomicU64::new(0)))
                .is_err()
        );
        // The administrator's reserve is still there, and the evicted session's close is a
        // no-op.
        adm.admit(7, c, socket(&l));
        adm.open_session(7, Role::Admin, Arc::new(AtomicU64::new(0)))
            .unwrap();
        adm.close_session(2);
        assert_eq!(adm.counts(), (0, 4));
    }

    #[test]
    fn a_connection_whose_hello_is_waiting_is_not_taken_for_a_silent_one() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let ip: IpAddr = "10.0.0.1".parse().unwrap();
        let adm = Admission::new(4, 0, 8, 2, 2);
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
    fn failed_handshakes_are_throttled_per_address() {
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        let a: IpAddr = "10.0.0.1".parse().unwrap();
        let b: IpAddr = "10.0.0.2".parse().unwrap();
        let th = AuthThrottle::new(3, 2.0);
        for _ in 0..3 {
            assert!(th.allows(a, at(0)));
            th.failed(a, at(0));
        }
        assert!(!th.allows(a, at(0)));
        assert!(th.allows(b, at(0)), "another address is not slowed");
        assert!(!th.allows(a, at(400)));
        assert!(th.allows(a, at(500)), "one more after half a second");
        th.failed(a, at(500));
        assert!(!th.allows(a, at(600)));
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
