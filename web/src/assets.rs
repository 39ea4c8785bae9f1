//! The page and everything it loads, compiled into the binary: the browser fetches nothing
//! but from this server.

use axum::extract::Path;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};

/// The page.
const INDEX: &str = include_str!("assets/index.html");
/// The login page; `{{message}}` is replaced by what went wrong (HTML-escaped).
const LOGIN: &str = include_str!("assets/login.html");

/// Files under `/assets/`: name, content type, body.
const FILES: &[(&str, &str, &str)] = &[
    (
        "app.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/app.js"),
    ),
    (
        "plots.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/plots.js"),
    ),
    (
        "style.css",
        "text/css; charset=utf-8",
        include_str!("assets/style.css"),
    ),
    // uPlot 1.6.32 (MIT), vendored unchanged: assets/vendor/README.md.
    (
        "uPlot.iife.min.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/vendor/uPlot.iife.min.js"),
    ),
    (
        "uPlot.min.css",
        "text/css; charset=utf-8",
        include_str!("assets/vendor/uPlot.min.css"),
    ),
];

/// Scripts only from this server, no framing by other sites (clickjacking of the e-stop and
/// the lifecycle buttons). uPlot sizes its elements with inline styles.
const CSP: &str = "default-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data:; \
                   frame-ancestors 'none'; form-action 'self'";

/// An HTML response with the page's security headers.
fn html(body: String, status: StatusCode) -> Response {
    let mut r = (status, body).into_response();
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/html; charset=utf-8"),
    );
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(CSP),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    r
}

/// `GET /`.
pub(crate) async fn index() -> Response {
    html(INDEX.to_string(), StatusCode::OK)
}

/// `GET /assets/{file}`.
pub(crate) async fn file(Path(name): Path<String>) -> Response {
    match FILES.iter().find(|(n, _, _)| *n == name) {
        Some((_, kind, body)) => (
            [(header::CONTENT_TYPE, HeaderValue::from_static(kind))],
            *body,
        )
            .into_response(),
        None => (StatusCode::NOT_FOUND, "no such file").into_response(),
    }
}

/// The login page saying `message` (empty: nothing went wrong).
fn login_page(message: &str) -> String {
    LOGIN.replace("{{message}}", &escape(message))
}

/// `message` safe inside HTML text.
fn escape(message: &str) -> String {
    message
        .replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A login page response with the page's security headers.
pub(crate) fn login_response(message: &str, status: StatusCode) -> Response {
    html(login_page(message), status)
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_login_page_escapes_what_it_says() {
        let page = super::login_page("<script>x</script>");
        assert!(page.contains("&lt;script&gt;x&lt;/script&gt;"));
        assert!(!page.contains("<script>x"));
    }
}
