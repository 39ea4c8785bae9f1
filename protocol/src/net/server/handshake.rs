//! The handshake of a connection: the hellos and, with a secret, the Noise handshake of
//! [`crate::net::auth`], after which the connection is sealed.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use super::{Conn, End, POLL_EVERY, bump, lock, msg_name};
use crate::net::auth::{self, PSK_LEN, SealError};
use crate::proto::{
    CallError, ClientMsg, MAGIC, PROTOCOL_VERSION, ProtocolError, Role, Security, ServerHello,
    ServerMsg, WireError,
};
use crate::service::Identity;

impl Conn<'_> {
    /// Hello (and, with a secret, the Noise handshake): the client's name and identity, or how
    /// it ended.
    pub(super) fn handshake(&mut self) -> Result<(String, Identity), End> {
        let config = &self.shared.config;
        let deadline = Instant::now() + config.handshake_timeout;
        let _ = self.stream.set_read_timeout(Some(
            config
                .handshake_timeout
                .clamp(Duration::from_millis(1), POLL_EVERY),
        ));
        let (hello, client_body) =
            match self.next_frame(Some(deadline), true)? {
                (ClientMsg::Hello(h), body) => (h, body),
                (other, _) => {
                    bump(&self.shared.counters.malformed);
                    return Err(self.fail(WireError::Protocol(ProtocolError::Unexpected(
                        format!("{} before the hello", msg_name(&other)),
                    ))));
                }
            };
        if hello.magic != MAGIC {
            bump(&self.shared.counters.malformed);
            return Err(self.fail(WireError::Protocol(ProtocolError::BadMagic)));
        }
        if hello.version != PROTOCOL_VERSION {
            bump(&self.shared.counters.malformed);
            return Err(
                self.fail(WireError::Protocol(ProtocolError::VersionMismatch {
                    ours: PROTOCOL_VERSION,
                    theirs: hello.version,
                })),
            );
        }
        self.greeted.store(true, Ordering::Release);
        let psk = self.shared.psk;
        let security = match &psk {
            None => Security::Plain,
            Some((_, admin)) => Security::Noise {
                admin: admin.is_some(),
            },
        };
        let ours = ServerMsg::Hello(ServerHello {
            magic: MAGIC,
            version: PROTOCOL_VERSION,
            node: self.shared.config.node.clone(),
            security,
        });
        let identity = match psk {
            None => {
                // The server hello ends a plain handshake: a session before it goes out.
                self.open_session(hello.role)?;
                self.queue(&ours);
                Identity {
                    role: hello.role,
                    proven: false,
                }
            }
            Some((member, admin)) => {
                if !self.shared.throttle.allows(self.peer.ip(), Instant::now()) {
                    bump(&self.shared.counters.rate_limited);
                    let limit = self.shared.config.auth_failures_per_s.ceil() as u32;
                    return Err(
                        self.fail(WireError::Protocol(ProtocolError::RateLimited { limit }))
                    );
                }
                self.queue(&ours);
                // An admin claim nobody can prove here is served as an operator.
                let (role, psk) = match (hello.role, admin) {
                    (Role::Admin, Some(admin)) => (Role::Admin, admin),
                    (Role::Admin, None) => (Role::Operator, member),
                    (role, _) => (role, member),
                };
                let server_body = postcard::to_stdvec(&ours).unwrap_or_default();
                self.authenticate(&psk, &client_body, &server_body, role, deadline)?;
                Identity { role, proven: true }
            }
        };
        if !self.flush() {
            return Err(self.dropped_writer());
        }
        Ok((hello.client, identity))
    }

    /// Takes a session slot for `role` and leaves the pending pool, before the message that
    /// tells the client it is in goes out (the server hello of a plain handshake, the answer to
    /// the first sealed request): a client is then never told it is connected by a connection
    /// that the pending pool may still evict (an eviction that came first is its answer instead).
    fn open_session(&mut self, role: Role) -> Result<(), End> {
        let admission = &self.shared.admission;
        if self.evicted.load(Ordering::Acquire) {
            return Err(self.evict());
        }
        let activity = self.last_activity.clone();
        if let Err(e) = admission.open_session(self.id, role, activity) {
            bump(&self.shared.counters.refused);
            return Err(self.fail(e));
        }
        self.in_session = true;
        Ok(())
    }

    /// A handshake from this address failed: it counts against the address's throttle.
    fn failed_authentication(&self) {
        bump(&self.shared.counters.auth_failures);
        self.shared.throttle.failed(self.peer.ip(), Instant::now());
    }

    /// The Noise handshake (after the hellos, which are its prologue): checks the client's
    /// message and answers it; then waits for the client's first sealed frame, and only when it
    /// opens takes a session slot for `role`.
    ///
    /// The first message (`-> psk, e`) proves nothing on its own: anyone who saw it on the wire
    /// can replay it, and it verifies again (the answer uses a fresh ephemeral key, so the
    /// replayer cannot use it, but the node cannot tell). The first sealed frame can only be
    /// made with the session's keys, which need the client's ephemeral private key as well as
    /// the secret: it is the proof that cannot be replayed, so a connection holds only a pending
    /// slot (evictable, bounded per address) until it arrives. It is a request (the client
    /// library sends a ping) or a bye; the request loop serves it first.
    fn authenticate(
        &mut self,
        psk: &[u8; PSK_LEN],
        client_hello: &[u8],
        server_hello: &[u8],
        role: Role,
        deadline: Instant,
    ) -> Result<(), End> {
        if !self.flush() {
            return Err(self.dropped_writer());
        }
        let first = match self.next_msg(Some(deadline))? {
            ClientMsg::Handshake { noise } => noise,
            other => {
                log::info!(
                    "connection {} from {}: {} instead of the handshake",
                    self.id,
                    self.peer,
                    msg_name(&other)
                );
                Vec::new()
            }
        };
        let prologue = auth::prologue(client_hello, server_hello);
        let keys = match auth::answer(psk, &prologue, &first) {
            Ok((second, keys)) => {
                self.queue(&ServerMsg::Handshake { noise: second });
                if !self.flush() {
                    return Err(self.dropped_writer());
                }
                keys
            }
            Err(SealError::Handshake) => {
                self.failed_authentication();
                return Err(self.fail(WireError::Protocol(ProtocolError::AuthFailed)));
            }
            Err(e) => {
                log::error!("noise handshake failed: {e}");
                return Err(self.fail(WireError::Call(CallError::Internal(
                    "handshake failed".into(),
                ))));
            }
        };
        let (sealer, opener) = keys.split();
        lock(&self.wire).sealer = Some(sealer);
        self.opener = Some(opener);
        self.decoder
            .set_max(auth::sealed_len(self.shared.config.max_frame));
        // The proof: a frame sealed with this session's keys.
        let proof = match self.next_msg(Some(deadline)) {
            Ok(m) => m,
            Err(end) => {
                // Closed, stalled or sent what does not open: a replayed first message looks
                // like this. An eviction or a shutdown is not the client's failure.
                if !self.evicted.load(Ordering::Acquire) && !matches!(end, End::Shutdown) {
                    self.failed_authentication();
                }
                return Err(end);
            }
        };
        match proof {
            ClientMsg::Request { .. } | ClientMsg::Bye => {}
            other => {
                bump(&self.shared.counters.malformed);
                return Err(
                    self.fail(WireError::Protocol(ProtocolError::Unexpected(format!(
                        "{} after the handshake",
                        msg_name(&other)
                    )))),
                );
            }
        }
        self.open_session(role)?;
        self.first = Some(proof);
        Ok(())
    }
}
