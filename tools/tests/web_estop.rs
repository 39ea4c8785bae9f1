//! The web page's E-STOP is the console's red button: `POST /api/estop` latches every loop of
//! every node and answers which loops latched it (here a node on loopback without a secret,
//! its PID loop running, spoken to in plain HTTP; the browser tests press the button itself).

use penelope_testkit::net::free_tcp_addr;
use penelope_testkit::process::{Children, Penelope};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The binary under test.
const PENELOPE: Penelope = Penelope::at(env!("CARGO_BIN_EXE_penelope"));

/// One HTTP/1.1 POST of JSON from the page's own origin; the status and the body.
fn post(addr: &str, path: &str, body: &str) -> (u16, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let req = format!(
        "POST {path} HTTP/1.1\r\nHost: {addr}\r\nOrigin: http://{addr}\r\nConnection: close\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    );
    s.write_all(req.as_bytes()).unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    let (head, body) = text.split_once("\r\n\r\n").unwrap();
    let status = head.split(' ').nth(1).unwrap().parse().unwrap();
    (status, body.to_string())
}

fn ctl(naming: &str, args: &[&str]) -> std::process::Output {
    Command::new(PENELOPE.path())
        .args(["ctl", "--naming", naming])
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap()
}

#[test]
fn the_pages_estop_latches_every_loop_of_every_node() {
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
        ],
        "Ctrl-C stops the node",
    );
    let mut children = Children(vec![node]);
    let dir = std::env::temp_dir().join(format!("penelope-web-estop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let setup = dir.join("setup.ctl");
    std::fs::write(
        &setup,
        "create lab board/sim sim0 axes=6 substep_us=200\n\
         create lab robot/puma560 slave\n\
         call lab/slave map-joints sim0 0:0 1:1 2:2 3:3 4:4 5:5\n\
         configure lab/sim0\n\
         configure lab/slave\n\
         create lab trajectory/step hold pose=start\n\
         create lab controller/joint-pid pid --config 'period_us = 2000'\n\
         call lab/pid set-robot slave\n\
         call lab/pid set-trajectory hold\n\
         configure lab/hold\n\
         configure lab/pid\n\
         activate lab/pid\n",
    )
    .unwrap();
    let o = ctl(&naming, &["run", setup.to_str().unwrap()]);
    assert!(o.status.success(), "{o:?}");
    let (web, line) = PENELOPE.start(
        &["web", "--naming", &naming, "--listen", "127.0.0.1:0"],
        "penelope web: serving",
    );
    children.0.push(web);
    let addr = line
        .split("http://")
        .nth(1)
        .and_then(|r| r.split('/').next())
        .unwrap()
        .trim()
        .to_string();

    let (status, body) = post(&addr, "/api/estop", "{}");
    assert_eq!(status, 200, "{body}");
    let answer: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(
        answer["nodes"],
        serde_json::json!([{ "node": "lab", "stopped": ["pid"], "pending": [] }]),
        "{body}"
    );
    // The loop's samples say so.
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let o = ctl(&naming, &["--json", "call", "lab/pid", "status"]);
        let reply: serde_json::Value =
            serde_json::from_str(String::from_utf8_lossy(&o.stdout).trim()).unwrap_or_default();
        if reply["Status"]["last"]["state"] == "estop" {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the loop never showed estop: {reply}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = std::fs::remove_dir_all(&dir);
}
