//! Who may use the page: the same rule as every client of the system, said for browsers.
//!
//! - Served on loopback without `--secret-file`, the page is open (as a node on loopback is).
//! - Otherwise a browser proves the shared secret once, at `/login`, and then holds a login
//!   cookie (`HttpOnly`, `SameSite=Strict`, expiring): a random token the server keeps, never
//!   the secret. Until then nothing but the login page is served: pages are redirected to it,
//!   `/api/*` answers 401.
//! - Whatever changes state (every method but `GET`/`HEAD`) and every WebSocket (a `GET` that
//!   streams) must come from the page's own origin: a request whose `Origin` is another (or
//!   `null`), or that the browser marks cross-site (`Sec-Fetch-Site`), is refused with 403. A
//!   request without either header is not from a browser's page, and the login still guards it.

use std::collections::HashMap;
use std::io::Read as _;
use std::net::{IpAddr, SocketAddr};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use axum::extract::{ConnectInfo, Request, State};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Redirect, Response};
use hmac::Mac as _;

use super::WebState;
use super::api::ApiError;
use super::assets;
use super::doors::client_of;

/// The login cookie's name.
pub(crate) const COOKIE: &str = "penelope_login";
/// Logins kept at once; the oldest goes first beyond it.
const MAX_LOGINS: usize = 256;
/// Failed logins allowed to one client (an IPv4 address, an IPv6 /64) per [`FAILURE_WINDOW`]
/// before its attempts are refused until the window ends; other clients are not affected, so a
/// guesser cannot lock the right secret out.
const MAX_FAILURES: u32 = 10;
/// Clients whose failed logins are remembered at once; beyond it the oldest window is forgotten.
const MAX_THROTTLED_CLIENTS: usize = 4096;
/// See [`MAX_FAILURES`].
const FAILURE_WINDOW: Duration = Duration::from_secs(60);

type HmacSha256 = hmac::Hmac<sha2::Sha256>;

/// The logins of one server.
pub(crate) struct Sessions {
    /// The shared secret (none: the page is open, on loopback).
    secret: Option<Vec<u8>>,
    /// A key of this process's: secrets are compared as their MACs under it, in constant time.
    key: [u8; 32],
    /// How long a login lasts.
    lifetime: Duration,
    /// Token -> when it expires.
    logins: Mutex<HashMap<String, Instant>>,
    /// Failed logins per client in its current window: (window start, count).
    failures: Mutex<HashMap<IpAddr, (Instant, u32)>>,
}

impl Sessions {
    /// Logins against `secret` (none: no login), each lasting `lifetime`.
    pub(crate) fn new(secret: Option<Vec<u8>>, lifetime: Duration) -> Sessions {
        Sessions {
            secret,
            key: random_bytes(),
            lifetime,
            logins: Mutex::new(HashMap::new()),
            failures: Mutex::new(HashMap::new()),
        }
    }

    /// Whether a browser must log in.
    pub(crate) fn needs_login(&self) -> bool {
        self.secret.is_some()
    }

    /// Whether `given` is the shared secret (constant time in its content).
    fn is_secret(&self, given: &[u8]) -> bool {
        let Some(secret) = &self.secret else {
            return false;
        };
        let mac = |bytes: &[u8]| {
            let mut m = <HmacSha256 as hmac::KeyInit>::new_from_slice(&self.key)
                .expect("HMAC takes a key of any length");
            m.update(bytes);
            m
        };
        let expected = mac(secret).finalize().into_bytes();
        mac(given).verify_slice(&expected).is_ok()
    }

    /// A new login: its token.
    fn open(&self) -> String {
        let token: String = random_bytes().iter().map(|b| format!("{b:02x}")).collect();
        let now = Instant::now();
        let mut logins = self.logins.lock().unwrap_or_else(PoisonError::into_inner);
        logins.retain(|_, until| *until > now);
        if logins.len() >= MAX_LOGINS
            && let Some(oldest) = logins
                .iter()
                .min_by_key(|(_, until)| **until)
                .map(|(t, _)| t.clone())
        {
            logins.remove(&oldest);
        }
        logins.insert(token.clone(), now + self.lifetime);
        token
    }

    /// Whether the request's cookie is a live login.
    fn admits(&self, headers: &HeaderMap) -> bool {
        let Some(token) = cookie(headers, COOKIE) else {
            return false;
        };
        let logins = self.logins.lock().unwrap_or_else(PoisonError::into_inner);
        logins
            .get(token)
            .is_some_and(|until| *until > Instant::now())
    }

    /// Ends the request's login.
    fn close(&self, headers: &HeaderMap) {
        if let Some(token) = cookie(headers, COOKIE) {
            let mut logins = self.logins.lock().unwrap_or_else(PoisonError::into_inner);
            logins.remove(token);
        }
    }

    /// Whether `peer` may try a login now: false while too many of its client's failed in the
    /// current window.
    fn may_try(&self, peer: IpAddr) -> bool {
        let f = self.failures.lock().unwrap_or_else(PoisonError::into_inner);
        f.get(&client_of(peer))
            .is_none_or(|(start, n)| start.elapsed() >= FAILURE_WINDOW || *n < MAX_FAILURES)
    }

    /// Counts a failed login of `peer`.
    fn failed(&self, peer: IpAddr) {
        let mut f = self.failures.lock().unwrap_or_else(PoisonError::into_inner);
        if f.len() >= MAX_THROTTLED_CLIENTS {
            f.retain(|_, (start, _)| start.elapsed() < FAILURE_WINDOW);
        }
        if f.len() >= MAX_THROTTLED_CLIENTS
            && let Some(oldest) = f
                .iter()
                .min_by_key(|(_, (start, _))| *start)
                .map(|(c, _)| *c)
        {
            f.remove(&oldest);
        }
        let window = f.entry(client_of(peer)).or_insert((Instant::now(), 0));
        if window.0.elapsed() >= FAILURE_WINDOW {
            *window = (Instant::now(), 0);
        }
        window.1 += 1;
    }
}

/// 32 bytes from the kernel's random source.
fn random_bytes() -> [u8; 32] {
    let mut bytes = [0u8; 32];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut bytes))
        .expect("the kernel's random source /dev/urandom is readable");
    bytes
}

/// The value of cookie `name`, if the request sends it.
fn cookie<'a>(headers: &'a HeaderMap, name: &str) -> Option<&'a str> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(';'))
        .filter_map(|pair| pair.trim().split_once('='))
        .find(|(k, _)| *k == name)
        .map(|(_, v)| v)
}

/// Refuses state-changing requests and WebSockets from another site (see the module docs).
pub(crate) async fn same_origin(request: Request, next: Next) -> Response {
    let headers = request.headers();
    let streams = headers.contains_key(header::UPGRADE);
    let changes = !matches!(*request.method(), Method::GET | Method::HEAD);
    if (changes || streams) && !from_own_page(headers) {
        return ApiError::forbidden("refused: the request comes from another site").into_response();
    }
    next.run(request).await
}

/// Whether nothing says the request comes from another origin than the one it is sent to.
fn from_own_page(headers: &HeaderMap) -> bool {
    let text = |name| {
        headers
            .get(name)
            .and_then(|v: &HeaderValue| v.to_str().ok())
    };
    if let Some(site) = text(header::HeaderName::from_static("sec-fetch-site"))
        && site != "same-origin"
        && site != "none"
    {
        return false;
    }
    match (text(header::ORIGIN), text(header::HOST)) {
        (None, _) => true,
        // https too: behind a TLS proxy that keeps the Host header, the page's origin is https.
        (Some(origin), Some(host)) => {
            origin == format!("http://{host}") || origin == format!("https://{host}")
        }
        (Some(_), None) => false,
    }
}

/// Lets a logged-in browser through (everyone, when no login is needed); sends others to the
/// login page (`/api/*`: 401).
pub(crate) async fn guard(
    State(state): State<Arc<WebState>>,
    request: Request,
    next: Next,
) -> Response {
    if !state.sessions.needs_login() || state.sessions.admits(request.headers()) {
        return next.run(request).await;
    }
    if request.uri().path().starts_with("/api/") || request.method() != Method::GET {
        return ApiError::unauthenticated().into_response();
    }
    Redirect::to("/login").into_response()
}

/// The login form's field.
#[derive(serde::Deserialize)]
pub(crate) struct LoginForm {
    secret: String,
}

/// `GET /login`.
pub(crate) async fn login_page(State(state): State<Arc<WebState>>) -> Response {
    if !state.sessions.needs_login() {
        return Redirect::to("/").into_response();
    }
    assets::login_response("", StatusCode::OK)
}

/// `POST /login`: the secret once, a cookie back.
pub(crate) async fn login(
    State(state): State<Arc<WebState>>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    form: Result<axum::Form<LoginForm>, axum::extract::rejection::FormRejection>,
) -> Response {
    let sessions = &state.sessions;
    if !sessions.needs_login() {
        return Redirect::to("/").into_response();
    }
    if !sessions.may_try(peer.ip()) {
        return assets::login_response(
            "Too many failed logins from this address: wait a minute before the next.",
            StatusCode::TOO_MANY_REQUESTS,
        );
    }
    let given = form.map(|f| f.0.secret).unwrap_or_default();
    // The secret file's trailing newline is not part of the secret; a pasted one is not either.
    let given = given.trim_end_matches(['\r', '\n']);
    if !sessions.is_secret(given.as_bytes()) {
        sessions.failed(peer.ip());
        return assets::login_response(
            "That is not the system's shared secret.",
            StatusCode::UNAUTHORIZED,
        );
    }
    let token = sessions.open();
    let cookie = format!(
        "{COOKIE}={token}; HttpOnly; SameSite=Strict; Path=/; Max-Age={}",
        sessions.lifetime.as_secs()
    );
    let mut response = Redirect::to("/").into_response();
    if let Ok(v) = HeaderValue::from_str(&cookie) {
        response.headers_mut().insert(header::SET_COOKIE, v);
    }
    response
}

/// `POST /logout`.
pub(crate) async fn logout(State(state): State<Arc<WebState>>, headers: HeaderMap) -> Response {
    state.sessions.close(&headers);
    let mut response = Redirect::to("/login").into_response();
    response.headers_mut().insert(
        header::SET_COOKIE,
        HeaderValue::from_static("penelope_login=; HttpOnly; SameSite=Strict; Path=/; Max-Age=0"),
    );
    response
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(&'static str, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.append(*k, HeaderValue::from_str(v).unwrap());
        }
        h
    }

    #[test]
    fn only_the_secret_opens_a_login_and_only_a_live_token_admits() {
        let s = Sessions::new(Some(b"s3cret".to_vec()), Duration::from_secs(60));
        assert!(s.is_secret(b"s3cret"));
        for wrong in [&b""[..], b"s3cre", b"s3cret!", b"S3CRET"] {
            assert!(!s.is_secret(wrong));
        }
        let token = s.open();
        assert!(s.admits(&headers(&[("cookie", &format!("a=b; {COOKIE}={token}"))])));
        assert!(!s.admits(&headers(&[("cookie", &format!("{COOKIE}=x{token}"))])));
        assert!(!s.admits(&headers(&[])));
        s.close(&headers(&[("cookie", &format!("{COOKIE}={token}"))]));
        assert!(!s.admits(&headers(&[("cookie", &format!("{COOKIE}={token}"))])));
        let expired = Sessions::new(Some(b"x".to_vec()), Duration::ZERO);
        let token = expired.open();
        assert!(!expired.admits(&headers(&[("cookie", &format!("{COOKIE}={token}"))])));
    }

    #[test]
    fn cross_site_requests_are_told_apart() {
        let host = ("host", "127.0.0.1:8080");
        assert!(from_own_page(&headers(&[host])));
        assert!(from_own_page(&headers(&[
            host,
            ("origin", "http://127.0.0.1:8080")
        ])));
        assert!(!from_own_page(&headers(&[
            host,
            ("origin", "http://evil.example")
        ])));
        assert!(!from_own_page(&headers(&[host, ("origin", "null")])));
        assert!(!from_own_page(&headers(&[
            host,
            ("sec-fetch-site", "cross-site")
        ])));
        assert!(!from_own_page(&headers(&[
            host,
            ("sec-fetch-site", "same-site")
        ])));
        assert!(from_own_page(&headers(&[
            host,
            ("sec-fetch-site", "same-origin")
        ])));
    }

    #[test]
    fn failed_logins_are_bounded_per_client() {
        let s = Sessions::new(Some(b"x".to_vec()), Duration::from_secs(60));
        let guesser: IpAddr = "2001:db8::1".parse().unwrap();
        for _ in 0..MAX_FAILURES {
            assert!(s.may_try(guesser));
            s.failed(guesser);
        }
        // The guesser's whole /64 waits; other clients do not.
        assert!(!s.may_try(guesser));
        assert!(!s.may_try("2001:db8::2".parse().unwrap()));
        assert!(s.may_try("2001:db9::1".parse().unwrap()));
        assert!(s.may_try("127.0.0.1".parse().unwrap()));
        // Many clients failing once each are remembered within a bound.
        for i in 0..(MAX_THROTTLED_CLIENTS as u32 + 10) {
            s.failed(IpAddr::from(i.to_be_bytes()));
        }
        assert!(s.failures.lock().unwrap().len() <= MAX_THROTTLED_CLIENTS);
    }
}
