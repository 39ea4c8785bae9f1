//! The [`Server`] handle and its accept thread: binding, admission of each connection (or its
//! refusal with a typed error), reaping finished connection threads, stopping.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::os::fd::AsFd;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nix::poll::{PollFd, PollFlags, PollTimeout, poll};

use super::{
    Counters, NetError, POLL_EVERY, ServerConfig, ServerStats, Shared, add, bump, lock, serve,
};
use crate::net::auth;
use crate::net::frame::encode_into;
use crate::net::limits::{Admission, AuthThrottle};
use crate::proto::{ProtocolError, ServerMsg, WireError};
use crate::service::Service;

/// A running server.
pub struct Server {
    addr: SocketAddr,
    shared: Arc<Shared>,
    accept: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for Server {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Server")
            .field("addr", &self.addr)
            .field("node", &self.shared.config.node)
            .field("stats", &self.stats())
            .finish()
    }
}

impl Server {
    /// Listens on `addr` and serves `service`. Port 0 takes any free port (see
    /// [`local_addr`](Self::local_addr)).
    ///
    /// # Errors
    /// [`NetError::SecretRequired`] for a non-loopback address (such as `0.0.0.0`) without a
    /// non-empty secret; [`NetError::AdminSecretWithoutSecret`] for an admin secret without a
    /// secret; [`NetError::WeakSecret`] for a secret under
    /// [`MIN_SECRET_BITS`](crate::net::auth::MIN_SECRET_BITS); [`NetError::Io`] if the socket cannot be bound or the accept thread cannot start.
    pub fn bind(
        addr: SocketAddr,
        config: ServerConfig,
        service: Arc<dyn Service>,
    ) -> Result<Server, NetError> {
        let has_secret = config.secret.as_ref().is_some_and(|s| !s.is_empty());
        if !addr.ip().is_loopback() && !has_secret {
            return Err(NetError::SecretRequired(addr));
        }
        let has_admin_secret = config.admin_secret.as_ref().is_some_and(|a| !a.is_empty());
        if !has_secret && has_admin_secret {
            return Err(NetError::AdminSecretWithoutSecret);
        }
        for (secret, what) in [
            (&config.secret, "the shared secret"),
            (&config.admin_secret, "the admin secret"),
        ] {
            if let Some(s) = secret.as_ref().filter(|s| !s.is_empty()) {
                s.check_strength(what).map_err(NetError::WeakSecret)?;
            }
        }
        let listener = TcpListener::bind(addr)?;
        let addr = listener.local_addr()?;
        let psk = config.secret.as_ref().filter(|s| !s.is_empty()).map(|s| {
            let admin = config.admin_secret.as_ref().filter(|a| !a.is_empty());
            (
                auth::member_psk(s.bytes()),
                admin.map(|a| auth::admin_psk(s.bytes(), a.bytes())),
            )
        });
        let admission = Admission::new(
            config.max_connections,
            config.admin_reserve,
            config.max_handshakes,
            config.max_handshakes_per_peer,
            config.max_sessions_per_peer,
        );
        let throttle = AuthThrottle::new(config.auth_failure_burst, config.auth_failures_per_s);
        let shared = Arc::new(Shared {
            admission,
            throttle,
            psk,
            config,
            service,
            stop: AtomicBool::new(false),
            counters: Counters::default(),
            next_session: AtomicU64::new(1),
            streams: Mutex::new(HashMap::new()),
            threads: Mutex::new(Vec::new()),
            epoch: Instant::now(),
        });
        let s = shared.clone();
        let accept = std::thread::Builder::new()
            .name("pnlp-accept".into())
            .spawn(move || accept_loop(&s, &listener))?;
        log::info!(
            "node `{}` listening on {addr}{}",
            shared.config.node,
            if has_secret { " (shared secret)" } else { "" }
        );
        Ok(Server {
            addr,
            shared,
            accept: Some(accept),
        })
    }

    /// The bound address (the real port when bound to port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Counters.
    pub fn stats(&self) -> ServerStats {
        let c = &self.shared.counters;
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        ServerStats {
            accepted: get(&c.accepted),
            refused: get(&c.refused),
            open: get(&c.open),
            dropped: get(&c.dropped),
            requests: get(&c.requests),
            sessions: get(&c.sessions),
            frames_in: get(&c.frames_in),
            frames_out: get(&c.frames_out),
            malformed: get(&c.malformed),
            too_large: get(&c.too_large),
            auth_failures: get(&c.auth_failures),
            timeouts: get(&c.timeouts),
            rate_limited: get(&c.rate_limited),
        }
    }

    /// Stops accepting, closes every connection (their sessions get [`Service::closed`]) and
    /// joins every thread of the server.
    pub fn shutdown(mut self) {
        self.stop_and_join();
    }

    fn stop_and_join(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        if let Some(h) = self.accept.take() {
            let _ = h.join();
        }
        for s in lock(&self.shared.streams).values() {
            let _ = s.shutdown(Shutdown::Both);
        }
        let threads = std::mem::take(&mut *lock(&self.shared.threads));
        for t in threads {
            let _ = t.join();
        }
        log::info!(
            "node `{}` server on {} stopped",
            self.shared.config.node,
            self.addr
        );
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if self.accept.is_some() {
            self.stop_and_join();
        }
    }
}

fn accept_loop(shared: &Arc<Shared>, listener: &TcpListener) {
    while !shared.stop.load(Ordering::Acquire) {
        let mut fds = [PollFd::new(listener.as_fd(), PollFlags::POLLIN)];
        let ready = poll(&mut fds, PollTimeout::from(POLL_EVERY.as_millis() as u16));
        reap(shared);
        match ready {
            Ok(0) => continue,
            Ok(_) => {}
            Err(nix::errno::Errno::EINTR) => continue,
            Err(e) => {
                log::error!("poll on the listening socket failed: {e}");
                std::thread::sleep(POLL_EVERY);
                continue;
            }
        }
        if shared.stop.load(Ordering::Acquire) {
            break;
        }
        match listener.accept() {
            Ok((stream, peer)) => admit(shared, stream, peer),
            Err(e) => {
                // EMFILE and friends: back off instead of spinning.
                log::warn!("accept failed: {e}");
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    }
}

/// Joins the connection threads that have ended.
fn reap(shared: &Shared) {
    let finished: Vec<JoinHandle<()>> = {
        let mut threads = lock(&shared.threads);
        let (done, running): (Vec<_>, Vec<_>) = threads.drain(..).partition(|t| t.is_finished());
        *threads = running;
        done
    };
    for t in finished {
        let _ = t.join();
    }
}

fn admit(shared: &Arc<Shared>, stream: TcpStream, peer: SocketAddr) {
    let c = &shared.counters;
    let id = shared.next_session.fetch_add(1, Ordering::Relaxed);
    let (handle, for_admission) = match (stream.try_clone(), stream.try_clone()) {
        (Ok(h), Ok(a)) => (h, a),
        (Err(e), _) | (_, Err(e)) => {
            log::warn!("cannot serve {peer}: {e}");
            return;
        }
    };
    let admitted = shared.admission.admit(id, peer.ip(), for_admission);
    if admitted.evictions > 0 {
        add(&c.refused, u64::from(admitted.evictions));
        log::warn!(
            "{} connection(s) in their handshake evicted to admit {peer}",
            admitted.evictions
        );
    }
    bump(&c.accepted);
    bump(&c.open);
    lock(&shared.streams).insert(id, handle);
    let s = shared.clone();
    let (evicted, greeted) = (admitted.evicted, admitted.greeted);
    let spawned = std::thread::Builder::new()
        .name(format!("pnlp-conn-{id}"))
        .spawn(move || {
            serve(&s, stream, peer, id, evicted, greeted);
            lock(&s.streams).remove(&id);
            s.counters.open.fetch_sub(1, Ordering::Relaxed);
        });
    match spawned {
        Ok(t) => lock(&shared.threads).push(t),
        Err(e) => {
            log::error!("cannot start a thread for {peer}: {e}");
            shared.admission.abandon(id);
            if let Some(s) = lock(&shared.streams).remove(&id) {
                refuse(
                    s,
                    &WireError::Protocol(ProtocolError::TooManyConnections {
                        limit: shared.config.max_connections,
                    }),
                    shared.config.max_frame,
                );
            }
            c.open.fetch_sub(1, Ordering::Relaxed);
        }
    }
}

/// Sends `error` on a connection that is not served and closes it (from the accept thread: never
/// waits long).
fn refuse(stream: TcpStream, error: &WireError, max_frame: usize) {
    let mut stream = stream;
    let _ = stream.set_nodelay(true);
    let _ = stream.set_write_timeout(Some(Duration::from_millis(50)));
    let mut out = Vec::new();
    if encode_into(&ServerMsg::Error(error.clone()), max_frame, &mut out).is_ok() {
        let _ = stream.write_all(&out);
    }
    let _ = stream.shutdown(Shutdown::Write);
    // Take what the client already sent (its hello), so closing does not reset the connection
    // and lose the error; do not wait for more.
    if stream.set_nonblocking(true).is_ok() {
        let mut scratch = [0u8; 4096];
        while let Ok(n) = stream.read(&mut scratch) {
            if n == 0 {
                break;
            }
        }
    }
}
