//! The page and everything it loads, compiled into the binary: the browser fetches nothing
//! but from this server.

use std::sync::LazyLock;

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
        "camera.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/camera.js"),
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
    // The 3D view (an ES module) and what it imports: three.js r185 (MIT) with its orbit
    // controls and urdf-loader 0.13.1 (Apache-2.0), vendored unchanged; the stand-in for the
    // mesh loaders urdf-loader imports is ours. The import map in `index.html` names them.
    (
        "scene3d.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/scene3d.js"),
    ),
    (
        "mesh-loaders.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/mesh-loaders.js"),
    ),
    (
        "three.module.min.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/vendor/three.module.min.js"),
    ),
    (
        "three.core.min.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/vendor/three.core.min.js"),
    ),
    (
        "OrbitControls.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/vendor/OrbitControls.js"),
    ),
    (
        "URDFLoader.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/vendor/URDFLoader.js"),
    ),
    (
        "URDFClasses.js",
        "text/javascript; charset=utf-8",
        include_str!("assets/vendor/URDFClasses.js"),
    ),
];

/// Scripts only from this server, no framing by other sites (clickjacking of the e-stop and
/// the lifecycle buttons). uPlot sizes its elements with inline styles. The one inline script
/// is the page's import map (ES modules name `three` by a bare name), allowed by its hash.
static CSP: LazyLock<String> = LazyLock::new(|| {
    format!(
        "default-src 'self'; script-src 'self' '{}'; style-src 'self' 'unsafe-inline'; \
         img-src 'self' data:; frame-ancestors 'none'; form-action 'self'",
        script_hash(import_map(INDEX))
    )
});

/// The text of the page's `<script type="importmap">` element (empty without one).
fn import_map(page: &str) -> &str {
    const OPEN: &str = "<script type=\"importmap\">";
    page.split_once(OPEN)
        .and_then(|(_, rest)| rest.split_once("</script>"))
        .map_or("", |(map, _)| map)
}

/// A CSP hash source for an inline script: `sha256-` and the base64 of its SHA-256.
fn script_hash(script: &str) -> String {
    use sha2::Digest;
    format!(
        "sha256-{}",
        base64(&sha2::Sha256::digest(script.as_bytes()))
    )
}

/// Standard base64 with padding (RFC 4648), for the one hash above.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(char::from(ALPHABET[(n >> (18 - 6 * i)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

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
        HeaderValue::from_str(&CSP)
            .unwrap_or_else(|_| HeaderValue::from_static("default-src 'self'")),
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
    fn the_csp_allows_the_import_map_by_its_hash() {
        // RFC 4648's test vectors.
        for (plain, coded) in [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v")] {
            assert_eq!(super::base64(plain.as_bytes()), coded);
        }
        assert_eq!(
            super::script_hash("abc"),
            "sha256-ungWv48Bz+pBQUDeXa4iI7ADYaOWF3qctBD/YfIAFa0="
        );
        let map = super::import_map(super::INDEX);
        assert!(
            map.contains("\"three\": \"/assets/three.module.min.js\""),
            "{map}"
        );
        assert!(super::CSP.contains(&super::script_hash(map)));
        assert_eq!(super::import_map("<p>no map</p>"), "");
    }

    #[test]
    fn the_login_page_escapes_what_it_says() {
        let page = super::login_page("<script>x</script>");
        assert!(page.contains("&lt;script&gt;x&lt;/script&gt;"));
        assert!(!page.contains("<script>x"));
    }
}
