//! The handshake of a connection: the hellos and, with a secret, the Noise handshake of
//! [`crate::net::auth`], after which the connection is sealed.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use super::{Conn, End, POLL_EVERY, bump, lock, msg_name};
use crate::net::auth::{self, PSK_LEN, SealError};
use crate::proto::{
    ClientMsg, MAGIC, PROTOCOL_VERSION, Role, Security, ServerHello, ServerMsg, WireError,
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
        let (hello, client_body) = match self.next_frame(Some(deadline), true)? {
            (ClientMsg::Hello(h), body) => (h, body),
            (other, _) => {
                bump(&self.shared.counters.malformed);
                return Err(self.fail(WireError::Unexpected(format!(
                    "{} before the hello",
                    msg_name(&other)
                ))));
            }
        };
        if hello.magic != MAGIC {
            bump(&self.shared.counters.malformed);
            return Err(self.fail(WireError::BadMagic));
        }
        if hello.version != PROTOCOL_VERSION {
            bump(&self.shared.counters.malformed);
            return Err(self.fail(WireError::VersionMismatch {
                ours: PROTOCOL_VERSION,
                theirs: hello.version,
            }));
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
                self.queue(&ours);
                let (role, psk) = match (hello.role, admin) {
                    (Role::Admin, Some(admin)) => (Role::Admin, admin),
                    (Role::Admin, None) => (Role::Reader, member),
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

    /// Takes a session slot for `role` and leaves the pending pool, before the handshake's last
    /// message goes out: a client is then never told it is connected by a connection that the
    /// pool may still evict (an eviction that came first is the client's answer instead).
    fn open_session(&mut self, role: Role) -> Result<(), End> {
        let admission = &self.shared.admission;
        if let Err(e) = admission.open_session(self.id, role) {
            bump(&self.shared.counters.refused);
            return Err(self.fail(e));
        }
        self.in_session = true;
        // Evicted while still pending (the flag is set under the admission lock, which
        // `open_session` took after it): give the slot back and say so.
        if self.evicted.load(Ordering::Acquire) {
            admission.close_session();
            self.in_session = false;
            return Err(self.evict());
        }
        Ok(())
    }

    /// The Noise handshake (after the hellos, which are its prologue): checks the client's
    /// message, takes a session slot for `role`, answers, and seals the connection from then on.
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
        match auth::answer(psk, &prologue, &first) {
            Ok((second, keys)) => {
                self.open_session(role)?;
                self.queue(&ServerMsg::Handshake { noise: second });
                if !self.flush() {
                    return Err(self.dropped_writer());
                }
                let (sealer, opener) = keys.split();
                lock(&self.wire).sealer = Some(sealer);
                self.opener = Some(opener);
                self.decoder
                    .set_max(auth::sealed_len(self.shared.config.max_frame));
                Ok(())
            }
            Err(SealError::Handshake) => {
                bump(&self.shared.counters.auth_failures);
                Err(self.fail(WireError::AuthFailed))
            }
            Err(e) => {
                log::error!("noise handshake failed: {e}");
                Err(self.fail(WireError::Internal("handshake failed".into())))
            }
        }
    }
}
