//! The bounds of a server that must hold under attack: who gets a connection slot, and how many
//! requests a connection may make.
//!
//! # Admission
//! Connections that have not finished their handshake (*pending*) and sessions (past it) have
//! separate pools, so silent, slow or flooding connections, which never finish a handshake
//! without the secret, can never take a session's slot:
//! - pending: at most [`Admission::max_pending`] in all and [`Admission::max_pending_per_peer`]
//!   per IP address. At either bound a newcomer is admitted and the *oldest* pending connection
//!   (of the same address at the per-address bound, else of the address holding most) is evicted:
//!   it gets [`WireError::TooManyConnections`] and is closed. A silent connection thus holds a slot
//!   only until newer ones arrive or its handshake time runs out, and an operator's connection,
//!   whose handshake takes a round trip, always gets through the flood of another address;
//! - sessions: at most `max_sessions`, of which `admin_reserve` only for [`Role::Admin`]
//!   sessions, so that members holding the system secret cannot lock the administrator out.
//!
//! Threads follow: one per pending connection and two per session.

use std::collections::VecDeque;
use std::net::{IpAddr, Shutdown, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

use crate::proto::{Role, WireError};

/// A pending connection, as admission tracks it.
struct Pending {
    id: u64,
    peer: IpAddr,
    evicted: Arc<AtomicBool>,
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

    /// Admits a new pending connection `id` from `peer`, evicting the oldest ones as the bounds
    /// require. `stream` is a handle on its socket.
    pub fn admit(&self, id: u64, peer: IpAddr, stream: TcpStream) -> Admitted {
        let mut s = self.lock();
        let mut evictions = 0;
        let of_peer = |s: &State, ip: IpAddr| s.pending.iter().filter(|p| p.peer == ip).count();
        while of_peer(&s, peer) >= self.max_pending_per_peer as usize {
            if let Some(at) = s.pending.iter().position(|p| p.peer == peer) {
                evict(&mut s, at);
                evictions += 1;
            }
        }
        while s.pending.len() >= self.max_pending as usize {
            // The oldest connection of the address that holds most.
            let busiest = s
                .pending
                .iter()
                .map(|p| p.peer)
                .max_by_key(|ip| of_peer(&s, *ip));
            let at = busiest
                .and_then(|ip| s.pending.iter().position(|p| p.peer == ip))
                .unwrap_or(0);
            evict(&mut s, at);
            evictions += 1;
        }
        let evicted = Arc::new(AtomicBool::new(false));
        s.pending.push_back(Pending {
            id,
            peer,
            evicted: evicted.clone(),
            stream,
        });
        Admitted { evicted, evictions }
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
    use std::time::Duration;

    use super::*;

    fn socket(l: &TcpListener) -> TcpStream {
        TcpStream::connect(l.local_addr().unwrap()).unwrap()
    }

    #[test]
    fn the_oldest_pending_connection_makes_room_per_peer_and_in_all() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let a: IpAddr = "10.0.0.1".parse().unwrap();
        let b: IpAddr = "10.0.0.2".parse().unwrap();
        let adm = Admission::new(4, 1, 3, 2);
        let a1 = adm.admit(1, a, socket(&l));
        let a2 = adm.admit(2, a, socket(&l));
        assert_eq!(adm.counts(), (2, 0));
        // A third from `a` evicts a's oldest.
        let a3 = adm.admit(3, a, socket(&l));
        assert_eq!(a3.evictions, 1);
        assert!(a1.evicted.load(Ordering::Acquire));
        assert!(!a2.evicted.load(Ordering::Acquire));
        // `b` fills the pool, then its second connection evicts from `a` (which holds most).
        let b1 = adm.admit(4, b, socket(&l));
        assert_eq!(b1.evictions, 0);
        let b2 = adm.admit(5, b, socket(&l));
        assert_eq!(b2.evictions, 1);
        assert!(a2.evicted.load(Ordering::Acquire));
        assert_eq!(adm.counts(), (3, 0));
        // Sessions: three for anyone, the fourth only for an administrator.
        for id in [3, 4, 5] {
            adm.open_session(id, Role::Node).unwrap();
        }
        assert_eq!(
            adm.open_session(6, Role::Reader),
            Err(WireError::TooManyConnections { limit: 3 })
        );
        adm.open_session(7, Role::Admin).unwrap();
        assert!(adm.open_session(8, Role::Admin).is_err());
        adm.close_session();
        assert_eq!(adm.counts(), (0, 3));
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
