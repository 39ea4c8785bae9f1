//! The WebSocket side: who may connect, and one task per client that writes its two queues
//! (control first) and reads its requests: subscriptions and the e-stop service.
//!
//! The Foxglove protocol has no authentication, so this server listens on loopback only (the
//! command refuses any other address), and a browser page may connect only from an origin it
//! allows: none (a script), a desktop app's (`file://`), loopback pages, Foxglove's web app, and those given
//! with `--allow-origin`. Without that check any web site open in the operator's browser could
//! read the telemetry from `ws://127.0.0.1:8765`. At most [`MAX_CLIENTS`] at once.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use axum::Router;
use axum::extract::ws::{Message, Utf8Bytes, WebSocket, WebSocketUpgrade};
use axum::extract::{ConnectInfo, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use penelope_protocol::client::{Client, estop_reports};
use serde_json::json;

use crate::hub::{Hub, Outgoing};
use crate::topics;
use crate::wire::{self, ClientOp, Level, ServiceAd};

/// Clients served at once.
pub const MAX_CLIENTS: usize = 16;
/// Largest message a client may send (requests are small).
const MAX_REQUEST: usize = 64 * 1024;
/// The e-stop service's id.
pub const ESTOP_SERVICE_ID: u32 = 1;
/// Foxglove's web app, allowed as an origin by default.
pub const FOXGLOVE_APP_ORIGIN: &str = "https://app.foxglove.dev";

/// What the socket handlers share.
pub struct ServerState {
    /// Channels and clients.
    pub hub: Arc<Hub>,
    /// The system (for the e-stop).
    pub client: Client,
    /// Whether the e-stop service is offered.
    pub estop: bool,
    /// Origins allowed besides none and loopback (`*`: any).
    pub origins: Vec<String>,
    /// Clients connected now.
    pub connected: AtomicUsize,
    /// E-stop calls under way (at most [`MAX_ESTOPS`]).
    pub estops: AtomicUsize,
}

/// E-stop calls under way at once: each asks every node on connections of its own, so a
/// client repeating the call cannot open connections without bound (the first is enough).
pub const MAX_ESTOPS: usize = 4;

/// The e-stop service as advertised.
pub fn estop_service() -> ServiceAd {
    ServiceAd {
        id: ESTOP_SERVICE_ID,
        name: topics::ESTOP_SERVICE.to_string(),
        kind: topics::ESTOP_TYPE.to_string(),
        request: (
            "penelope.EStopRequest".to_string(),
            topics::ESTOP_REQUEST_SCHEMA.to_string(),
        ),
        response: (
            "penelope.EStopReply".to_string(),
            topics::ESTOP_REPLY_SCHEMA.to_string(),
        ),
    }
}

/// The routes: the WebSocket at `/`.
pub fn router(state: Arc<ServerState>) -> Router {
    Router::new().route("/", get(upgrade)).with_state(state)
}

/// Whether a page of `origin` may connect: a loopback page, Foxglove's app, or one allowed.
pub fn origin_allowed(origin: &str, allowed: &[String]) -> bool {
    if allowed
        .iter()
        .any(|a| a == "*" || a.eq_ignore_ascii_case(origin))
    {
        return true;
    }
    // Foxglove's web app; a desktop app's own page (Electron's `file://`).
    if origin.eq_ignore_ascii_case(FOXGLOVE_APP_ORIGIN) || origin.starts_with("file://") {
        return true;
    }
    let Some(rest) = origin
        .strip_prefix("http://")
        .or_else(|| origin.strip_prefix("https://"))
    else {
        return false;
    };
    let host = if let Some(v6) = rest.strip_prefix('[') {
        v6.split(']').next().unwrap_or("")
    } else {
        rest.split(':').next().unwrap_or("")
    };
    host.eq_ignore_ascii_case("localhost")
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

async fn upgrade(
    State(state): State<Arc<ServerState>>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    upgrade: WebSocketUpgrade,
) -> Response {
    if let Some(origin) = headers.get("origin") {
        let origin = origin.to_str().unwrap_or("");
        if !origin_allowed(origin, &state.origins) {
            return (
                StatusCode::FORBIDDEN,
                format!(
                    "a page of {origin} may not connect (allow it with `penelope foxglove --allow-origin {origin}`)"
                ),
            )
                .into_response();
        }
    }
    let upgrade = upgrade
        .protocols(wire::SUBPROTOCOLS)
        .max_message_size(MAX_REQUEST);
    if upgrade.selected_protocol().is_none() {
        return (
            StatusCode::BAD_REQUEST,
            format!(
                "offer the WebSocket subprotocol {} (Sec-WebSocket-Protocol)",
                wire::SUBPROTOCOLS.join(" or ")
            ),
        )
            .into_response();
    }
    if state.connected.fetch_add(1, Ordering::AcqRel) >= MAX_CLIENTS {
        state.connected.fetch_sub(1, Ordering::AcqRel);
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            format!("{MAX_CLIENTS} clients are connected: close one first"),
        )
            .into_response();
    }
    let slot = Slot(state.clone());
    upgrade
        .on_failed_upgrade(|_| ())
        .on_upgrade(move |ws| async move {
            serve_client(slot.0.clone(), peer, ws).await;
            drop(slot);
        })
}

/// A client's place in [`ServerState::connected`], given back when dropped.
struct Slot(Arc<ServerState>);

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.connected.fetch_sub(1, Ordering::AcqRel);
    }
}

fn to_message(out: Outgoing) -> Message {
    match out {
        Outgoing::Text(t) => Message::Text(Utf8Bytes::from(t)),
        Outgoing::Binary(b) => Message::Binary(b.into()),
    }
}

async fn serve_client(state: Arc<ServerState>, peer: SocketAddr, mut ws: WebSocket) {
    let mut queues = state.hub.connect(peer);
    let id = queues.id;
    loop {
        tokio::select! {
            biased;
            out = queues.control.recv() => match out {
                Some(m) => if ws.send(to_message(m)).await.is_err() { break },
                // Disconnected by the hub (a full control queue).
                None => break,
            },
            out = queues.data.recv() => match out {
                Some(m) => if ws.send(to_message(m)).await.is_err() { break },
                None => break,
            },
            incoming = ws.recv() => match incoming {
                Some(Ok(Message::Text(t))) => handle(&state, id, wire::parse_text(t.as_str())),
                Some(Ok(Message::Binary(b))) => handle(&state, id, wire::parse_binary(&b)),
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => break,
                Some(Ok(_)) => {}
            },
        }
    }
    if let Some(stats) = state.hub.disconnect(id)
        && stats.dropped > 0
    {
        eprintln!(
            "penelope foxglove: client {} ({}) left; it read too slowly for {} of {} messages (dropped)",
            stats.id,
            stats.address,
            stats.dropped,
            stats.dropped + stats.queued
        );
    }
    let _ = ws.send(Message::Close(None)).await;
}

fn warn(state: &ServerState, id: u64, message: &str) {
    state
        .hub
        .send_control(id, Outgoing::Text(wire::status(Level::Warning, message)));
}

fn handle(state: &Arc<ServerState>, id: u64, op: Result<ClientOp, wire::ParseError>) {
    match op {
        Err(e) => warn(state, id, &e.to_string()),
        Ok(ClientOp::Subscribe(subs)) => {
            for (sub, channel) in subs {
                if let Err(e) = state.hub.subscribe(id, sub, channel) {
                    warn(state, id, &format!("subscription {sub}: {e}"));
                }
            }
        }
        Ok(ClientOp::Unsubscribe(subs)) => {
            for sub in subs {
                state.hub.unsubscribe(id, sub);
            }
        }
        Ok(ClientOp::ServiceCall {
            service_id,
            call_id,
            encoding,
            ..
        }) => {
            let fail = |message: &str| {
                state.hub.send_control(
                    id,
                    Outgoing::Text(wire::service_call_failure(service_id, call_id, message)),
                );
            };
            if service_id != ESTOP_SERVICE_ID || !state.estop {
                return fail(&format!("no service {service_id}"));
            }
            if encoding != "json" {
                return fail(&format!("requests are json, not {encoding}"));
            }
            if state.estops.fetch_add(1, Ordering::AcqRel) >= MAX_ESTOPS {
                state.estops.fetch_sub(1, Ordering::AcqRel);
                return fail(&format!(
                    "{MAX_ESTOPS} e-stops are under way already: every loop is being stopped"
                ));
            }
            let state = state.clone();
            // The client library blocks; an e-stop has a thread of the pool to itself.
            tokio::task::spawn_blocking(move || {
                let answer = estop(&state.client);
                state.estops.fetch_sub(1, Ordering::AcqRel);
                let message = match answer {
                    Ok(body) => Outgoing::Binary(wire::service_call_response(
                        service_id,
                        call_id,
                        body.as_bytes(),
                    )),
                    Err(message) => {
                        Outgoing::Text(wire::service_call_failure(service_id, call_id, &message))
                    }
                };
                state.hub.send_control(id, message);
            });
        }
        Ok(ClientOp::Unsupported(what)) => warn(
            state,
            id,
            &format!(
                "`{what}` is not offered by this server (it serves subscriptions and the e-stop service)"
            ),
        ),
    }
}

/// The global e-stop, as `penelope web`'s red button: every loop of every node latched, each
/// node asked at once on a connection of its own. The reply's JSON, or why some node was not
/// reached (the others are stopped all the same).
fn estop(client: &Client) -> Result<String, String> {
    let answers = client
        .estop_all()
        .map_err(|e| format!("E-STOP could not list the nodes: {e}"))?;
    let nodes = estop_reports(answers).map_err(|e| e.to_string())?;
    Ok(json!({ "nodes": nodes }).to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pages_of_loopback_and_foxglove_may_connect_others_only_when_allowed() {
        let none: Vec<String> = Vec::new();
        for ok in [
            "http://localhost:8080",
            "http://127.0.0.1",
            "http://[::1]:3000",
            "https://app.foxglove.dev",
            "file://",
        ] {
            assert!(origin_allowed(ok, &none), "{ok}");
        }
        for bad in [
            "https://evil.example",
            "http://localhost.evil.example",
            "http://127.0.0.1.evil.example:80",
            "null",
        ] {
            assert!(!origin_allowed(bad, &none), "{bad}");
        }
        assert!(origin_allowed(
            "https://lab.example",
            &["https://lab.example".to_string()]
        ));
        assert!(origin_allowed("https://x.example", &["*".to_string()]));
    }
}
