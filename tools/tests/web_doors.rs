//! The doors of `penelope web` against hostile clients, over loopback (which has many
//! addresses: 127.0.0.2 is another client than 127.0.0.1): a DNS-rebound page is refused,
//! a guesser's failed logins do not lock the right secret out of another address, stalled
//! connections do not starve the page, and the E-STOP works for any logged-in browser.

use penelope_testkit::net::free_tcp_addr;
use penelope_testkit::process::Penelope;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::os::unix::fs::PermissionsExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

const SECRET: &str = "correct horse battery staple";

/// The child processes and a scratch directory, gone when the test ends, passed or failed.
struct System {
    children: Vec<Child>,
    dir: PathBuf,
    /// The page's address, as it printed it.
    web: String,
    /// The naming service.
    naming: String,
    /// The secret file and the admin secret file, when the system has a secret.
    secret: Option<(String, String)>,
}

impl Drop for System {
    fn drop(&mut self) {
        for c in &mut self.children {
            let _ = c.kill();
            let _ = c.wait();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// A node hosting the naming service and `penelope web` on it, both with the secret when
/// `secret` (the web page then needs a login).
fn system(name: &str, secret: bool) -> System {
    let dir = std::env::temp_dir().join(format!("penelope-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("secret");
    std::fs::write(&file, format!("{SECRET}\n")).unwrap();
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).unwrap();
    let file = file.to_str().unwrap().to_string();
    // The page and the setup script create objects: they speak as an admin.
    let admin = dir.join("admin");
    std::fs::write(&admin, "4b9e2d7f1a0c3e5d8f2b6a9c1e4d7f0a\n").unwrap();
    std::fs::set_permissions(&admin, std::fs::Permissions::from_mode(0o600)).unwrap();
    let admin = admin.to_str().unwrap().to_string();
    let naming = free_tcp_addr().to_string();
    let mut node_args = vec![
        "node",
        "--name",
        "lab",
        "--host-naming",
        "--listen",
        &naming,
        "--priority",
        "0",
    ];
    let mut web_args = vec![
        "web",
        "--naming",
        &naming,
        "--listen",
        "127.0.0.1:0",
        "--role",
        "admin",
    ];
    if secret {
        node_args.extend(["--secret-file", &file, "--admin-secret-file", &admin]);
        web_args.extend(["--secret-file", &file, "--admin-secret-file", &admin]);
    }
    let (node, _) = PENELOPE.start(&node_args, "Ctrl-C stops the node");
    let mut system = System {
        children: vec![node],
        dir,
        web: String::new(),
        naming: naming.clone(),
        secret: secret.then(|| (file.clone(), admin.clone())),
    };
    let (web, line) = PENELOPE.start(&web_args, "penelope web: serving");
    system.children.push(web);
    system.web = line
        .split("http://")
        .nth(1)
        .and_then(|r| r.split('/').next())
        .unwrap()
        .to_string();
    system
}

/// A connection to `to` from the loopback address `from`.
fn connect_from(from: &str, to: &str) -> TcpStream {
    let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).unwrap();
    let local: SocketAddr = format!("{from}:0").parse().unwrap();
    socket.bind(&local.into()).unwrap();
    let to: SocketAddr = to.parse().unwrap();
    socket.connect(&to.into()).unwrap();
    socket.into()
}

/// A reply: the status, the headers (lower-case names) and the body.
type Reply = (u16, Vec<(String, String)>, String);

/// One HTTP/1.1 request from loopback address `from` to `to`, saying `Host: host`.
fn request_as(
    from: &str,
    to: &str,
    host: &str,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &str,
) -> Reply {
    let mut s = connect_from(from, to);
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut req = format!(
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\nContent-Length: {}\r\n",
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

/// A request from 127.0.0.1 under the server's own name.
fn request(to: &str, method: &str, path: &str, headers: &[(&str, &str)], body: &str) -> Reply {
    request_as("127.0.0.1", to, to, method, path, headers, body)
}

fn header<'a>(headers: &'a [(String, String)], name: &str) -> Option<&'a str> {
    headers
        .iter()
        .find(|(k, _)| k == name)
        .map(|(_, v)| v.as_str())
}

const FORM: (&str, &str) = ("Content-Type", "application/x-www-form-urlencoded");
const JSON: (&str, &str) = ("Content-Type", "application/json");

/// Logs in from `from` with `secret`: the status and the cookie, if one came back.
fn login(web: &str, from: &str, secret: &str) -> (u16, Option<String>) {
    let body = format!("secret={}", secret.replace(' ', "+"));
    let (status, headers, _) = request_as(from, web, web, "POST", "/login", &[FORM], &body);
    let cookie = header(&headers, "set-cookie").map(|c| c.split(';').next().unwrap().to_string());
    (status, cookie)
}

#[test]
fn a_dns_rebound_page_is_refused_for_pages_and_api_calls_alike() {
    // On loopback without a secret: the page is open, so only the Host check stands between a
    // rebound page of another site and the robots.
    let sys = system("web-rebind", false);
    let web = sys.web.as_str();
    let port = web.rsplit(':').next().unwrap();
    let evil_host = format!("evil.example:{port}");
    let evil_origin = format!("http://{evil_host}");
    let create = r#"{"node":"lab","kind":"board/sim","name":"sim0"}"#;
    let rebound = [JSON, ("Origin", evil_origin.as_str())];
    for (method, path, body) in [
        ("GET", "/", ""),
        ("GET", "/login", ""),
        ("GET", "/assets/app.js", ""),
        ("GET", "/api/tree", ""),
        ("POST", "/api/create", create),
        (
            "POST",
            "/api/call",
            r#"{"path":"/lab/creator","method":"list"}"#,
        ),
    ] {
        let (status, _, reply) =
            request_as("127.0.0.1", web, &evil_host, method, path, &rebound, body);
        println!("rebound {method} {path}: {status}");
        assert_eq!(status, 421, "{method} {path}: {reply}");
        assert!(reply.contains("misdirected"), "{reply}");
    }
    // The absolute form of a request names its host too.
    let (status, _, _) = request_as(
        "127.0.0.1",
        web,
        web,
        "GET",
        &format!("http://{evil_host}/api/tree"),
        &[],
        "",
    );
    assert_eq!(status, 421);
    // Nothing was created; under its own names the server serves as before.
    let local = format!("localhost:{port}");
    for host in [web, local.as_str()] {
        let (status, _, body) = request_as("127.0.0.1", web, host, "GET", "/api/tree", &[], "");
        assert_eq!(status, 200, "{host}: {body}");
        assert!(!body.contains("sim0"), "{body}");
    }
    let own_origin = format!("http://{web}");
    let own = [JSON, ("Origin", own_origin.as_str())];
    let (status, _, body) = request(web, "POST", "/api/create", &own, create);
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("/lab/boards/sim0"), "{body}");
}

#[test]
fn wrong_logins_from_one_address_leave_the_right_secret_to_another() {
    let sys = system("web-throttle", true);
    let web = sys.web.as_str();
    // A guesser at 127.0.0.2: ten wrong secrets, then it waits, even with the right one.
    for i in 0..10 {
        let (status, cookie) = login(web, "127.0.0.2", &format!("guess {i}"));
        assert_eq!((status, cookie), (401, None), "guess {i}");
    }
    let (status, cookie) = login(web, "127.0.0.2", SECRET);
    assert_eq!((status, cookie), (429, None));
    // The operator at 127.0.0.1 is not locked out.
    let (status, cookie) = login(web, "127.0.0.1", SECRET);
    assert_eq!(status, 303);
    let cookie = cookie.expect("a login cookie");
    // And, logged in, stops the loop: the E-STOP is for every logged-in browser.
    let own_origin = format!("http://{web}");
    let own = [
        ("Cookie", cookie.as_str()),
        JSON,
        ("Origin", own_origin.as_str()),
    ];
    estop_works(&sys, &own);
}

/// A running loop (simulated board and robot, a PID controller holding its pose), made with
/// `penelope ctl` as an admin.
const SETUP: &str = "\
create lab board/sim sim0 axes=6
create lab robot/puma560 slave
call /lab/robots/slave map-joints sim0 0:0 1:1 2:2 3:3 4:4 5:5
configure lab/sim0
configure lab/slave
create lab trajectory/step hold pose=start
create lab controller/joint-pid pid period_us=2000
call lab/pid set-robot slave
call lab/pid set-trajectory hold
configure lab/hold
configure lab/pid
activate lab/pid
";

/// Starts the loop of [`SETUP`] and latches its E-STOP from the page with `headers` (a login,
/// the own origin).
fn estop_works(sys: &System, headers: &[(&str, &str)]) {
    let script = sys.dir.join("setup.ctl");
    std::fs::write(&script, SETUP).unwrap();
    let mut ctl = Command::new(PENELOPE.path());
    ctl.args(["ctl", "--naming", &sys.naming]);
    if let Some((secret, admin)) = &sys.secret {
        ctl.args(["--secret-file", secret, "--admin-secret-file", admin]);
    }
    let out = ctl
        .args(["run", script.to_str().unwrap()])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let web = sys.web.as_str();
    let (status, _, body) = request(
        web,
        "POST",
        "/api/call",
        headers,
        r#"{"path":"/lab/controllers/pid","method":"estop"}"#,
    );
    assert_eq!(status, 200, "{body}");
    // The loop says so in its newest tick (bounded: 30 s).
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let (status, _, body) = request(
            web,
            "POST",
            "/api/call",
            headers,
            r#"{"path":"/lab/controllers/pid","method":"status"}"#,
        );
        assert_eq!(status, 200, "{body}");
        let last = body.split("\"last\":").nth(1).unwrap_or("").to_lowercase();
        if last.contains("estop") {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "no e-stop in the loop's status: {body}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn stalled_connections_do_not_stop_the_page_being_served() {
    let sys = system("web-stall", true);
    let web = sys.web.as_str();
    let (status, cookie) = login(web, "127.0.0.1", SECRET);
    assert_eq!(status, 303);
    let cookie = cookie.expect("a login cookie");

    // 300 connections from 127.0.0.3, each with half a request head, never finished.
    let started = Instant::now();
    let mut stalled = Vec::new();
    for _ in 0..300 {
        let mut s = connect_from("127.0.0.3", web);
        // The server may already have closed a connection beyond its cap: fine.
        let _ = s.write_all(b"GET / HTTP/1.1\r\nHost: ");
        stalled.push(s);
    }
    println!("300 stalled connections opened in {:?}", started.elapsed());

    // The page, the API and the E-STOP are served to another client meanwhile.
    let asked = Instant::now();
    let (status, _, body) = request(web, "GET", "/", &[("Cookie", &cookie)], "");
    let page_took = asked.elapsed();
    println!("the page was served in {page_took:?} beside 300 stalled connections");
    assert_eq!(status, 200);
    assert!(body.contains("E-STOP"), "{body}");
    assert!(page_took < Duration::from_secs(10), "{page_took:?}");
    let own_origin = format!("http://{web}");
    let own = [
        ("Cookie", cookie.as_str()),
        JSON,
        ("Origin", own_origin.as_str()),
    ];
    estop_works(&sys, &own);

    // Beyond the per-client cap (64) the server closed them at once; the rest it closes at
    // the header deadline (10 s). Polled: each pass looks at every connection without waiting.
    let closed = |s: &mut TcpStream| {
        s.set_nonblocking(true).unwrap();
        let mut buf = [0u8; 64];
        !matches!(s.read(&mut buf), Err(e) if e.kind() == std::io::ErrorKind::WouldBlock)
    };
    let closed_at_once = loop {
        let n = stalled
            .iter_mut()
            .filter_map(|s| closed(s).then_some(()))
            .count();
        if n >= 300 - 64 || started.elapsed() > Duration::from_secs(8) {
            break n;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    println!(
        "{closed_at_once} of 300 stalled connections closed at once ({:?})",
        started.elapsed()
    );
    assert!(closed_at_once >= 300 - 64, "{closed_at_once}");
    let deadline = Instant::now() + Duration::from_secs(60);
    let all_closed_in = loop {
        if stalled.iter_mut().all(closed) {
            break started.elapsed();
        }
        assert!(
            Instant::now() < deadline,
            "stalled connections still open after 60 s"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    println!("all 300 stalled connections closed {all_closed_in:?} after they were opened");
    assert!(all_closed_in >= Duration::from_secs(9), "{all_closed_in:?}");
}
