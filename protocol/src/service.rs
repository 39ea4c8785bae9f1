//! The seam between the transport (`net`) and what a node serves (creator, objects, naming).
//!
//! The server decodes a [`Call`] from a connection and hands it to a [`Service`] together with
//! the connection's [`Session`]; the service answers with a [`Reply`] or a [`WireError`]. Streams
//! (telemetry) go back to the connection through the session's [`Outbox`], which never blocks
//! the producer: when the connection is slow, frames are dropped and counted.

#[cfg(doc)]
use crate::proto::CallError;
use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{
    Receiver, RecvTimeoutError, SyncSender, TryRecvError, TrySendError, sync_channel,
};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::proto::{Call, FrameBatch, Method, Reply, Role, ServerMsg, WireError};

/// What a node serves. Called from connection threads (never from a real-time thread), possibly
/// from several at once.
pub trait Service: Send + Sync + 'static {
    /// Serves one call of `session`.
    ///
    /// # Errors
    /// The typed error that goes back to the client in the response.
    fn call(&self, session: &Session, call: Call) -> Result<Reply, WireError>;

    /// The connection of `session` closed: drop its subscriptions.
    fn closed(&self, session: &Session) {
        let _ = session;
    }
}

/// How objects of one node reach objects of other nodes (a controller bound to a sensor that lives
/// elsewhere asks it, once at activation, where it is published on the data plane). The node
/// implements it with the naming service and a client connection; called only from
/// non-real-time threads (connection threads, never a loop's).
pub trait Remote: Send + Sync + 'static {
    /// Calls `method` on the object bound at the naming `path` (`/node/sensors/ft`).
    ///
    /// # Errors
    /// [`CallError::UnknownName`] if nothing is bound there, [`CallError::Remote`] if its node
    /// cannot be reached, or the remote object's own error.
    fn call(&self, path: &str, method: Method) -> Result<Reply, WireError>;
}

/// One client connection, as a [`Service`] sees it.
#[derive(Clone, Debug)]
pub struct Session {
    /// Unique per node run.
    pub id: u64,
    /// The peer's address.
    pub peer: SocketAddr,
    /// The name the client gave in its hello (the node's name for [`Role::Node`]).
    pub client: String,
    /// Who the session speaks for, as its handshake established it.
    pub identity: Identity,
    /// Frames to push to this connection (telemetry).
    pub outbox: Outbox,
}

impl Session {
    /// A session for calls made inside the process (a node's calls to itself, tests): no
    /// connection behind it (its outbox is closed), [`Identity::IN_PROCESS`].
    pub fn in_process(client: &str) -> Session {
        let (outbox, _receiver) = Outbox::bounded(1);
        Session {
            id: u64::MAX,
            peer: SocketAddr::from(([127, 0, 0, 1], 0)),
            client: client.to_string(),
            identity: Identity::IN_PROCESS,
            outbox,
        }
    }
}

/// Who a session speaks for: the role its hello claimed, and whether the handshake proved the
/// secret behind it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Identity {
    /// The role served: the claimed one, except that [`Role::Admin`] at a node without an admin
    /// secret is served as [`Role::Operator`].
    pub role: Role,
    /// The handshake proved the secret (the system secret; for [`Role::Admin`] the admin secret
    /// too). `false` on a plain connection (no secret configured): the role is taken on trust.
    pub proven: bool,
}

impl Identity {
    /// A node's own calls to itself (never crossed a wire), as the node it is.
    pub const LOCAL_NODE: Identity = Identity {
        role: Role::Node,
        proven: true,
    };

    /// Calls made inside the process by its owner (a node applying its system file, tests):
    /// everything is allowed, as to an administrator.
    pub const IN_PROCESS: Identity = Identity {
        role: Role::Admin,
        proven: true,
    };
}

/// A bounded, non-blocking queue of frames to one connection.
///
/// Producers ([`Outbox::try_push`]) never wait: a full queue drops the frame and counts it. The
/// connection's writer drains the other end ([`OutboxReceiver`]).
#[derive(Clone, Debug)]
pub struct Outbox {
    tx: SyncSender<ServerMsg>,
    dropped: Arc<AtomicU64>,
    closed: Arc<AtomicBool>,
    frames_waiting: Arc<FramesWaiting>,
}

/// Per camera subscription, its frame batches in the outbox that the writer has not taken off
/// yet: so that a slow reader's frames wait in the subscription's drop-oldest queue (which
/// drops the oldest) rather than here (which would keep old video).
#[derive(Debug, Default)]
struct FramesWaiting(Mutex<HashMap<u64, usize>>);

impl FramesWaiting {
    /// Counts one more of `subscription`'s unless `limit` wait already.
    fn take_slot(&self, subscription: u64, limit: usize) -> bool {
        let Ok(mut map) = self.0.lock() else {
            return false;
        };
        let n = map.entry(subscription).or_insert(0);
        if *n >= limit {
            return false;
        }
        *n += 1;
        true
    }

    /// One fewer of `subscription`'s waits.
    fn free_slot(&self, subscription: u64) {
        if let Ok(mut map) = self.0.lock()
            && let Some(n) = map.get_mut(&subscription)
        {
            *n = n.saturating_sub(1);
            if *n == 0 {
                map.remove(&subscription);
            }
        }
    }
}

/// The connection writer's end of an [`Outbox`].
#[derive(Debug)]
pub struct OutboxReceiver {
    /// Frames in push order. A writer takes them with [`OutboxReceiver::recv_timeout`] and
    /// [`OutboxReceiver::try_recv`], which free camera frames' places; reading `rx` directly
    /// (tests) leaves them taken.
    pub rx: Receiver<ServerMsg>,
    closed: Arc<AtomicBool>,
    frames_waiting: Arc<FramesWaiting>,
}

impl OutboxReceiver {
    /// The next message, waiting up to `timeout`.
    ///
    /// # Errors
    /// As [`Receiver::recv_timeout`].
    pub fn recv_timeout(&self, timeout: Duration) -> Result<ServerMsg, RecvTimeoutError> {
        self.rx.recv_timeout(timeout).inspect(|m| self.taken(m))
    }

    /// The next message if one is queued.
    ///
    /// # Errors
    /// As [`Receiver::try_recv`].
    pub fn try_recv(&self) -> Result<ServerMsg, TryRecvError> {
        self.rx.try_recv().inspect(|m| self.taken(m))
    }

    fn taken(&self, msg: &ServerMsg) {
        if let ServerMsg::Frames(batch) = msg {
            self.frames_waiting.free_slot(batch.subscription);
        }
    }
}

impl Drop for OutboxReceiver {
    fn drop(&mut self) {
        self.closed.store(true, Ordering::Release);
    }
}

impl Outbox {
    /// An outbox holding at most `capacity` frames, and its receiving end.
    pub fn bounded(capacity: usize) -> (Outbox, OutboxReceiver) {
        let (tx, rx) = sync_channel(capacity.max(1));
        let closed = Arc::new(AtomicBool::new(false));
        let frames_waiting = Arc::new(FramesWaiting::default());
        (
            Outbox {
                tx,
                dropped: Arc::new(AtomicU64::new(0)),
                closed: closed.clone(),
                frames_waiting: frames_waiting.clone(),
            },
            OutboxReceiver {
                rx,
                closed,
                frames_waiting,
            },
        )
    }

    /// Queues a camera subscription's `batch` unless `limit` of that subscription's batches
    /// are in the outbox already, not yet taken off by the writer; `false` when refused (that
    /// limit, full or closed: the caller keeps the batch, so a refusal here is not counted as
    /// a drop).
    pub fn try_push_frames(&self, batch: FrameBatch, limit: usize) -> bool {
        let subscription = batch.subscription;
        if !self.frames_waiting.take_slot(subscription, limit.max(1)) {
            return false;
        }
        match self.tx.try_send(ServerMsg::Frames(batch)) {
            Ok(()) => true,
            Err(e) => {
                self.frames_waiting.free_slot(subscription);
                if matches!(e, TrySendError::Disconnected(_)) {
                    self.closed.store(true, Ordering::Release);
                }
                false
            }
        }
    }

    /// Queues `msg` if there is room; `false` if it was dropped (full or closed).
    pub fn try_push(&self, msg: ServerMsg) -> bool {
        match self.tx.try_send(msg) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
                false
            }
            Err(TrySendError::Disconnected(_)) => {
                self.closed.store(true, Ordering::Release);
                false
            }
        }
    }

    /// Queues `msg`, waiting for room (for responses, which must not be lost). `false` if the
    /// connection is gone.
    pub fn push(&self, msg: ServerMsg) -> bool {
        self.tx.send(msg).is_ok()
    }

    /// Frames dropped so far because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Whether the connection's writer is gone (pushing is pointless).
    pub fn is_closed(&self) -> bool {
        self.closed.load(Ordering::Acquire)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_outbox_drops_and_counts_and_a_closed_one_says_so() {
        let (outbox, receiver) = Outbox::bounded(2);
        let msg = || {
            ServerMsg::Error(WireError::Call(crate::proto::CallError::Internal(
                "test".into(),
            )))
        };
        assert!(outbox.try_push(msg()));
        assert!(outbox.try_push(msg()));
        assert!(!outbox.try_push(msg()));
        assert_eq!(outbox.dropped(), 1);
        assert!(!outbox.is_closed());
        assert_eq!(receiver.rx.recv().unwrap(), msg());
        drop(receiver);
        assert!(outbox.is_closed());
        assert!(!outbox.try_push(msg()));
        assert!(!outbox.push(msg()));
    }

    fn batch(subscription: u64) -> FrameBatch {
        FrameBatch {
            subscription,
            dropped: 0,
            frames: Vec::new(),
        }
    }

    #[test]
    fn a_camera_subscription_holds_at_most_its_limit_of_frames_until_the_writer_takes_them() {
        let (outbox, receiver) = Outbox::bounded(256);
        assert!(outbox.try_push_frames(batch(1), 2));
        assert!(outbox.try_push_frames(batch(1), 2));
        assert!(
            !outbox.try_push_frames(batch(1), 2),
            "a third of subscription 1"
        );
        assert!(
            outbox.try_push_frames(batch(2), 2),
            "another subscription's own"
        );
        assert_eq!(outbox.dropped(), 0, "a refusal at the limit is not a drop");
        assert!(matches!(receiver.try_recv(), Ok(ServerMsg::Frames(b)) if b.subscription == 1));
        assert!(
            outbox.try_push_frames(batch(1), 2),
            "a place freed by the writer"
        );
        assert!(!outbox.try_push_frames(batch(1), 2));
        drop(receiver);
        assert!(!outbox.try_push_frames(batch(3), 2));
        assert!(outbox.is_closed());
    }
}
