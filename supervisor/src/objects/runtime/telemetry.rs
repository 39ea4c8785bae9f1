//! Telemetry: the pump and the subscriptions.

use super::*;

/// The newest state of a running loop, as the pump keeps it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Newest {
    /// The newest sample.
    pub sample: TelemetrySample,
    /// Joint accelerations estimated from the two newest samples, rad/s².
    pub acceleration: JointVector,
}

/// What a running loop shares with the non-real-time side.
#[derive(Debug, Default)]
pub struct LoopShared {
    /// The newest sample.
    pub newest: Mutex<Option<Newest>>,
    /// Samples the telemetry ring dropped.
    pub dropped: AtomicU64,
    /// Samples drained.
    pub drained: AtomicU64,
}

impl LoopShared {
    /// The newest sample.
    pub fn newest(&self) -> Option<Newest> {
        self.newest.lock().ok().and_then(|g| *g)
    }
}

/// One telemetry subscription.
#[derive(Debug)]
struct Subscription {
    id: u64,
    session: u64,
    controller: String,
    decimation: u64,
    outbox: Outbox,
    dropped: u64,
}

/// Every subscription of a creator (non-real-time side only).
#[derive(Debug, Default)]
pub struct Subscriptions {
    list: Mutex<Vec<Subscription>>,
    next: AtomicU64,
}

impl Subscriptions {
    /// How many there are.
    pub fn len(&self) -> usize {
        self.list.lock().map(|l| l.len()).unwrap_or(0)
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Adds one (at most `limit`), returning its id.
    ///
    /// # Errors
    /// [`WireError::LimitReached`].
    pub fn add(
        &self,
        session: u64,
        controller: &str,
        decimation: u32,
        outbox: Outbox,
        limit: u32,
    ) -> Result<u64, WireError> {
        let mut list = self
            .list
            .lock()
            .map_err(|_| WireError::Internal("subscriptions poisoned".into()))?;
        list.retain(|s| !s.outbox.is_closed());
        if list.len() >= limit as usize {
            return Err(WireError::LimitReached {
                what: "subscriptions".into(),
                limit,
            });
        }
        let id = self.next.fetch_add(1, Ordering::Relaxed) + 1;
        list.push(Subscription {
            id,
            session,
            controller: controller.to_string(),
            decimation: u64::from(decimation.max(1)),
            outbox,
            dropped: 0,
        });
        Ok(id)
    }

    /// Removes subscription `id` of `session`; false if there was none.
    pub fn remove(&self, session: u64, id: u64) -> bool {
        let Ok(mut list) = self.list.lock() else {
            return false;
        };
        let before = list.len();
        list.retain(|s| !(s.id == id && s.session == session));
        list.len() != before
    }

    /// Removes every subscription of `session`.
    pub fn remove_session(&self, session: u64) {
        if let Ok(mut list) = self.list.lock() {
            list.retain(|s| s.session != session);
        }
    }

    /// Sends `samples` of `controller` to its subscribers, decimated, without waiting: a full
    /// outbox loses the batch (counted), a closed one ends the subscription.
    pub fn publish(&self, controller: &str, samples: &[TelemetrySample], joints: usize) {
        if samples.is_empty() {
            return;
        }
        let Ok(mut list) = self.list.lock() else {
            return;
        };
        list.retain_mut(|s| {
            if s.controller != controller {
                return true;
            }
            let records: Vec<TelemetryRecord> = samples
                .iter()
                .filter(|x| x.seq % s.decimation == 0)
                .map(|x| record(x, joints))
                .collect();
            if records.is_empty() {
                return true;
            }
            let batch = TelemetryBatch {
                subscription: s.id,
                dropped: s.dropped,
                samples: records,
            };
            if s.outbox.try_push(ServerMsg::Telemetry(batch)) {
                true
            } else if s.outbox.is_closed() {
                false
            } else {
                s.dropped += 1;
                true
            }
        });
    }
}

/// A sample as a client sees it.
pub fn record(s: &TelemetrySample, joints: usize) -> TelemetryRecord {
    TelemetryRecord {
        time_ns: s.time.as_nanos(),
        seq: s.seq,
        q: joints_from_vector(&s.q, joints),
        qd: joints_from_vector(&s.qd, joints),
        effort: joints_from_vector(&s.effort, joints),
        tool_position: [s.tool_position.x, s.tool_position.y, s.tool_position.z],
        wrench: WrenchMsg::from(&s.wrench),
        state: s.state.as_str().to_string(),
        fault: s.fault.map(|f| f.to_string()),
    }
}

/// Runs a telemetry pump until `stop` (then drains once more): every `period`, takes every sample
/// out of the ring, keeps the newest in `shared`, and publishes them to the subscribers of
/// `controller`.
#[allow(clippy::too_many_arguments)]
pub fn run_pump(
    ring: &mut ArcConsumer<TelemetrySample, TELEMETRY_CAPACITY>,
    shared: &LoopShared,
    subscriptions: &Subscriptions,
    controller: &str,
    joints: usize,
    period: Duration,
    stop: &AtomicBool,
) {
    let mut batch: Vec<TelemetrySample> = Vec::with_capacity(TELEMETRY_CAPACITY);
    let mut previous: Option<TelemetrySample> = shared.newest().map(|n| n.sample);
    loop {
        let last_round = stop.load(Ordering::Acquire);
        if !last_round {
            std::thread::sleep(period);
        }
        batch.clear();
        while let Some(s) = ring.pop() {
            batch.push(s);
        }
        shared
            .dropped
            .store(ring.dropped() as u64, Ordering::Relaxed);
        shared
            .drained
            .fetch_add(batch.len() as u64, Ordering::Relaxed);
        if let Some(last) = batch.last().copied() {
            let before = batch.len().checked_sub(2).map(|i| batch[i]).or(previous);
            let acceleration = match before {
                Some(b) if last.time > b.time => {
                    (last.qd - b.qd) / (last.time - b.time).as_secs_f64()
                }
                _ => JointVector::zeros(),
            };
            if let Ok(mut g) = shared.newest.lock() {
                *g = Some(Newest {
                    sample: last,
                    acceleration,
                });
            }
            previous = Some(last);
        }
        subscriptions.publish(controller, &batch, joints);
        if last_round {
            break;
        }
    }
}
