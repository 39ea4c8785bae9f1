//! Live telemetry for the page's plots: one WebSocket per watched controller (or robot).
//!
//! Each socket gets its own subscription of the client library, decimated by the node (one
//! tick in `decimation`), exactly as `penelope ctl watch` subscribes: the node's telemetry
//! thread copies from the rings and the loop never sees a browser. A thread of ours reads the
//! subscription and hands batches every [`BATCH_PERIOD`] to the socket through a bounded queue;
//! a browser too slow to take them loses batches (counted), never holds the thread up.
//!
//! Messages, JSON text:
//! - `{"type":"batch","records":[{"t":s,"seq":n,"q":[rad],"p":[m],"f":[N,N·m],"s":state}],"dropped":n}`
//! - `{"type":"event","t":s,"from":state,"to":state,"fault":text|null}`: the loop's safety state
//!   changed (an e-stop, a fault, a re-arm): the safety events a client can see.
//! - `{"type":"status","ticks":n,"overruns":n,"telemetry_dropped":n,"running":bool}` every
//!   [`STATUS_PERIOD`]: the loop's timing counters.
//! - `{"type":"error","error":{"kind":..,"message":..}}`, then the socket closes.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use axum::extract::ws::{Message, Utf8Bytes, WebSocket, WebSocketUpgrade};
use axum::extract::{Query, State};
use axum::response::{IntoResponse, Response};
use penelope_protocol::proto::{Class, ControllerMethod, Method, Reply, TelemetryRecord};
use serde::Deserialize;
use serde_json::{Value, json};
use tokio::sync::mpsc;

use super::WebState;
use super::api::ApiError;

/// How often a batch goes to the browser (a plot redraws at about this rate).
pub(crate) const BATCH_PERIOD: Duration = Duration::from_millis(50);
/// How often the loop's counters are read.
const STATUS_PERIOD: Duration = Duration::from_millis(500);
/// Batches queued for one socket before new ones are dropped.
const QUEUE: usize = 32;
/// The default decimation: one tick in 10 (100 samples/s of a 1 kHz loop).
const DEFAULT_DECIMATION: u32 = 10;
/// Live sockets one server keeps open at once: each holds a thread and a subscription (a
/// connection to the node, whose own bounds are the last word).
pub(crate) const MAX_SOCKETS: usize = 64;

/// `GET /api/live?path=&decimation=`.
#[derive(Deserialize)]
pub(crate) struct LiveQuery {
    path: String,
    decimation: Option<u32>,
}

/// `GET /api/live`: upgrades to the WebSocket described in the module docs.
pub(crate) async fn socket(
    State(state): State<Arc<WebState>>,
    Query(q): Query<LiveQuery>,
    upgrade: WebSocketUpgrade,
) -> Response {
    let decimation = q.decimation.unwrap_or(DEFAULT_DECIMATION);
    if !(1..=100_000).contains(&decimation) {
        return ApiError::bad_input(format!("decimation must be 1..=100000, got {decimation}"))
            .into_response();
    }
    let slot = match SocketSlot::take(&state) {
        Ok(slot) => slot,
        Err(e) => return e.into_response(),
    };
    upgrade
        .on_failed_upgrade(|_| ())
        .on_upgrade(move |ws| async move {
            follow(slot.0.clone(), q.path, decimation, ws).await;
            drop(slot);
        })
}

/// A live socket's place in [`WebState::live_sockets`], given back when dropped (also when
/// the upgrade never completes and the future is dropped unrun).
pub(crate) struct SocketSlot(pub(crate) Arc<WebState>);

impl SocketSlot {
    /// Takes a place (counted from here to the socket's end: before the upgrade is answered),
    /// or says the server has [`MAX_SOCKETS`] open.
    pub(crate) fn take(state: &Arc<WebState>) -> Result<SocketSlot, ApiError> {
        let open = state.live_sockets.fetch_add(1, Ordering::AcqRel);
        if open >= MAX_SOCKETS {
            state.live_sockets.fetch_sub(1, Ordering::AcqRel);
            return Err(ApiError::busy(format!(
                "{MAX_SOCKETS} live plots and cameras are open on this server: close one first"
            )));
        }
        Ok(SocketSlot(state.clone()))
    }
}

impl Drop for SocketSlot {
    fn drop(&mut self) {
        self.0.live_sockets.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Pumps one subscription into one socket until either ends.
async fn follow(state: Arc<WebState>, path: String, decimation: u32, mut ws: WebSocket) {
    let (tx, mut rx) = mpsc::channel::<String>(QUEUE);
    let client = state.client.clone();
    // The client library blocks: the subscription has a thread of its own for its lifetime.
    let reader = tokio::task::spawn_blocking(move || read(&client, &path, decimation, &tx));
    loop {
        tokio::select! {
            out = rx.recv() => match out {
                Some(text) => {
                    if ws.send(Message::Text(Utf8Bytes::from(text))).await.is_err() {
                        break;
                    }
                }
                None => break,
            },
            incoming = ws.recv() => match incoming {
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => break,
                Some(Ok(_)) => {}
            },
        }
    }
    // Closing the queue tells the reader to stop (and so to end the subscription).
    drop(rx);
    let _ = reader.await;
    let _ = ws.send(Message::Close(None)).await;
}

/// One record as the page plots it.
fn compact(r: &TelemetryRecord, t0_ns: u64) -> Value {
    json!({
        "t": r.time_ns.saturating_sub(t0_ns) as f64 * 1e-9,
        "seq": r.seq,
        "q": r.q,
        "p": r.tool_position,
        "f": [r.wrench.force[0], r.wrench.force[1], r.wrench.force[2],
              r.wrench.torque[0], r.wrench.torque[1], r.wrench.torque[2]],
        "s": r.state,
        // The displayed force: the commanded wrench (what a master's motors produce).
        "d": r.commanded_wrench.force,
        "c": r.clutch,
        "pe": r.port_energy,
        "ce": r.channel_energy,
    })
}

/// The reader thread: subscription -> batches, events and status -> `tx`, until `tx` closes
/// or the subscription fails.
fn read(
    client: &penelope_protocol::client::Client,
    path: &str,
    decimation: u32,
    tx: &mpsc::Sender<String>,
) {
    let fail = |e: ApiError| {
        let _ = tx.blocking_send(json!({ "type": "error", "error": e.to_json() }).to_string());
    };
    let target = match client.locate(path) {
        Ok(r) => r,
        Err(e) => return fail(e.into()),
    };
    let mut stream = match client.subscribe(path, decimation) {
        Ok(s) => s,
        Err(e) => return fail(e.into()),
    };
    let _ = tx.blocking_send(
        json!({ "type": "subscribed", "path": path, "decimation": decimation }).to_string(),
    );
    let mut batch: Vec<Value> = Vec::new();
    let mut last_batch = Instant::now();
    let mut last_status: Option<Instant> = None;
    let mut t0 = None;
    let mut safety: Option<(String, Option<String>)> = None;
    let mut dropped = 0u64;
    while !tx.is_closed() {
        match stream.recv_timeout(BATCH_PERIOD) {
            Ok(Some(rec)) => {
                let t0 = *t0.get_or_insert(rec.time_ns);
                let now = (rec.state.clone(), rec.fault.clone());
                if safety.as_ref() != Some(&now) {
                    if let Some((from, _)) = &safety {
                        let event = json!({
                            "type": "event",
                            "t": rec.time_ns.saturating_sub(t0) as f64 * 1e-9,
                            "from": from, "to": rec.state, "fault": rec.fault,
                        });
                        // Events are few and matter: they wait for room.
                        if tx.blocking_send(event.to_string()).is_err() {
                            return;
                        }
                    }
                    safety = Some(now);
                }
                batch.push(compact(&rec, t0));
            }
            Ok(None) => {}
            Err(e) => return fail(e.into()),
        }
        if last_batch.elapsed() >= BATCH_PERIOD && !batch.is_empty() {
            let msg = json!({ "type": "batch", "records": batch, "dropped": dropped });
            batch = Vec::new();
            last_batch = Instant::now();
            match tx.try_send(msg.to_string()) {
                Ok(()) => {}
                Err(mpsc::error::TrySendError::Full(_)) => dropped += 1,
                Err(mpsc::error::TrySendError::Closed(_)) => return,
            }
        }
        // A robot's socket (the 3D view's) has no loop counters of its own to show.
        if target.class == Class::Controller
            && last_status.is_none_or(|t| t.elapsed() >= STATUS_PERIOD)
        {
            last_status = Some(Instant::now());
            let status = client.call_ref(&target, Method::Controller(ControllerMethod::Status));
            if let Ok(Reply::Status(s)) = status {
                let msg = json!({
                    "type": "status", "ticks": s.ticks, "overruns": s.overruns,
                    "telemetry_dropped": s.telemetry_dropped, "running": s.running,
                });
                let _ = tx.try_send(msg.to_string());
            }
        }
    }
}
