//! The TCP server of a node.
//!
//! # Threads
//! - one accept thread (`pnlp-accept`), which admits connections as [`crate::net::limits`]
//!   says (a pending pool that evicts its oldest, sessions up to
//!   [`ServerConfig::max_connections`]);
//! - per connection, a reader thread (`pnlp-conn-N`) that does the handshake, decodes requests,
//!   calls the [`Service`] and writes each response itself (no hand-off to another thread on the
//!   request path: the round trip costs the same context switches as a raw TCP echo), and a
//!   writer thread (`pnlp-wr-N`) that drains the session's [`Outbox`] (telemetry pushed by the
//!   objects with [`Outbox::try_push`], or anything a service pushes).
//!
//! Both write whole frames to the socket under one short lock; responses go out in request
//! order (only the reader writes them), telemetry in push order. Pipelined requests are answered
//! into one buffer that is written once the decoder has no complete request left (one `write`
//! per batch). Responses do not go through the outbox: `Outbox::push` would cost a thread
//! hand-off per call and could wait behind telemetry.
//!
//! # Limits
//! Each connection holds at most `max_frame` + 4 bytes of input, one batch of responses and the
//! outbox's `outbox_capacity` frames. A client that does not read blocks the socket's writes for
//! at most `write_timeout` and is then dropped; meanwhile the outbox drops telemetry (never the
//! real-time side's problem). Requests are limited by a token bucket per connection
//! (`max_requests_per_s`, bursts up to one second's worth): over it a request is answered with
//! [`ProtocolError::RateLimited`]; [`ABUSE_STRIKES`] refused requests in a row close the
//! connection.
//! Malformed or oversized frames, a wrong hello, a failed authentication, a frame that fails to
//! open, a silent handshake or an idle connection get a [`ServerMsg::Error`] and are closed. The
//! whole handshake must end within `handshake_timeout` (a deadline, not an idle time: trickling
//! bytes does not extend it). [`Service::closed`] runs at every end of a session that passed its
//! handshake. Admission (how many connections, for whom) is [`crate::net::limits`].
//!
//! # Authentication
//! With a secret, the handshake is the Noise handshake of [`crate::net::auth`] (in
//! `server/handshake.rs`); the session's [`Identity`](crate::service::Identity) is the role the
//! client's hello claimed (an admin claim needs the admin secret), and every later frame both ways
//! is sealed: responses and telemetry are sealed under the socket's write lock, in the order they
//! are written.
//!
//! # Layout
//! - this file: the state the threads share (`Shared`, its counters) and one connection's
//!   session (`Conn`: framing, the request loop, the outbox writer);
//! - `server/config.rs`: [`ServerConfig`], [`NetError`] and [`ServerStats`];
//! - `server/listener.rs`: the [`Server`] handle and its accept thread (admission, refusal);
//! - `server/handshake.rs`: the hellos and the Noise handshake of a connection;
//! - `server/tests.rs`: the unit tests.

use std::collections::HashMap;
use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::net::auth::{Opener, PSK_LEN, Sealer, open_message};
use crate::net::frame::{FrameDecoder, FrameError, encode_into};
use crate::net::limits::{Admission, AuthThrottle, TokenBucket};
use crate::proto::{CallError, ClientMsg, ProtocolError, ServerMsg, WireError};
use crate::service::{Outbox, OutboxReceiver, Service, Session};

mod config;
mod handshake;
mod listener;
#[cfg(test)]
mod tests;

pub use config::{NetError, ServerConfig, ServerStats};
pub use listener::Server;

/// Refused requests in a row (rate limit) after which a connection is closed.
pub const ABUSE_STRIKES: u32 = 1000;

/// How often the accept thread looks at the stop flag, and the longest a read waits before the
/// reader looks at the idle clock.
const POLL_EVERY: Duration = Duration::from_millis(100);
/// Responses buffered before they are written even though more requests are queued, bytes.
const OUT_FLUSH_AT: usize = 64 * 1024;
/// After a closing error: how long and how much input is drained so that the error frame is not
/// lost to a TCP reset.
const LINGER: Duration = Duration::from_millis(200);
const LINGER_BYTES: usize = 1 << 20;

#[derive(Default)]
struct Counters {
    accepted: AtomicU64,
    refused: AtomicU64,
    open: AtomicU64,
    dropped: AtomicU64,
    requests: AtomicU64,
    sessions: AtomicU64,
    frames_in: AtomicU64,
    frames_out: AtomicU64,
    malformed: AtomicU64,
    too_large: AtomicU64,
    auth_failures: AtomicU64,
    timeouts: AtomicU64,
    rate_limited: AtomicU64,
}

fn bump(c: &AtomicU64) {
    c.fetch_add(1, Ordering::Relaxed);
}

fn add(c: &AtomicU64, n: u64) {
    if n > 0 {
        c.fetch_add(n, Ordering::Relaxed);
    }
}

struct Shared {
    config: ServerConfig,
    admission: Admission,
    /// Failed handshakes per address.
    throttle: AuthThrottle,
    /// The pre-shared keys of members and (if an admin secret is set) administrators.
    psk: Option<([u8; PSK_LEN], Option<[u8; PSK_LEN]>)>,
    service: Arc<dyn Service>,
    stop: AtomicBool,
    counters: Counters,
    next_session: AtomicU64,
    /// A handle on every open connection's socket, to close them at shutdown.
    streams: Mutex<HashMap<u64, TcpStream>>,
    /// Every connection thread not yet joined.
    threads: Mutex<Vec<JoinHandle<()>>>,
    /// When the server started (the idle clock's origin).
    epoch: Instant,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic elsewhere never leaves these maps inconsistent: keep serving.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Why a connection ends.
enum End {
    /// The client closed or said bye.
    Client,
    /// The server is stopping.
    Shutdown,
    /// Dropped: a typed error has been sent (or the socket failed).
    Dropped,
}

/// The socket's write side, shared by the reader (responses) and the writer (outbox).
struct Wire {
    stream: TcpStream,
    failed: bool,
    /// After an authenticated handshake: seals every frame, in write order.
    sealer: Option<Sealer>,
    /// Sealed frames being written.
    sealed: Vec<u8>,
}

/// A connection's socket send buffer once it carries camera frames, bytes (the kernel doubles
/// it): so that a slow reader's frames wait in their subscription's drop-oldest queue, not by
/// the megabyte in the kernel's autotuned buffer (seconds-old video).
const FRAME_SEND_BUFFER: usize = 64 * 1024;

impl Wire {
    /// Limits the socket's send buffer to [`FRAME_SEND_BUFFER`] (autotuning off).
    fn limit_send_buffer(&self) {
        if let Err(e) = nix::sys::socket::setsockopt(
            &self.stream,
            nix::sys::socket::sockopt::SndBuf,
            &FRAME_SEND_BUFFER,
        ) {
            log::debug!("send buffer not limited: {e}");
        }
    }

    /// Writes whole frames (plain ones, sealed here when the session is); `false` once the
    /// socket has failed (timeout: a client that does not read).
    fn send(&mut self, bytes: &[u8]) -> bool {
        if self.failed {
            return false;
        }
        let result = match &mut self.sealer {
            None => self.stream.write_all(bytes),
            Some(sealer) => {
                self.sealed.clear();
                match sealer.seal_frames(bytes, &mut self.sealed) {
                    Ok(_) => self.stream.write_all(&self.sealed),
                    Err(e) => Err(io::Error::other(e)),
                }
            }
        };
        if self.sealed.capacity() > 4 * OUT_FLUSH_AT {
            self.sealed = Vec::new();
        }
        if let Err(e) = result {
            log::debug!("write failed: {e}");
            self.failed = true;
            let _ = self.stream.shutdown(Shutdown::Both);
        }
        !self.failed
    }
}

struct Conn<'a> {
    shared: &'a Shared,
    id: u64,
    peer: SocketAddr,
    stream: TcpStream,
    decoder: FrameDecoder,
    /// After an authenticated handshake: opens every frame of the client.
    opener: Option<Opener>,
    /// Set by admission when this connection is evicted (pending, or as a session).
    evicted: Arc<AtomicBool>,
    /// Set once the client said a valid hello (admission then evicts silent ones first).
    greeted: Arc<AtomicBool>,
    /// Set once the handshake took a session slot: the connection left the pending pool (a
    /// full pool may still evict it as a session, see [`crate::net::limits`]).
    in_session: bool,
    /// The first sealed message, which proved the secret (served first by the request loop).
    first: Option<ClientMsg>,
    wire: Arc<Mutex<Wire>>,
    /// Responses not yet written.
    out: Vec<u8>,
    out_frames: u64,
    /// Milliseconds since the server's epoch of the last frame in either direction.
    last_activity: Arc<AtomicU64>,
    /// When the last input arrived.
    now: Instant,
}

impl Conn<'_> {
    fn now_ms(&self) -> u64 {
        self.shared.epoch.elapsed().as_millis() as u64
    }

    /// Notes input: reads the clock once per read (the rate limit and the idle clock use it).
    fn touch(&mut self) {
        self.now = Instant::now();
        let ms = self
            .now
            .saturating_duration_since(self.shared.epoch)
            .as_millis() as u64;
        self.last_activity.store(ms, Ordering::Relaxed);
    }

    fn flush(&mut self) -> bool {
        if self.out.is_empty() {
            return true;
        }
        let ok = lock(&self.wire).send(&self.out);
        self.out.clear();
        add(&self.shared.counters.frames_out, self.out_frames);
        self.out_frames = 0;
        ok
    }

    fn queue(&mut self, msg: &ServerMsg) {
        let max = self.shared.config.max_frame;
        match encode_into(msg, max, &mut self.out) {
            Ok(()) => self.out_frames += 1,
            Err(e) => {
                // A reply over the frame limit: tell the client instead.
                let id = match msg {
                    ServerMsg::Response { id, .. } => *id,
                    _ => 0,
                };
                let result = Err(WireError::from(&e));
                if encode_into(&ServerMsg::Response { id, result }, max, &mut self.out).is_ok() {
                    self.out_frames += 1;
                }
            }
        }
    }

    /// Sends `error`, closes our side and drains the input briefly so the error is not lost.
    fn fail(&mut self, error: WireError) -> End {
        log::info!(
            "dropping connection {} from {}: {error}",
            self.id,
            self.peer
        );
        bump(&self.shared.counters.dropped);
        self.queue(&ServerMsg::Error(error));
        self.flush();
        let _ = self.stream.shutdown(Shutdown::Write);
        let deadline = Instant::now() + LINGER;
        let _ = self.stream.set_read_timeout(Some(LINGER));
        let mut scratch = [0u8; 4096];
        let mut drained = 0;
        while drained < LINGER_BYTES && Instant::now() < deadline {
            match self.stream.read(&mut scratch) {
                Ok(0) | Err(_) => break,
                Ok(n) => drained += n,
            }
        }
        End::Dropped
    }

    fn frame_error(&mut self, e: FrameError) -> End {
        let c = &self.shared.counters;
        match e {
            FrameError::TooLarge { .. } => {
                bump(&c.too_large);
                self.fail(WireError::from(&e))
            }
            FrameError::Malformed(_) => {
                bump(&c.malformed);
                self.fail(WireError::from(&e))
            }
            FrameError::Closed => End::Client,
            FrameError::Truncated => {
                log::info!(
                    "connection {} from {} closed inside a frame",
                    self.id,
                    self.peer
                );
                End::Client
            }
            FrameError::Io(e) => {
                if self.shared.stop.load(Ordering::Acquire) {
                    End::Shutdown
                } else {
                    log::debug!("connection {} from {}: {e}", self.id, self.peer);
                    End::Client
                }
            }
            FrameError::Overflow { .. } => {
                self.fail(WireError::Call(CallError::Remote("input overflow".into())))
            }
        }
    }

    /// Reads until the next message; `Err(end)` when the connection must end. `deadline` bounds
    /// the wait (the handshake); otherwise the idle timeout does.
    fn next_msg(&mut self, deadline: Option<Instant>) -> Result<ClientMsg, End> {
        self.next_frame(deadline, false).map(|(m, _)| m)
    }

    /// [`next_msg`](Self::next_msg), with the frame's (plain) body when `keep_body`.
    fn next_frame(
        &mut self,
        deadline: Option<Instant>,
        keep_body: bool,
    ) -> Result<(ClientMsg, Vec<u8>), End> {
        loop {
            let opener = self.opener.as_mut();
            let next = self
                .decoder
                .next_with(|body| open_message::<ClientMsg>(opener, body, keep_body));
            match next {
                Ok(Some(m)) => {
                    bump(&self.shared.counters.frames_in);
                    return Ok(m);
                }
                Ok(None) => {}
                Err(e) => return Err(self.frame_error(e)),
            }
            if self.evicted.load(Ordering::Acquire) {
                return Err(self.evict());
            }
            if !self.flush() {
                return Err(self.dropped_writer());
            }
            match self.decoder.read_from(&mut self.stream) {
                Ok(0) => {
                    if self.shared.stop.load(Ordering::Acquire) {
                        return Err(End::Shutdown);
                    }
                    if self.evicted.load(Ordering::Acquire) {
                        return Err(self.evict());
                    }
                    let e = self.decoder.eof_error();
                    return Err(self.frame_error(e));
                }
                Ok(_) => self.touch(),
                Err(FrameError::Io(e))
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    if self.shared.stop.load(Ordering::Acquire) {
                        return Err(End::Shutdown);
                    }
                    if lock(&self.wire).failed {
                        return Err(self.dropped_writer());
                    }
                    let expired = match deadline {
                        Some(d) => Instant::now() >= d,
                        None => {
                            let idle = self
                                .now_ms()
                                .saturating_sub(self.last_activity.load(Ordering::Relaxed));
                            idle >= self.shared.config.idle_timeout.as_millis() as u64
                        }
                    };
                    if expired {
                        bump(&self.shared.counters.timeouts);
                        let what = if deadline.is_some() {
                            "no handshake in time"
                        } else {
                            "idle connection"
                        };
                        return Err(
                            self.fail(WireError::Protocol(ProtocolError::Timeout(what.into())))
                        );
                    }
                }
                Err(e) => return Err(self.frame_error(e)),
            }
        }
    }

    /// Admission evicted this connection from the pending pool (newer ones needed the room) or,
    /// as a session, from the full session pool for an address under its quota.
    fn evict(&mut self) -> End {
        let config = &self.shared.config;
        let limit = if self.in_session {
            config.max_connections
        } else {
            config.max_handshakes
        };
        self.fail(WireError::Protocol(ProtocolError::TooManyConnections {
            limit,
        }))
    }

    fn dropped_writer(&self) -> End {
        if self.shared.stop.load(Ordering::Acquire) {
            return End::Shutdown;
        }
        log::info!(
            "dropping connection {} from {}: it does not read (write timeout)",
            self.id,
            self.peer
        );
        bump(&self.shared.counters.timeouts);
        bump(&self.shared.counters.dropped);
        End::Dropped
    }

    /// Serves requests until the connection ends.
    fn requests(&mut self, session: &Session) -> End {
        let config = &self.shared.config;
        let _ = self.stream.set_read_timeout(Some(
            config
                .idle_timeout
                .clamp(Duration::from_millis(1), POLL_EVERY * 5),
        ));
        let mut bucket = TokenBucket::new(config.max_requests_per_s);
        let mut strikes = 0u32;
        loop {
            let next = match self.first.take() {
                Some(m) => Ok(m),
                None => self.next_msg(None),
            };
            let msg = match next {
                Ok(m) => m,
                Err(end) => return end,
            };
            match msg {
                ClientMsg::Request { id, call } => {
                    if bucket.take(self.now) {
                        strikes = 0;
                        bump(&self.shared.counters.requests);
                        let service = &self.shared.service;
                        let result = catch_unwind(AssertUnwindSafe(|| service.call(session, call)))
                            .unwrap_or_else(|_| {
                                log::error!("the service panicked serving request {id}");
                                Err(WireError::Call(CallError::Remote(
                                    "internal error in the node".into(),
                                )))
                            });
                        self.queue(&ServerMsg::Response { id, result });
                    } else {
                        bump(&self.shared.counters.rate_limited);
                        strikes += 1;
                        let limit = bucket.rate;
                        if strikes >= ABUSE_STRIKES {
                            return self
                                .fail(WireError::Protocol(ProtocolError::RateLimited { limit }));
                        }
                        self.queue(&ServerMsg::Response {
                            id,
                            result: Err(WireError::Protocol(ProtocolError::RateLimited { limit })),
                        });
                    }
                    if self.out.len() >= OUT_FLUSH_AT && !self.flush() {
                        return self.dropped_writer();
                    }
                }
                ClientMsg::Bye => {
                    self.flush();
                    return End::Client;
                }
                other => {
                    bump(&self.shared.counters.malformed);
                    return self.fail(WireError::Protocol(ProtocolError::Unexpected(format!(
                        "{} after the handshake",
                        msg_name(&other)
                    ))));
                }
            }
        }
    }
}

fn msg_name(m: &ClientMsg) -> &'static str {
    match m {
        ClientMsg::Hello(_) => "hello",
        ClientMsg::Handshake { .. } => "handshake",
        ClientMsg::Request { .. } => "request",
        ClientMsg::Bye => "bye",
    }
}

/// The connection thread: handshake, then the writer thread and the requests.
fn serve(
    shared: &Arc<Shared>,
    stream: TcpStream,
    peer: SocketAddr,
    id: u64,
    evicted: Arc<AtomicBool>,
    greeted: Arc<AtomicBool>,
) {
    let config = &shared.config;
    let Some(mut conn) = Conn::accept(shared, stream, peer, id, evicted, greeted) else {
        return;
    };
    conn.touch();
    let (client, identity) = match conn.handshake() {
        Ok(c) => c,
        Err(_) => {
            if conn.in_session {
                shared.admission.close_session(id);
            } else {
                shared.admission.abandon(id);
            }
            let _ = conn.stream.shutdown(Shutdown::Both);
            return;
        }
    };
    log::info!(
        "connection {id} from {peer}: client {client:?} as {:?}{}",
        identity.role,
        if identity.proven {
            " (authenticated)"
        } else {
            ""
        }
    );
    bump(&shared.counters.sessions);
    let (outbox, receiver) = Outbox::bounded(config.outbox_capacity);
    let session = Session {
        id,
        peer,
        client,
        identity,
        outbox: outbox.clone(),
    };
    let closing = Arc::new(AtomicBool::new(false));
    let writer = {
        let (wire, closing, activity) = (
            conn.wire.clone(),
            closing.clone(),
            conn.last_activity.clone(),
        );
        let shared = shared.clone();
        std::thread::Builder::new()
            .name(format!("pnlp-wr-{id}"))
            .spawn(move || drain_outbox(receiver, &wire, &closing, &activity, &shared))
    };
    let end = match &writer {
        Ok(_) => conn.requests(&session),
        Err(e) => {
            log::error!("cannot start the writer of connection {id}: {e}");
            End::Dropped
        }
    };
    closing.store(true, Ordering::Release);
    // Wake the writer (it ignores everything once closing is set).
    let _ = outbox.try_push(ServerMsg::Error(WireError::Protocol(
        ProtocolError::Timeout("closing".into()),
    )));
    let _ = conn.stream.shutdown(Shutdown::Both);
    if let Ok(h) = writer {
        let _ = h.join();
    }
    close_session(shared, &session, end);
}

impl<'a> Conn<'a> {
    /// A new connection on `stream`, its write half shared with the writer thread to come;
    /// `None` (said in the log) when the stream cannot be split.
    fn accept(
        shared: &'a Shared,
        stream: TcpStream,
        peer: SocketAddr,
        id: u64,
        evicted: Arc<AtomicBool>,
        greeted: Arc<AtomicBool>,
    ) -> Option<Self> {
        let config = &shared.config;
        let _ = stream.set_nodelay(true);
        let _ = stream.set_write_timeout(Some(config.write_timeout.max(Duration::from_millis(1))));
        let write_half = match stream.try_clone() {
            Ok(w) => w,
            Err(e) => {
                log::warn!("connection {id} from {peer}: {e}");
                return None;
            }
        };
        let wire = Arc::new(Mutex::new(Wire {
            stream: write_half,
            failed: false,
            sealer: None,
            sealed: Vec::new(),
        }));
        Some(Conn {
            shared,
            id,
            peer,
            stream,
            decoder: FrameDecoder::new(config.max_frame),
            opener: None,
            evicted,
            greeted,
            in_session: false,
            first: None,
            wire,
            out: Vec::with_capacity(4096),
            out_frames: 0,
            last_activity: Arc::new(AtomicU64::new(0)),
            now: Instant::now(),
        })
    }
}

/// Ends `session` (its connection closed as `end` says): the service told (a panic there is
/// logged, not spread), the admission slot freed.
fn close_session(shared: &Shared, session: &Session, end: End) {
    let (id, peer) = (session.id, session.peer);
    let service = &shared.service;
    if catch_unwind(AssertUnwindSafe(|| service.closed(session))).is_err() {
        log::error!("the service panicked closing session {id}");
    }
    shared.admission.close_session(id);
    let how = match end {
        End::Client => "closed by the client",
        End::Shutdown => "closed by the server's shutdown",
        End::Dropped => "dropped",
    };
    log::info!("connection {id} from {peer} {how}");
}

/// The writer thread: frames pushed to the outbox, in order, batched while more are queued.
fn drain_outbox(
    receiver: OutboxReceiver,
    wire: &Mutex<Wire>,
    closing: &AtomicBool,
    activity: &AtomicU64,
    shared: &Shared,
) {
    let max = shared.config.max_frame;
    let mut buf = Vec::with_capacity(4096);
    let mut carries_frames = false;
    loop {
        let first = match receiver.recv_timeout(Duration::from_secs(1)) {
            Ok(m) => m,
            Err(RecvTimeoutError::Timeout) => {
                if closing.load(Ordering::Acquire) {
                    return;
                }
                continue;
            }
            Err(RecvTimeoutError::Disconnected) => return,
        };
        if closing.load(Ordering::Acquire) {
            return;
        }
        let mut frames = 0u64;
        let mut next = Some(first);
        while let Some(msg) = next {
            if !carries_frames && matches!(msg, ServerMsg::Frames(_)) {
                carries_frames = true;
                lock(wire).limit_send_buffer();
            }
            match encode_into(&msg, max, &mut buf) {
                Ok(()) => frames += 1,
                Err(e) => log::warn!("outbox frame not sent: {e}"),
            }
            if buf.len() >= OUT_FLUSH_AT {
                break;
            }
            next = receiver.try_recv().ok();
        }
        if !buf.is_empty() {
            let ok = lock(wire).send(&buf);
            buf.clear();
            if !ok {
                return;
            }
            add(&shared.counters.frames_out, frames);
            activity.store(shared.epoch.elapsed().as_millis() as u64, Ordering::Relaxed);
        }
    }
}
