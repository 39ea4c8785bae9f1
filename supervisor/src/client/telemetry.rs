//! A telemetry subscription on a connection of its own.
//!
//! The node pushes batches of samples as the loop runs and drops batches, never queues them
//! without bound, when this side reads too slowly ([`TelemetryStream::dropped`] counts them).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use super::{parse_address, unexpected};
use crate::net::conn::{ClientConfig, Connection, RpcError};
use crate::proto::{Call, ObjectRef, Reply, TelemetryRecord, object_path};

/// The telemetry of one object, sample after sample. Unsubscribes (and closes its connection)
/// when dropped.
///
/// As an [`Iterator`], it waits up to [`TelemetryStream::timeout`] for each sample, yields
/// `Err(RpcError::Timeout)` when none came and ends after a transport error.
#[derive(Debug)]
pub struct TelemetryStream {
    conn: Connection,
    subscription: u64,
    path: String,
    pending: VecDeque<TelemetryRecord>,
    dropped: u64,
    timeout: Duration,
    broken: bool,
}

impl TelemetryStream {
    /// Opens a connection to the node of `reference` and subscribes to the object, one tick in
    /// `decimation`.
    ///
    /// # Errors
    /// The node's refusal or a transport error.
    pub(crate) fn open(
        reference: &ObjectRef,
        config: &ClientConfig,
        decimation: u32,
    ) -> Result<TelemetryStream, RpcError> {
        let address = parse_address(reference)?;
        let mut conn = Connection::connect(address, config)?;
        let subscription = match conn.call(Call::Subscribe {
            object: reference.name.clone(),
            decimation: decimation.max(1),
        })? {
            Reply::Subscribed { subscription } => subscription,
            other => return Err(unexpected("a subscription", &other)),
        };
        Ok(TelemetryStream {
            conn,
            subscription,
            path: object_path(&reference.node, reference.class, &reference.name),
            pending: VecDeque::new(),
            dropped: 0,
            timeout: config.timeout,
            broken: false,
        })
    }

    /// The subscription's id on its connection.
    pub fn subscription(&self) -> u64 {
        self.subscription
    }

    /// The naming path of the object watched.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Batches the node dropped so far because this side read too slowly.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// How long the iterator waits for one sample.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// Sets how long the iterator waits for one sample.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// The next sample, waiting at most `timeout`; `Ok(None)` if none came in time.
    ///
    /// # Errors
    /// A transport error (the node went away); the stream is then finished.
    pub fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<TelemetryRecord>, RpcError> {
        if let Some(sample) = self.pending.pop_front() {
            return Ok(Some(sample));
        }
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.conn.next_telemetry(left) {
                Ok(Some(batch)) => {
                    if batch.subscription == self.subscription {
                        self.dropped = self.dropped.max(batch.dropped);
                        self.pending.extend(batch.samples);
                        if let Some(sample) = self.pending.pop_front() {
                            return Ok(Some(sample));
                        }
                    }
                }
                Ok(None) | Err(RpcError::Timeout) => return Ok(None),
                Err(e) => {
                    self.broken = true;
                    return Err(e);
                }
            }
            if left.is_zero() {
                return Ok(None);
            }
        }
    }
}

impl Iterator for TelemetryStream {
    type Item = Result<TelemetryRecord, RpcError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.broken {
            return None;
        }
        match self.recv_timeout(self.timeout) {
            Ok(Some(sample)) => Some(Ok(sample)),
            Ok(None) => Some(Err(RpcError::Timeout)),
            Err(e) => Some(Err(e)),
        }
    }
}

impl Drop for TelemetryStream {
    fn drop(&mut self) {
        if !self.broken {
            // Best effort: the node also drops the subscription when the connection closes.
            let _ = self.conn.call(Call::Unsubscribe {
                subscription: self.subscription,
            });
        }
    }
}
