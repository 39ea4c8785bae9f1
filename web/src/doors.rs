//! What stands before every handler of `penelope web`: which names it answers to, how many
//! connections it holds, and how long a request's head may take.
//!
//! - **Host names** ([`Hosts`], [`named_host`]): a request is served only when its `Host` names
//!   this server: its listen address (any IP address of the machine, when it listens on all of
//!   them), `localhost`, both with the listen port, or a name given with `--allow-host`. A page
//!   of another site whose name was rebound to this machine (DNS rebinding) sends its own name
//!   and gets 421, so the same-origin check, which compares `Origin` with `Host`, cannot be
//!   met by a foreign page.
//! - **Connections** ([`Connections`]): at most [`MAX_CONNECTIONS`] at once, and at most
//!   [`MAX_CONNECTIONS_PER_CLIENT`] of one client (an IPv4 address, an IPv6 /64); a connection
//!   beyond either is closed at once, so one client's stalled sockets leave room for others.
//! - **Header deadline** ([`HEADER_DEADLINE`]): hyper's own `header_read_timeout` closes a
//!   connection whose request head (or next request, on an idle keep-alive connection) has
//!   not arrived in time.

use std::collections::HashMap;
use std::net::{IpAddr, Ipv6Addr, SocketAddr};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use axum::Router;
use axum::extract::{ConnectInfo, Request, State};
use axum::http::uri::Authority;
use axum::http::{StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use hyper_util::rt::{TokioIo, TokioTimer};

/// How long a connection may take to send a request's head (and an idle keep-alive connection
/// its next one) before it is closed.
pub(crate) const HEADER_DEADLINE: Duration = Duration::from_secs(10);
/// Connections held at once; beyond it a new one is closed at once.
pub(crate) const MAX_CONNECTIONS: usize = 512;
/// Connections of one client held at once (a browser opens about 6, plus a WebSocket per plot).
pub(crate) const MAX_CONNECTIONS_PER_CLIENT: usize = 64;

/// The names this server answers to.
#[derive(Debug)]
pub(crate) struct Hosts {
    /// The address it listens on (the port as bound).
    bound: SocketAddr,
    /// `--allow-host` names, lower case, each with its port if it was given one.
    names: Vec<(String, Option<u16>)>,
}

impl Hosts {
    /// The names of a server bound to `bound`, with the `--allow-host` names `allowed`
    /// (`NAME` for any port, `NAME:PORT` for that port).
    ///
    /// # Errors
    /// A name that is not a host name (with an optional port).
    pub(crate) fn new(bound: SocketAddr, allowed: &[String]) -> anyhow::Result<Hosts> {
        let names = allowed
            .iter()
            .map(|name| {
                let authority = name
                    .parse::<Authority>()
                    .ok()
                    .filter(|a| !a.as_str().contains('@') && !a.host().is_empty())
                    .ok_or_else(|| {
                        crate::cli::usage(format!("--allow-host `{name}` is not NAME or NAME:PORT"))
                    })?;
                Ok((unbracket(authority.host()), authority.port_u16()))
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(Hosts { bound, names })
    }

    /// Whether `host` (a `Host` header or a request's authority) names this server.
    pub(crate) fn admits(&self, host: &str) -> bool {
        let Some(authority) = host
            .parse::<Authority>()
            .ok()
            .filter(|a| !a.as_str().contains('@'))
        else {
            return false;
        };
        let name = unbracket(authority.host());
        // No port is the scheme's default, as the browser sends it.
        let port = authority.port_u16().unwrap_or(80);
        if let Ok(ip) = name.parse::<IpAddr>() {
            // An address cannot be rebound: it names this server if it is the listen address.
            return port == self.bound.port()
                && (ip == self.bound.ip() || self.bound.ip().is_unspecified());
        }
        if name == "localhost" {
            return port == self.bound.port();
        }
        self.names
            .iter()
            .any(|(n, p)| *n == name && p.is_none_or(|p| p == port))
    }
}

/// `host` lower case, without an IPv6 address's brackets.
fn unbracket(host: &str) -> String {
    host.trim_start_matches('[')
        .trim_end_matches(']')
        .to_ascii_lowercase()
}

/// Serves the request only when its `Host` (and its authority, in absolute form) names this
/// server; 421 Misdirected Request otherwise.
pub(crate) async fn named_host(
    State(hosts): State<Arc<Hosts>>,
    request: Request,
    next: Next,
) -> Response {
    let host = request
        .headers()
        .get(header::HOST)
        .and_then(|v| v.to_str().ok());
    let named = host.is_some_and(|h| hosts.admits(h))
        && request
            .uri()
            .authority()
            .is_none_or(|a| hosts.admits(a.as_str()));
    if named {
        return next.run(request).await;
    }
    let message = format!(
        "refused: `Host: {}` does not name this server (its listen address, localhost, or an \
         --allow-host name)",
        host.unwrap_or("")
    );
    (
        StatusCode::MISDIRECTED_REQUEST,
        axum::Json(serde_json::json!({ "kind": "misdirected", "message": message })),
    )
        .into_response()
}

/// The client a connection or login is counted against: an IPv4 address, or the /64 of an
/// IPv6 address (one host usually holds a whole /64).
pub(crate) fn client_of(ip: IpAddr) -> IpAddr {
    match ip {
        IpAddr::V4(_) => ip,
        IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
            Some(v4) => IpAddr::V4(v4),
            None => {
                let mut s = v6.segments();
                s[4..].fill(0);
                IpAddr::V6(Ipv6Addr::from(s))
            }
        },
    }
}

/// The connections held, in all and per client.
#[derive(Debug, Default)]
pub(crate) struct Connections {
    open: Mutex<(usize, HashMap<IpAddr, usize>)>,
}

/// One held connection; dropping it frees its place.
#[derive(Debug)]
pub(crate) struct Slot {
    connections: Arc<Connections>,
    client: IpAddr,
}

impl Connections {
    /// A place for a connection from `peer`, or none when the server or that client holds its
    /// most.
    pub(crate) fn admit(self: &Arc<Self>, peer: IpAddr) -> Option<Slot> {
        let client = client_of(peer);
        let mut open = self.open.lock().unwrap_or_else(PoisonError::into_inner);
        let of_client = open.1.get(&client).copied().unwrap_or(0);
        if open.0 >= MAX_CONNECTIONS || of_client >= MAX_CONNECTIONS_PER_CLIENT {
            return None;
        }
        open.0 += 1;
        open.1.insert(client, of_client + 1);
        Some(Slot {
            connections: self.clone(),
            client,
        })
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        let mut open = self
            .connections
            .open
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        open.0 -= 1;
        if let Some(n) = open.1.get_mut(&self.client) {
            *n -= 1;
            if *n == 0 {
                open.1.remove(&self.client);
            }
        }
    }
}

/// Accepts connections on `listener` and serves `app` on each, within the connection caps
/// and the header deadline; each request carries its peer as [`ConnectInfo`]. Never returns.
pub(crate) async fn serve(listener: tokio::net::TcpListener, app: Router) {
    let connections = Arc::new(Connections::default());
    loop {
        let (stream, peer) = match listener.accept().await {
            Ok(accepted) => accepted,
            // Out of descriptors or an aborted handshake: the next accept may do; pause so a
            // persistent error does not spin.
            Err(_) => {
                tokio::time::sleep(Duration::from_millis(20)).await;
                continue;
            }
        };
        let Some(slot) = connections.admit(peer.ip()) else {
            drop(stream);
            continue;
        };
        let app = app.clone();
        tokio::spawn(async move {
            let _slot = slot;
            let service = hyper::service::service_fn(move |mut request: Request<_>| {
                request.extensions_mut().insert(ConnectInfo(peer));
                let mut app = app.clone();
                async move {
                    tower_service::Service::call(&mut app, request.map(axum::body::Body::new)).await
                }
            });
            let mut builder = hyper::server::conn::http1::Builder::new();
            builder
                .timer(TokioTimer::new())
                .header_read_timeout(HEADER_DEADLINE);
            // A connection's end (closed, timed out, malformed) concerns that connection only.
            let _ = builder
                .serve_connection(TokioIo::new(stream), service)
                .with_upgrades()
                .await;
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_names_of_this_server_are_admitted() {
        let hosts = Hosts::new(
            "127.0.0.1:8080".parse().unwrap(),
            &["lab.example".into(), "proxy.example:443".into()],
        )
        .unwrap();
        for ok in [
            "127.0.0.1:8080",
            "localhost:8080",
            "LOCALHOST:8080",
            "lab.example:8080",
            "lab.example",
            "proxy.example:443",
        ] {
            assert!(hosts.admits(ok), "{ok}");
        }
        for refused in [
            "evil.example:8080",
            "127.0.0.1:8081",
            "127.0.0.2:8080",
            "127.0.0.1",
            "localhost",
            "proxy.example:8080",
            "a@127.0.0.1:8080",
            "lab.example.evil.example",
            "",
        ] {
            assert!(!hosts.admits(refused), "{refused}");
        }
        let any = Hosts::new("[::]:80".parse().unwrap(), &[]).unwrap();
        assert!(any.admits("10.1.2.3") && any.admits("[::1]") && any.admits("localhost"));
        assert!(!any.admits("evil.example"));
        assert!(Hosts::new("127.0.0.1:1".parse().unwrap(), &["a b".into()]).is_err());
    }

    #[test]
    fn connections_are_capped_per_client_and_freed_when_dropped() {
        let c = Arc::new(Connections::default());
        let one: IpAddr = "10.0.0.1".parse().unwrap();
        let held: Vec<Slot> = (0..MAX_CONNECTIONS_PER_CLIENT)
            .map(|_| c.admit(one).unwrap())
            .collect();
        assert!(c.admit(one).is_none());
        // Another address of the same IPv6 /64 is the same client; another client is not.
        let v6: IpAddr = "2001:db8::1".parse().unwrap();
        let v6_held: Vec<Slot> = (0..MAX_CONNECTIONS_PER_CLIENT)
            .map(|_| c.admit(v6).unwrap())
            .collect();
        assert!(c.admit("2001:db8::ffff".parse().unwrap()).is_none());
        assert!(c.admit("10.0.0.2".parse().unwrap()).is_some());
        drop(held);
        assert!(c.admit(one).is_some());
        drop(v6_held);
        assert_eq!(c.open.lock().unwrap().0, 0);
    }
}
