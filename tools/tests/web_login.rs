//! `penelope web` with `--secret-file`, spoken to in plain HTTP over loopback (the browser
//! tests in `tests/browser/` drive the page itself): nothing but the login page before the
//! secret, a cookie with the right attributes after it, and no state change from another
//! origin even with that cookie.

use penelope_testkit::net::free_tcp_addr;
use penelope_testkit::process::{Children, Penelope};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::time::Duration;

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

const SECRET: &str = "correct horse battery staple";

/// One HTTP/1.1 request; the status, the headers (lower-case names) and the body.
fn request(
    addr: &str,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &str,
) -> (u16, Vec<(String, String)>, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut req = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        req += &format!("{k}: {v}\r\n");
    }
    req += "\r\n";
    req += body;
    s.write_all(req.as_bytes()).unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    let (head, body) = text.split_once("\r\n\r\n").unwrap();
    let mut lines = head.lines();
    let status = lines
        .next()
        .unwrap()
        .split(' ')
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    let headers = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    (status, headers, body.to_string())
}

fn header<'a>(headers: &'a [(String, String)], name: &str) -> Option<&'a str> {
    headers
        .iter()
        .find(|(k, _)| k == name)
        .map(|(_, v)| v.as_str())
}

#[test]
fn a_browser_proves_the_secret_once_and_holds_a_strict_cookie() {
    let dir = std::env::temp_dir().join(format!("penelope-web-login-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (_children, addr) = a_node_and_its_web_server(&dir);

    before_the_secret_only_the_login_page(&addr);

    let token = the_secret_alone_gives_a_strict_cookie(&addr);
    let with = [("Cookie", token.as_str())];
    let (status, _, body) = request(&addr, "GET", "/api/tree", &with, "");
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("/lab/creator"), "{body}");

    // Even logged in, another origin changes nothing; the page's own origin does.
    let create = r#"{"node":"lab","kind":"board/sim","name":"sim0"}"#;
    let json = ("Content-Type", "application/json");
    let evil = [with[0], json, ("Origin", "http://evil.example")];
    let (status, _, body) = request(&addr, "POST", "/api/create", &evil, create);
    assert_eq!(status, 403, "{body}");
    let own_origin = format!("http://{addr}");
    let own = [with[0], json, ("Origin", own_origin.as_str())];
    let (status, _, body) = request(&addr, "POST", "/api/create", &own, create);
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("/lab/boards/sim0"), "{body}");
    // Unknown names and bad values are typed errors.
    let (status, _, body) = request(
        &addr,
        "POST",
        "/api/call",
        &own,
        r#"{"path":"lab/nobody","method":"describe"}"#,
    );
    assert_eq!(status, 404, "{body}");
    assert!(body.contains("\"unknown-name\""), "{body}");

    // Logging out ends the login.
    let (status, _, _) = request(&addr, "POST", "/logout", &own, "");
    assert_eq!(status, 303);
    let (status, _, _) = request(&addr, "GET", "/api/tree", &with, "");
    assert_eq!(status, 401);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A node with a secret and an admin secret in `dir`, and `penelope web` speaking to it as an
/// admin; returns the children and the web server's address.
fn a_node_and_its_web_server(dir: &Path) -> (Children, String) {
    let secret = dir.join("secret");
    std::fs::write(&secret, format!("{SECRET}\n")).unwrap();
    std::fs::set_permissions(&secret, std::fs::Permissions::from_mode(0o600)).unwrap();
    let secret = secret.to_str().unwrap();
    // The page creates objects: the web server speaks as an admin, with the admin secret.
    let admin = dir.join("admin");
    std::fs::write(&admin, "4b9e2d7f1a0c3e5d8f2b6a9c1e4d7f0a\n").unwrap();
    std::fs::set_permissions(&admin, std::fs::Permissions::from_mode(0o600)).unwrap();
    let admin = admin.to_str().unwrap();
    let naming = free_tcp_addr().to_string();
    let (node, _) = PENELOPE.start(
        &[
            "node",
            "--name",
            "lab",
            "--host-naming",
            "--listen",
            &naming,
            "--priority",
            "0",
            "--secret-file",
            secret,
            "--admin-secret-file",
            admin,
        ],
        "Ctrl-C stops the node",
    );
    let mut children = Children(vec![node]);
    let (web, line) = PENELOPE.start(
        &[
            "web",
            "--naming",
            &naming,
            "--listen",
            "127.0.0.1:0",
            "--secret-file",
            secret,
            "--role",
            "admin",
            "--admin-secret-file",
            admin,
            "--login-hours",
            "2",
        ],
        "penelope web: serving",
    );
    children.0.push(web);
    let addr = line
        .split("http://")
        .nth(1)
        .and_then(|r| r.split('/').next())
        .unwrap()
        .to_string();

    (children, addr)
}

/// Before the secret: pages and assets send to the login, the API answers 401, the login page
/// asks for the secret.
fn before_the_secret_only_the_login_page(addr: &str) {
    for path in ["/", "/assets/app.js", "/assets/uPlot.iife.min.js"] {
        let (status, headers, body) = request(addr, "GET", path, &[], "");
        assert_eq!(
            (status, header(&headers, "location")),
            (303, Some("/login")),
            "{path}"
        );
        assert!(body.is_empty(), "{path}: {body}");
    }
    for path in ["/api/tree", "/api/kinds", "/api/live?path=/lab/creator"] {
        let (status, _, body) = request(addr, "GET", path, &[], "");
        assert_eq!(status, 401, "{path}: {body}");
        assert!(body.contains("unauthenticated"), "{body}");
    }
    let (status, _, body) = request(addr, "GET", "/login", &[], "");
    assert_eq!(status, 200);
    assert!(body.contains("name=\"secret\""));
}

/// A wrong secret: 401, no cookie. The secret: a cookie, HttpOnly, SameSite=Strict, expiring
/// with --login-hours, that opens the API. Returns the cookie's `name=value`.
fn the_secret_alone_gives_a_strict_cookie(addr: &str) -> String {
    let form = [("Content-Type", "application/x-www-form-urlencoded")];
    let (status, headers, _) = request(addr, "POST", "/login", &form, "secret=nope");
    assert_eq!(status, 401);
    assert!(header(&headers, "set-cookie").is_none());

    // The secret: a cookie, HttpOnly, SameSite=Strict, expiring with --login-hours.
    let body = format!("secret={}", SECRET.replace(' ', "+"));
    let (status, headers, _) = request(addr, "POST", "/login", &form, &body);
    assert_eq!(status, 303);
    let cookie = header(&headers, "set-cookie").expect("a login cookie");
    for attribute in ["HttpOnly", "SameSite=Strict", "Path=/", "Max-Age=7200"] {
        assert!(cookie.contains(attribute), "{cookie}");
    }
    cookie.split(';').next().unwrap().to_string()
}
