//! The client side of one connection to a node.
//!
//! A [`Connection`] is one TCP stream (`TCP_NODELAY`) that has passed the hello and, when the
//! client holds the secret, the Noise handshake of [`crate::net::auth`]: the node proved the
//! secret before a single request is sent, and every frame after it is sealed both ways. A client
//! with a secret refuses a node that answers [`Security::Plain`] (it sends it nothing more), and a
//! frame of the node that fails to open ends the connection. [`Connection::call`] sends one request and
//! waits for its answer; [`Connection::call_many`] pipelines many (written back to back, answers
//! read in order); telemetry and link frames that arrive meanwhile are kept (at most
//! [`TELEMETRY_BACKLOG`] batches, the oldest dropped first) for [`Connection::next_pushed`].
//!
//! Request ids increase from 1. A call that timed out leaves its answer on the wire: it is
//! recognised and skipped later. Any other surprise (an answer with an unexpected id, a frame a
//! node never sends) is [`RpcError::Protocol`], and a connection-level [`ServerMsg::Error`] is
//! [`RpcError::Remote`]; after either, or a transport failure, the connection is unusable and
//! every later call says so. Nothing here panics on what the node sends.

use std::collections::VecDeque;
use std::io::{self, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use crate::net::auth::{self, ClientHandshake, Opener, SealError, Sealer, Secret, open_message};
use crate::net::frame::{FrameDecoder, FrameError, encode_into};
use crate::proto::{
    Call, CallError, ClientHello, ClientMsg, DEFAULT_MAX_FRAME, FrameBatch, LinkBatch, MAGIC,
    PROTOCOL_VERSION, ProtocolError, Reply, Role, Security, ServerMsg, TelemetryBatch, WireError,
};

/// Pushed batches (telemetry and link records) kept while nobody asks for them; older ones are
/// dropped.
pub const TELEMETRY_BACKLOG: usize = 1024;

/// Pipelined requests in flight at most in [`Connection::call_many`] (more wait for answers, so
/// neither side's socket buffers can fill up and stall both).
const MAX_IN_FLIGHT: usize = 512;

/// How far past a deadline a read may wait before it is noticed.
const TIMEOUT_SLACK: Duration = Duration::from_millis(5);

/// Request bytes buffered before they are written in [`Connection::call_many`].
const WRITE_CHUNK: usize = 64 * 1024;

/// How a client connects.
#[derive(Clone, Debug)]
pub struct ClientConfig {
    /// The name sent in the hello (a node's own name for [`Role::Node`]).
    pub name: String,
    /// The role claimed in the hello.
    pub role: Role,
    /// The shared secret. With it, the client authenticates the node before sending anything and
    /// refuses a node without the secret.
    pub secret: Option<Secret>,
    /// The admin secret, for [`Role::Admin`] at a node that has one.
    pub admin_secret: Option<Secret>,
    /// Connect and per-call timeout.
    pub timeout: Duration,
    /// Largest frame accepted, bytes.
    pub max_frame: usize,
}

impl ClientConfig {
    /// Defaults for a client (a [`Role::Reader`]) named `name`: no secret, 5 s timeout, 256 KiB
    /// frames.
    pub fn new(name: impl Into<String>) -> Self {
        ClientConfig {
            name: name.into(),
            role: Role::Reader,
            secret: None,
            admin_secret: None,
            timeout: Duration::from_secs(5),
            max_frame: DEFAULT_MAX_FRAME,
        }
    }

    /// The defaults of [`new`](Self::new) for the node named `node` ([`Role::Node`]).
    pub fn node(node: impl Into<String>) -> Self {
        ClientConfig {
            role: Role::Node,
            ..ClientConfig::new(node)
        }
    }

    /// The defaults of [`new`](Self::new) for an operator ([`Role::Operator`]): it may run
    /// objects (lifecycle, methods, recordings) but not create or destroy them.
    pub fn operator(name: impl Into<String>) -> Self {
        ClientConfig {
            role: Role::Operator,
            ..ClientConfig::new(name)
        }
    }

    /// The most a tool holding `secret` and `admin_secret` can be: [`Role::Admin`] with the
    /// admin secret, or without any secret (a plain, loopback-only system takes the claim on
    /// trust); [`Role::Operator`] with the shared secret alone.
    pub fn strongest_role(secret: Option<&Secret>, admin_secret: Option<&Secret>) -> Role {
        match (secret, admin_secret) {
            (None, _) | (Some(_), Some(_)) => Role::Admin,
            (Some(_), None) => Role::Operator,
        }
    }

    /// The defaults of [`new`](Self::new) for an administrator ([`Role::Admin`]); set
    /// `admin_secret` (and `secret`) for a node that has them.
    pub fn admin(name: impl Into<String>) -> Self {
        ClientConfig {
            role: Role::Admin,
            ..ClientConfig::new(name)
        }
    }
}

/// What can go wrong with a remote call.
#[derive(Debug, thiserror::Error)]
pub enum RpcError {
    /// The socket failed.
    #[error("i/o: {0}")]
    Io(#[from] std::io::Error),
    /// A frame could not be read or written.
    #[error("{0}")]
    Frame(#[from] FrameError),
    /// The node answered with an error.
    #[error("{0}")]
    Remote(WireError),
    /// The node broke the protocol.
    #[error("protocol error: {0}")]
    Protocol(String),
    /// The client holds the secret and the node did not prove it (it offered no authentication,
    /// or its handshake answer did not verify): nothing was sent to it.
    #[error("the node at {0} did not prove the shared secret; nothing was sent to it")]
    Unauthenticated(SocketAddr),
    /// No answer in time.
    #[error("timed out")]
    Timeout,
}

impl From<RpcError> for WireError {
    fn from(e: RpcError) -> Self {
        match e {
            RpcError::Remote(w) => w,
            other => WireError::Call(CallError::Remote(other.to_string())),
        }
    }
}

/// One connection to a node.
#[derive(Debug)]
pub struct Connection {
    node: String,
    stream: TcpStream,
    decoder: FrameDecoder,
    out: Vec<u8>,
    /// After the handshake with a secret: seals what is sent, opens what arrives.
    seal: Option<(Sealer, Opener)>,
    /// Sealed bytes being written.
    sealed: Vec<u8>,
    max_frame: usize,
    timeout: Duration,
    /// The socket's read timeout as last set.
    read_timeout: Duration,
    next_id: u64,
    /// Answers to ids below this may still arrive from calls that timed out: skipped.
    stale_below: u64,
    telemetry: VecDeque<Pushed>,
    /// Why the connection is unusable.
    broken: Option<String>,
}

/// What a node pushes to a subscriber between responses.
#[derive(Clone, Debug, PartialEq)]
pub enum Pushed {
    /// Control ticks of a controller's subscription.
    Telemetry(TelemetryBatch),
    /// Link records of a channel's subscription.
    Link(LinkBatch),
    /// Frames of a camera's subscription.
    Frames(FrameBatch),
}

impl Pushed {
    /// The subscription it belongs to.
    pub fn subscription(&self) -> u64 {
        match self {
            Pushed::Telemetry(b) => b.subscription,
            Pushed::Link(b) => b.subscription,
            Pushed::Frames(b) => b.subscription,
        }
    }
}

/// A frame of the node, classified.
#[allow(clippy::large_enum_variant)] // moved once per frame; boxing would allocate per call
enum Incoming {
    Response(u64, Result<Reply, WireError>),
    Pushed(Pushed),
}

impl Connection {
    /// Connects (within `config.timeout`), says hello and, with a secret, runs the Noise
    /// handshake: the node must prove the secret before anything else is sent.
    ///
    /// # Errors
    /// [`RpcError::Io`] if the node cannot be reached, [`RpcError::Timeout`] if it does not
    /// answer in time, [`RpcError::Remote`] with [`ProtocolError::AuthFailed`] if the node wants a
    /// secret and none or a wrong one was given (or another error the node sent),
    /// [`RpcError::Unauthenticated`] if this client has a secret and the node did not prove it,
    /// [`RpcError::Protocol`] for a peer that is not a Penelope node of this version.
    pub fn connect(addr: SocketAddr, config: &ClientConfig) -> Result<Connection, RpcError> {
        let timeout = config.timeout.max(Duration::from_millis(1));
        let mut conn = Connection::open(addr, config, timeout)?;
        let hello = ClientMsg::Hello(ClientHello::new(config.name.clone(), config.role));
        let client_body = postcard::to_stdvec(&hello)
            .map_err(|e| RpcError::Frame(FrameError::Malformed(e.to_string())))?;
        conn.send(&hello)?;
        conn.write_out()?;
        let mut deadline = Deadline::after(timeout);
        let (security, server_body) = conn.read_hello(&mut deadline)?;
        let secret = config
            .secret
            .as_ref()
            .filter(|s| !s.is_empty())
            .map(Secret::bytes);
        match (security, secret) {
            (Security::Plain, None) => {}
            (Security::Plain, Some(_)) => {
                log::warn!(
                    "node `{}` at {addr} offers no authentication; refusing it",
                    conn.node
                );
                conn.close_unauthenticated();
                return Err(RpcError::Unauthenticated(addr));
            }
            (Security::Noise { .. }, None) => {
                log::warn!("node `{}` at {addr} requires a shared secret", conn.node);
                return Err(RpcError::Remote(WireError::Protocol(
                    ProtocolError::AuthFailed,
                )));
            }
            (Security::Noise { admin }, Some(secret)) => {
                let psk = conn.psk(config, admin, secret)?;
                let prologue = auth::prologue(&client_body, &server_body);
                conn.handshake(addr, config, &psk, &prologue, &mut deadline)?;
                conn.prove_session()?;
            }
        }
        Ok(conn)
    }

    /// The TCP connection to `addr`, with no delay and `timeout` on every read and write.
    fn open(
        addr: SocketAddr,
        config: &ClientConfig,
        timeout: Duration,
    ) -> Result<Connection, RpcError> {
        let stream = TcpStream::connect_timeout(&addr, timeout)?;
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(timeout))?;
        stream.set_write_timeout(Some(timeout))?;
        Ok(Connection {
            node: String::new(),
            stream,
            decoder: FrameDecoder::new(config.max_frame),
            out: Vec::with_capacity(256),
            seal: None,
            sealed: Vec::new(),
            max_frame: config.max_frame,
            timeout,
            read_timeout: timeout,
            next_id: 1,
            stale_below: 0,
            telemetry: VecDeque::new(),
            broken: None,
        })
    }

    /// Reads the node's hello, checks it is a Penelope node of this version and takes its name;
    /// returns the security it offers and the hello's bytes (for the handshake's prologue).
    fn read_hello(&mut self, deadline: &mut Deadline) -> Result<(Security, Vec<u8>), RpcError> {
        let (theirs, server_body) = self.read_raw(deadline)?;
        let hello = match theirs {
            ServerMsg::Hello(h) => h,
            ServerMsg::Error(e) => return Err(RpcError::Remote(e)),
            other => return Err(self.protocol(format!("expected the node's hello, got {other:?}"))),
        };
        if hello.magic != MAGIC {
            return Err(self.protocol("the peer is not a Penelope node (bad magic)".into()));
        }
        if hello.version != PROTOCOL_VERSION {
            return Err(RpcError::Remote(WireError::Protocol(
                ProtocolError::VersionMismatch {
                    ours: PROTOCOL_VERSION,
                    theirs: hello.version,
                },
            )));
        }
        self.node = hello.node;
        Ok((hello.security, server_body))
    }

    /// The pre-shared key for this client's role: an administrator of a node that wants the
    /// admin secret mixes it in (refused without one); everyone else uses the member key.
    fn psk(
        &self,
        config: &ClientConfig,
        admin: bool,
        secret: &[u8],
    ) -> Result<[u8; auth::PSK_LEN], RpcError> {
        let admin_secret = config
            .admin_secret
            .as_ref()
            .filter(|a| !a.is_empty())
            .map(Secret::bytes);
        match (config.role, admin, admin_secret) {
            (Role::Admin, true, Some(a)) => Ok(auth::admin_psk(secret, a)),
            (Role::Admin, true, None) => {
                log::warn!("node `{}` wants the admin secret for admin", self.node);
                Err(RpcError::Remote(WireError::Protocol(
                    ProtocolError::AuthFailed,
                )))
            }
            _ => Ok(auth::member_psk(secret)),
        }
    }

    /// The Noise handshake with `psk`: on success every frame from here on is sealed; a node
    /// that does not prove the secret is closed.
    fn handshake(
        &mut self,
        addr: SocketAddr,
        config: &ClientConfig,
        psk: &[u8; auth::PSK_LEN],
        prologue: &[u8],
        deadline: &mut Deadline,
    ) -> Result<(), RpcError> {
        let (handshake, first) =
            ClientHandshake::start(psk, prologue).map_err(|e| self.protocol(e.to_string()))?;
        self.send(&ClientMsg::Handshake { noise: first })?;
        self.write_out()?;
        let second = match self.read_msg(deadline)? {
            ServerMsg::Handshake { noise } => noise,
            ServerMsg::Error(e) => return Err(RpcError::Remote(e)),
            _ => Vec::new(),
        };
        match handshake.finish(&second) {
            Ok(keys) => {
                self.seal = Some(keys.split());
                self.decoder.set_max(auth::sealed_len(config.max_frame));
                Ok(())
            }
            Err(SealError::Handshake) => {
                log::warn!(
                    "node `{}` at {addr} did not prove the shared secret",
                    self.node
                );
                self.close_unauthenticated();
                Err(RpcError::Unauthenticated(addr))
            }
            Err(e) => Err(self.protocol(e.to_string())),
        }
    }

    /// The node holds no session for us until a frame sealed with this session's keys proves
    /// the secret (the first handshake message could be a replay): a ping, whose answer says
    /// we are in (or why not).
    fn prove_session(&mut self) -> Result<(), RpcError> {
        match self.call(Call::Ping {
            payload: Vec::new(),
        }) {
            Ok(_) => Ok(()),
            Err(RpcError::Remote(e)) if !self.is_usable() => Err(RpcError::Remote(e)),
            // An error reply of a service that does not serve pings: we are in.
            Err(RpcError::Remote(_)) => Ok(()),
            Err(e) => Err(e),
        }
    }

    /// Closes a connection to a node that did not prove the secret, without sending anything.
    fn close_unauthenticated(&mut self) {
        self.broken = Some("the node did not prove the shared secret".into());
        self.out.clear();
        let _ = self.stream.shutdown(Shutdown::Both);
    }

    /// The node's name from its hello.
    pub fn node(&self) -> &str {
        &self.node
    }

    /// The node's address.
    ///
    /// # Errors
    /// The socket's error.
    pub fn peer_addr(&self) -> io::Result<SocketAddr> {
        self.stream.peer_addr()
    }

    /// Whether the connection can still be used (no transport or protocol failure so far).
    pub fn is_usable(&self) -> bool {
        self.broken.is_none()
    }

    /// One call, waiting at most the configured timeout for its answer.
    ///
    /// # Errors
    /// [`RpcError::Remote`] for an error reply, [`RpcError::Timeout`], others for transport or
    /// protocol failures (which leave the connection unusable).
    pub fn call(&mut self, call: Call) -> Result<Reply, RpcError> {
        self.check()?;
        let id = self.next_id;
        self.next_id += 1;
        self.send(&ClientMsg::Request { id, call })?;
        self.write_out()?;
        match self.wait_response(id, &mut Deadline::after(self.timeout)) {
            Ok(result) => result.map_err(RpcError::Remote),
            Err(e) => {
                if matches!(e, RpcError::Timeout) {
                    self.stale_below = self.next_id;
                }
                Err(e)
            }
        }
    }

    /// Several calls sent back to back (pipelined: one write for many requests, at most 512 in
    /// flight), then their answers in order. The timeout applies to each answer.
    ///
    /// # Errors
    /// Transport, protocol and timeout failures; each call's own error is in its slot.
    pub fn call_many(
        &mut self,
        calls: Vec<Call>,
    ) -> Result<Vec<Result<Reply, WireError>>, RpcError> {
        self.check()?;
        let first = self.next_id;
        let n = calls.len() as u64;
        self.next_id += n;
        let mut results = Vec::with_capacity(calls.len());
        let mut sent = first;
        let result = (|| {
            for call in calls {
                if sent - first - results.len() as u64 >= MAX_IN_FLIGHT as u64 {
                    self.write_out()?;
                    let want = first + results.len() as u64;
                    results.push(self.wait_response(want, &mut Deadline::after(self.timeout))?);
                }
                self.send(&ClientMsg::Request { id: sent, call })?;
                sent += 1;
                if self.out.len() >= WRITE_CHUNK {
                    self.write_out()?;
                }
            }
            self.write_out()?;
            while (results.len() as u64) < n {
                let want = first + results.len() as u64;
                results.push(self.wait_response(want, &mut Deadline::after(self.timeout))?);
            }
            Ok(())
        })();
        match result {
            Ok(()) => Ok(results),
            Err(e) => {
                if matches!(e, RpcError::Timeout) {
                    self.stale_below = self.next_id;
                }
                Err(e)
            }
        }
    }

    /// The next pushed batch, telemetry or link records (first those that arrived during
    /// calls), waiting at most `timeout`; `Ok(None)` if none came.
    ///
    /// # Errors
    /// Transport and protocol failures.
    pub fn next_pushed(&mut self, timeout: Duration) -> Result<Option<Pushed>, RpcError> {
        if let Some(b) = self.telemetry.pop_front() {
            return Ok(Some(b));
        }
        self.check()?;
        let mut deadline = Deadline::after(timeout);
        loop {
            match self.read_incoming(&mut deadline) {
                Ok(Incoming::Pushed(b)) => return Ok(Some(b)),
                Ok(Incoming::Response(id, _)) if id < self.stale_below => {}
                Ok(Incoming::Response(id, _)) => {
                    return Err(self.protocol(format!("an answer to request {id}, never sent")));
                }
                Err(RpcError::Timeout) => return Ok(None),
                Err(e) => return Err(e),
            }
        }
    }

    fn check(&self) -> Result<(), RpcError> {
        match &self.broken {
            Some(why) => Err(RpcError::Protocol(format!("connection unusable: {why}"))),
            None => Ok(()),
        }
    }

    fn protocol(&mut self, what: String) -> RpcError {
        self.broken = Some(what.clone());
        let _ = self.stream.shutdown(Shutdown::Both);
        RpcError::Protocol(what)
    }

    fn fail<E: std::fmt::Display>(&mut self, e: E) -> E {
        self.broken = Some(e.to_string());
        e
    }

    /// Appends one frame to the output buffer.
    fn send(&mut self, msg: &ClientMsg) -> Result<(), RpcError> {
        encode_into(msg, self.max_frame, &mut self.out).map_err(RpcError::Frame)
    }

    /// Writes the output buffer (sealed, after an authenticated handshake).
    fn write_out(&mut self) -> Result<(), RpcError> {
        if self.out.is_empty() {
            return Ok(());
        }
        let r = match &mut self.seal {
            None => self.stream.write_all(&self.out),
            Some((sealer, _)) => {
                self.sealed.clear();
                match sealer.seal_frames(&self.out, &mut self.sealed) {
                    Ok(_) => self.stream.write_all(&self.sealed),
                    Err(e) => Err(io::Error::other(e)),
                }
            }
        };
        self.out.clear();
        if self.sealed.capacity() > 4 * WRITE_CHUNK {
            self.sealed = Vec::new();
        }
        r.map_err(|e| RpcError::Io(self.fail(e)))
    }

    /// Waits for the answer to `id`, keeping pushed batches and skipping answers of timed-out
    /// calls.
    fn wait_response(
        &mut self,
        id: u64,
        deadline: &mut Deadline,
    ) -> Result<Result<Reply, WireError>, RpcError> {
        loop {
            match self.read_incoming(deadline)? {
                Incoming::Response(got, result) if got == id => return Ok(result),
                Incoming::Response(got, _) if got < self.stale_below && got < id => {}
                Incoming::Response(got, _) => {
                    return Err(self.protocol(format!("expected the answer to {id}, got {got}")));
                }
                Incoming::Pushed(b) => {
                    if self.telemetry.len() >= TELEMETRY_BACKLOG {
                        self.telemetry.pop_front();
                    }
                    self.telemetry.push_back(b);
                }
            }
        }
    }

    fn read_incoming(&mut self, deadline: &mut Deadline) -> Result<Incoming, RpcError> {
        match self.read_msg(deadline)? {
            ServerMsg::Response { id, result } => Ok(Incoming::Response(id, result)),
            ServerMsg::Telemetry(b) => Ok(Incoming::Pushed(Pushed::Telemetry(b))),
            ServerMsg::Link(b) => Ok(Incoming::Pushed(Pushed::Link(b))),
            ServerMsg::Frames(b) => Ok(Incoming::Pushed(Pushed::Frames(b))),
            ServerMsg::Error(e) => {
                let e = self.fail(e);
                let _ = self.stream.shutdown(Shutdown::Both);
                Err(RpcError::Remote(e))
            }
            other => Err(self.protocol(format!("unexpected {other:?} from the node"))),
        }
    }

    /// Reads the next frame of the node, waiting until `deadline`.
    fn read_msg(&mut self, deadline: &mut Deadline) -> Result<ServerMsg, RpcError> {
        self.read_frame(deadline, false).map(|(m, _)| m)
    }

    /// The node's next message and its frame body (its hello, for the handshake's prologue).
    fn read_raw(&mut self, deadline: &mut Deadline) -> Result<(ServerMsg, Vec<u8>), RpcError> {
        self.read_frame(deadline, true)
    }

    fn read_frame(
        &mut self,
        deadline: &mut Deadline,
        keep_body: bool,
    ) -> Result<(ServerMsg, Vec<u8>), RpcError> {
        loop {
            let opener = self.seal.as_mut().map(|(_, o)| o);
            let next = self
                .decoder
                .next_with(|body| open_message::<ServerMsg>(opener, body, keep_body));
            match next {
                Ok(Some(m)) => return Ok(m),
                Ok(None) => {}
                Err(e) => {
                    let e = self.fail(e);
                    let _ = self.stream.shutdown(Shutdown::Both);
                    return Err(RpcError::Frame(e));
                }
            }
            let left = deadline.left();
            if left.is_zero() {
                return Err(RpcError::Timeout);
            }
            // Only touch the socket option when the wait must be clearly shorter than the one
            // set, or may be longer again (a call's usual wait keeps it: no extra system call per
            // call; a read may overshoot the deadline by at most the slack).
            let want = left.min(self.timeout).max(Duration::from_millis(1));
            if want + TIMEOUT_SLACK < self.read_timeout
                || (self.read_timeout < self.timeout && want > self.read_timeout + TIMEOUT_SLACK)
            {
                self.stream.set_read_timeout(Some(want))?;
                self.read_timeout = want;
            }
            match self.decoder.read_from(&mut self.stream) {
                Ok(0) => {
                    let e = self.decoder.eof_error();
                    return Err(RpcError::Frame(self.fail(e)));
                }
                Ok(_) => {}
                Err(FrameError::Io(e))
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    if deadline.expired(self.read_timeout) {
                        return Err(RpcError::Timeout);
                    }
                }
                Err(e) => return Err(RpcError::Frame(self.fail(e))),
            }
        }
    }
}

/// A wait of at most `timeout`. Its clock starts only when the first read did not bring the
/// whole answer (the socket's read timeout bounds that first read), so a call answered by its
/// first read never reads the clock; a wait may thus last up to twice `timeout` when the answer
/// trickles in.
#[derive(Clone, Copy)]
enum Deadline {
    /// Nothing read yet.
    Fresh(Duration),
    /// The first read is under way.
    FirstRead(Duration),
    /// The clock runs.
    At(Instant),
}

impl Deadline {
    fn after(timeout: Duration) -> Self {
        Deadline::Fresh(timeout)
    }

    /// The longest the next read may wait.
    fn left(&mut self) -> Duration {
        match *self {
            Deadline::Fresh(t) => {
                *self = Deadline::FirstRead(t);
                t
            }
            Deadline::FirstRead(t) => {
                *self = Deadline::At(Instant::now() + t);
                t
            }
            Deadline::At(at) => at.saturating_duration_since(Instant::now()),
        }
    }

    /// After a read that timed out having waited `waited`: whether the time is up.
    fn expired(&mut self, waited: Duration) -> bool {
        if let Deadline::FirstRead(t) | Deadline::Fresh(t) = *self {
            *self = Deadline::At(Instant::now() + t.saturating_sub(waited));
        }
        match *self {
            Deadline::At(at) => Instant::now() >= at,
            _ => false,
        }
    }
}

impl Drop for Connection {
    fn drop(&mut self) {
        if self.broken.is_none() {
            self.out.clear();
            if self.send(&ClientMsg::Bye).is_ok() {
                let _ = self.write_out();
            }
        }
    }
}

#[cfg(test)]
mod tests;
