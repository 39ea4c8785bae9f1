//! Robustness of a node's server against bad clients, while a control loop runs.
//!
//! A real [`Server`] with a small test service (echo, and a subscription the test floods with
//! telemetry) faces garbage bytes, oversized lengths, half frames, a silent handshake, a client
//! that never reads, a connection flood, a request flood, a wrong secret and seeded random bytes.
//! Each attack must get its typed error (or be dropped), a good client must be answered during
//! and after all of it, nothing may panic, the server's threads must all end at shutdown, and a
//! 1 ms periodic thread (SCHED_FIFO when permitted) must not see more overruns during the attack
//! than during a quiet window of the same length (plus a small tolerance: virtual machines stall;
//! durations are never asserted).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use penelope_protocol::net::conn::{ClientConfig, Connection, RpcError};
use penelope_protocol::net::frame::{FrameError, encode, encode_into, read_frame};
use penelope_protocol::net::server::{ABUSE_STRIKES, NetError, Server, ServerConfig, ServerStats};
use penelope_protocol::proto::{
    Call, CallError, ClientHello, ClientMsg, ProtocolError, Reply, Role, ServerMsg, TelemetryBatch,
    TelemetryRecord, WireError, WrenchMsg,
};
use penelope_protocol::service::{Outbox, Service, Session};
use penelope_rt_core::exec::{Flow, PeriodicConfig, RunReport, spawn};

/// Tests of this file run one at a time (they count the process's threads).
static SERIAL: Mutex<()> = Mutex::new(());

const RATE: u32 = 2000;
const MAX_CONNECTIONS: u32 = 12;
const MAX_FRAME: usize = 64 * 1024;

/// Echo, plus subscriptions whose outboxes the test floods.
#[derive(Default)]
struct TestService {
    calls: AtomicU64,
    closed: AtomicU64,
    subscribers: Mutex<Vec<(u64, Outbox)>>,
}

impl Service for TestService {
    fn call(&self, session: &Session, call: Call) -> Result<Reply, WireError> {
        self.calls.fetch_add(1, Ordering::Relaxed);
        match call {
            Call::Ping { payload } => Ok(Reply::Pong(payload)),
            Call::Subscribe { .. } => {
                let mut subs = self.subscribers.lock().unwrap();
                subs.push((session.id, session.outbox.clone()));
                Ok(Reply::Unit)
            }
            _ => Err(WireError::Call(CallError::NotReady("test service".into()))),
        }
    }

    fn closed(&self, session: &Session) {
        self.closed.fetch_add(1, Ordering::Relaxed);
        self.subscribers
            .lock()
            .unwrap()
            .retain(|(id, _)| *id != session.id);
    }
}

impl TestService {
    /// One telemetry batch of about 4 KiB to every subscriber, never waiting.
    fn publish(&self, seq: u64) -> (u64, u64) {
        let record = TelemetryRecord {
            time_ns: seq,
            seq,
            q: vec![0.0; 6],
            qd: vec![0.0; 6],
            effort: vec![0.0; 6],
            tool_position: [0.0; 3],
            wrench: WrenchMsg {
                force: [0.0; 3],
                torque: [0.0; 3],
            },
            state: "x".repeat(4000),
            fault: None,
            commanded_wrench: WrenchMsg {
                force: [0.0; 3],
                torque: [0.0; 3],
            },
            clutch: None,
            port_energy: None,
            channel_energy: None,
        };
        let (mut sent, mut dropped) = (0, 0);
        for (_, outbox) in self.subscribers.lock().unwrap().iter() {
            let batch = TelemetryBatch {
                subscription: 1,
                dropped: outbox.dropped(),
                samples: vec![record.clone()],
                common_offset_ns: 0,
            };
            if outbox.try_push(ServerMsg::Telemetry(batch)) {
                sent += 1;
            } else {
                dropped += 1;
            }
        }
        (sent, dropped)
    }
}

fn config(secret: Option<&[u8]>) -> ServerConfig {
    let mut c = ServerConfig::new("robust");
    c.secret = secret.map(Into::into);
    c.max_frame = MAX_FRAME;
    c.max_connections = MAX_CONNECTIONS;
    c.max_requests_per_s = RATE;
    c.handshake_timeout = Duration::from_millis(300);
    c.idle_timeout = Duration::from_secs(10);
    c.write_timeout = Duration::from_millis(300);
    c.outbox_capacity = 8;
    c
}

fn threads() -> usize {
    std::fs::read_dir("/proc/self/task").map_or(0, |d| d.count())
}

fn raw(addr: SocketAddr) -> Option<TcpStream> {
    let s = TcpStream::connect_timeout(&addr, Duration::from_secs(2)).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(3))).ok()?;
    s.set_write_timeout(Some(Duration::from_secs(3))).ok()?;
    s.set_nodelay(true).ok()?;
    Some(s)
}

fn frame(msg: &ClientMsg) -> Vec<u8> {
    encode(msg, MAX_FRAME).unwrap()
}

fn hello() -> Vec<u8> {
    frame(&ClientMsg::Hello(ClientHello::new(
        "attacker",
        Role::Reader,
    )))
}

/// Reads frames until the server's connection-level error or the end; the error, if one came.
fn final_error(s: &mut TcpStream) -> Option<WireError> {
    loop {
        match read_frame::<_, ServerMsg>(s, 1 << 20) {
            Ok(ServerMsg::Error(e)) => return Some(e),
            Ok(_) => {}
            Err(_) => return None,
        }
    }
}

fn refused(e: &Option<WireError>) -> bool {
    matches!(
        e,
        Some(WireError::Protocol(
            ProtocolError::TooManyConnections { .. }
        ))
    )
}

/// What the attacks saw.
#[derive(Default)]
struct Seen {
    malformed: AtomicU64,
    too_large: AtomicU64,
    handshake_timeouts: AtomicU64,
    too_many: AtomicU64,
    rate_limited_replies: AtomicU64,
    rate_limit_drops: AtomicU64,
    auth_failed: AtomicU64,
    telemetry_dropped: AtomicU64,
    fuzz_inputs: AtomicU64,
}

fn note(counter: &AtomicU64) {
    counter.fetch_add(1, Ordering::Relaxed);
}

fn garbage(addr: SocketAddr, seen: &Seen) {
    let Some(mut s) = raw(addr) else { return };
    // A 5-byte body that is no message.
    let _ = s.write_all(&[5, 0, 0, 0, 0xff, 0xfe, 0xfd, 0xfc, 0xfb]);
    match final_error(&mut s) {
        Some(WireError::Protocol(ProtocolError::Malformed(_))) => note(&seen.malformed),
        e => assert!(refused(&e), "garbage got {e:?}"),
    }
}

fn oversized(addr: SocketAddr, seen: &Seen) {
    let Some(mut s) = raw(addr) else { return };
    let mut bytes = hello();
    bytes.extend(0xffff_fff0u32.to_le_bytes());
    bytes.extend([0u8; 1000]);
    let _ = s.write_all(&bytes);
    match final_error(&mut s) {
        Some(WireError::Protocol(ProtocolError::FrameTooLarge { len, max })) => {
            assert_eq!((len, max), (0xffff_fff0, MAX_FRAME as u64));
            note(&seen.too_large);
        }
        e => assert!(refused(&e), "oversized got {e:?}"),
    }
}

fn half_frames(addr: SocketAddr) {
    let Some(mut s) = raw(addr) else { return };
    let mut bytes = hello();
    let req = frame(&ClientMsg::Request {
        id: 1,
        call: Call::Ping {
            payload: vec![1; 100],
        },
    });
    bytes.extend(&req[..req.len() / 2]);
    let _ = s.write_all(&bytes);
    // Close in the middle of the request.
}

fn stalled_hello(addr: SocketAddr, seen: &Seen) {
    let Some(mut s) = raw(addr) else { return };
    match final_error(&mut s) {
        Some(WireError::Protocol(ProtocolError::Timeout(_))) => note(&seen.handshake_timeouts),
        e => assert!(refused(&e), "stalled hello got {e:?}"),
    }
}

fn connection_flood(addr: SocketAddr, seen: &Seen) {
    let mut socks: Vec<TcpStream> = (0..MAX_CONNECTIONS + 6).filter_map(|_| raw(addr)).collect();
    for s in &mut socks {
        let _ = s.set_read_timeout(Some(Duration::from_millis(100)));
        let mut b = [0u8; 64];
        if let Ok(n) = s.read(&mut b)
            && n > 4
            && let Ok(ServerMsg::Error(WireError::Protocol(ProtocolError::TooManyConnections {
                ..
            }))) = read_frame::<_, ServerMsg>(&mut &b[..n], 1024)
        {
            note(&seen.too_many);
        }
    }
}

fn request_flood(addr: SocketAddr, seen: &Seen) {
    let Some(mut s) = raw(addr) else { return };
    let mut bytes = hello();
    for id in 0..(RATE as u64 + u64::from(ABUSE_STRIKES) + 500) {
        encode_into(
            &ClientMsg::Request {
                id,
                call: Call::Ping { payload: vec![] },
            },
            MAX_FRAME,
            &mut bytes,
        )
        .unwrap();
    }
    let writer = s.try_clone().unwrap();
    let t = std::thread::spawn(move || {
        let mut w = writer;
        let _ = w.write_all(&bytes);
    });
    loop {
        match read_frame::<_, ServerMsg>(&mut s, 1 << 20) {
            Ok(ServerMsg::Response {
                result: Err(WireError::Protocol(ProtocolError::RateLimited { limit })),
                ..
            }) => {
                assert_eq!(limit, RATE);
                note(&seen.rate_limited_replies);
            }
            Ok(ServerMsg::Error(WireError::Protocol(ProtocolError::RateLimited { .. }))) => {
                note(&seen.rate_limit_drops);
                break;
            }
            Ok(ServerMsg::Error(e)) => {
                assert!(refused(&Some(e.clone())), "request flood got {e:?}");
                break;
            }
            Ok(_) => {}
            Err(_) => break,
        }
    }
    let _ = s.shutdown(std::net::Shutdown::Both);
    let _ = t.join();
}

fn wrong_secret(addr: SocketAddr, seen: &Seen) {
    let mut cfg = ClientConfig::new("intruder");
    cfg.secret = Some(b"not the secret".into());
    match Connection::connect(addr, &cfg) {
        Err(RpcError::Remote(WireError::Protocol(ProtocolError::AuthFailed))) => {
            note(&seen.auth_failed)
        }
        // Failed handshakes from one address are throttled: refused before the check.
        Err(RpcError::Remote(
            WireError::Protocol(ProtocolError::TooManyConnections { .. })
            | WireError::Protocol(ProtocolError::RateLimited { .. }),
        )) => {}
        other => panic!("a wrong secret got {other:?}"),
    }
}

/// Subscribes and never reads: the test then floods it with telemetry.
fn stalled_reader(addr: SocketAddr, service: &TestService) -> TcpStream {
    let mut s = raw(addr).unwrap();
    let mut bytes = hello();
    bytes.extend(frame(&ClientMsg::Request {
        id: 1,
        call: Call::Subscribe {
            object: "loop".into(),
            decimation: 1,
        },
    }));
    s.write_all(&bytes).unwrap();
    let deadline = Instant::now() + Duration::from_secs(3);
    while service.subscribers.lock().unwrap().is_empty() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(!service.subscribers.lock().unwrap().is_empty());
    s
}

/// Pushes telemetry to every subscriber (never waiting) until `until`.
fn flood_telemetry(service: &TestService, seen: &Seen, until: Instant) {
    let mut seq = 0;
    while Instant::now() < until {
        let (_, dropped) = service.publish(seq);
        seen.telemetry_dropped.fetch_add(dropped, Ordering::Relaxed);
        seq += 1;
        std::thread::sleep(Duration::from_micros(200));
    }
}

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

/// Seeded random bytes at the live server's handshake (sometimes after a valid hello).
fn handshake_fuzz(addr: SocketAddr, rng: &mut Rng, seen: &Seen) {
    let Some(mut s) = raw(addr) else { return };
    let _ = s.set_read_timeout(Some(Duration::from_millis(500)));
    let mut bytes = if rng.next().is_multiple_of(3) {
        hello()
    } else {
        Vec::new()
    };
    let n = (rng.next() % 200) as usize;
    bytes.extend((0..n).map(|_| rng.next() as u8));
    if rng.next().is_multiple_of(2) && bytes.len() > 4 {
        // A plausible small length, so the body is decoded rather than refused on its header.
        let len = (bytes.len() - 4) as u32;
        bytes[..4].copy_from_slice(&len.to_le_bytes());
    }
    let _ = s.write_all(&bytes);
    let _ = final_error(&mut s);
    note(&seen.fuzz_inputs);
}

fn control_loop() -> penelope_rt_core::exec::PeriodicThread {
    let mut c = PeriodicConfig::new("robust-loop", Duration::from_millis(1));
    c.lock_memory = false;
    c.hold_dma_latency = false;
    c.prefault_stack = 64 * 1024;
    c.stack_size = 256 * 1024;
    let mut x = 0u64;
    spawn(c, move |tick| {
        // A little work, like a small control law.
        for i in 0..200u64 {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(i ^ tick.index);
        }
        std::hint::black_box(x);
        Flow::Continue
    })
    .expect("periodic thread")
}

fn ping(c: &mut Connection, i: u64) -> Result<Reply, RpcError> {
    c.call(Call::Ping {
        payload: i.to_le_bytes().to_vec(),
    })
}

/// Runs `f` again and again until `until`.
fn repeat(until: Instant, f: impl Fn()) {
    while Instant::now() < until {
        f();
    }
}

const WINDOW: Duration = Duration::from_secs(3);

#[test]
fn attacks_while_a_control_loop_runs() {
    let _serial = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let baseline = threads();
    let service = Arc::new(TestService::default());
    let server = Server::bind(
        "127.0.0.1:0".parse().unwrap(),
        config(None),
        service.clone(),
    )
    .unwrap();
    let secured = Server::bind(
        "127.0.0.1:0".parse().unwrap(),
        config(Some(b"9e107d9d372bb6826bd81d3542a419d6")),
        Arc::new(TestService::default()),
    )
    .unwrap();
    let (addr, secured_addr) = (server.local_addr(), secured.local_addr());

    let mut good = Connection::connect(addr, &ClientConfig::new("good")).unwrap();
    assert!(ping(&mut good, 0).is_ok());

    // The quiet window.
    let quiet = quiet_window(&mut good);
    // The attack window, same length.
    let stalled = stalled_reader(addr, &service);
    let seen = Seen::default();
    let good_calls = AtomicU64::new(0);
    let attack = attack_window(addr, secured_addr, &service, &seen, &good_calls, &mut good);

    drop(stalled);
    // After: the old and a new client are answered.
    assert!(ping(&mut good, 7).is_ok());
    let mut fresh = Connection::connect(addr, &ClientConfig::new("fresh")).unwrap();
    assert_eq!(
        ping(&mut fresh, 8).unwrap(),
        Reply::Pong(8u64.to_le_bytes().to_vec())
    );
    let mut friend = friend_after_the_throttle(secured_addr);
    assert!(ping(&mut friend, 9).is_ok());

    let stats = server.stats();
    println!("server stats after the attacks: {stats:?}");
    every_attack_met_its_answer(&stats, &seen, &good_calls, &service);

    // The control loop.
    the_loop_kept_its_time(&quiet, &attack);

    drop((good, fresh, friend));
    let sessions = server.stats().sessions;
    server.shutdown();
    secured.shutdown();
    let calls = service.calls.load(Ordering::Relaxed);
    assert!(calls > 0);
    assert_eq!(
        service.closed.load(Ordering::Relaxed),
        sessions,
        "closed runs once per session"
    );
    // Every thread of the servers is gone.
    let deadline = Instant::now() + Duration::from_secs(2);
    while (threads() > baseline || !server_threads().is_empty()) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(
        server_threads(),
        Vec::<String>::new(),
        "server threads leaked"
    );
    assert!(
        threads() <= baseline,
        "threads leaked: {} > {baseline}",
        threads()
    );
}

/// The quiet window: the control loop runs for [`WINDOW`] while the good client pings.
fn quiet_window(good: &mut Connection) -> RunReport {
    let t = control_loop();
    let end = Instant::now() + WINDOW;
    let mut i = 0;
    while Instant::now() < end {
        i += 1;
        assert_eq!(
            ping(good, i).unwrap(),
            Reply::Pong(i.to_le_bytes().to_vec())
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    t.stop_and_join().expect("join")
}

/// The attack window, as long as the quiet one: every attacker at once, from its own thread,
/// while the control loop runs and the good client is answered all along (counted in
/// `good_calls`).
fn attack_window(
    addr: SocketAddr,
    secured_addr: SocketAddr,
    service: &TestService,
    seen: &Seen,
    good_calls: &AtomicU64,
    good: &mut Connection,
) -> RunReport {
    let t = control_loop();
    let until = Instant::now() + WINDOW;
    std::thread::scope(|scope| {
        scope.spawn(move || repeat(until, || garbage(addr, seen)));
        scope.spawn(move || repeat(until, || oversized(addr, seen)));
        scope.spawn(move || repeat(until, || half_frames(addr)));
        scope.spawn(move || repeat(until, || stalled_hello(addr, seen)));
        scope.spawn(move || repeat(until, || connection_flood(addr, seen)));
        scope.spawn(move || repeat(until, || request_flood(addr, seen)));
        scope.spawn(move || repeat(until, || wrong_secret(secured_addr, seen)));
        scope.spawn(|| flood_telemetry(service, seen, until));
        scope.spawn(|| {
            let mut rng = Rng(0x00c0_ffee_1234_5678);
            while Instant::now() < until {
                handshake_fuzz(addr, &mut rng, seen);
            }
        });
        // The good client, answered all along.
        let mut i = 1_000_000;
        while Instant::now() < until {
            i += 1;
            let r = ping(good, i);
            assert_eq!(r.unwrap(), Reply::Pong(i.to_le_bytes().to_vec()));
            good_calls.fetch_add(1, Ordering::Relaxed);
            std::thread::sleep(Duration::from_millis(5));
        }
        // The window ends here for the loop too (the attackers finish their last round
        // after it).
        t.stop_and_join().expect("join")
    })
}

/// The friend: a client with the secret, connected once the throttle lets it in.
fn friend_after_the_throttle(secured_addr: SocketAddr) -> Connection {
    let mut ok_cfg = ClientConfig::new("friend");
    ok_cfg.secret = Some(b"9e107d9d372bb6826bd81d3542a419d6".into());
    // The friend shares the attacker's address, which the throttle of failed handshakes slows
    // for a while (2 a second come back): it retries, within a bound.
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        match Connection::connect(secured_addr, &ok_cfg) {
            Ok(c) => break c,
            Err(RpcError::Remote(WireError::Protocol(ProtocolError::RateLimited { .. })))
                if Instant::now() < deadline =>
            {
                std::thread::sleep(Duration::from_millis(100));
            }
            Err(e) => panic!("the friend was refused: {e}"),
        }
    }
}

/// Every attack got its typed error or was dropped, the good client was answered during them,
/// and the stalled reader's session was closed.
fn every_attack_met_its_answer(
    stats: &ServerStats,
    seen: &Seen,
    good_calls: &AtomicU64,
    service: &TestService,
) {
    let load = |c: &AtomicU64| c.load(Ordering::Relaxed);
    println!(
        "attacks saw: malformed {}, too large {}, handshake timeouts {}, too many connections {}, \
         rate-limited replies {}, rate-limit drops {}, auth failed {}, telemetry dropped {}, \
         fuzz inputs {}; good calls during the attack {}",
        load(&seen.malformed),
        load(&seen.too_large),
        load(&seen.handshake_timeouts),
        load(&seen.too_many),
        load(&seen.rate_limited_replies),
        load(&seen.rate_limit_drops),
        load(&seen.auth_failed),
        load(&seen.telemetry_dropped),
        load(&seen.fuzz_inputs),
        load(good_calls),
    );
    assert!(load(&seen.malformed) > 0, "garbage must get Malformed");
    assert!(
        load(&seen.too_large) > 0,
        "an oversized length must get FrameTooLarge"
    );
    assert!(
        load(&seen.handshake_timeouts) > 0,
        "a silent client must time out"
    );
    assert!(stats.refused > 0, "the flood must hit the connection limit");
    assert!(
        load(&seen.rate_limited_replies) > 0,
        "the request flood must be limited"
    );
    assert!(
        load(&seen.rate_limit_drops) > 0,
        "sustained abuse must be dropped"
    );
    assert!(load(&seen.auth_failed) > 0, "a wrong secret must fail");
    assert!(
        load(&seen.telemetry_dropped) > 0,
        "a client that does not read loses telemetry"
    );
    assert!(load(&seen.fuzz_inputs) > 0);
    assert!(load(good_calls) > 10);
    assert!(stats.timeouts > 0 && stats.dropped > 0 && stats.too_large > 0);
    assert!(
        service.subscribers.lock().unwrap().is_empty(),
        "the stalled reader's session must be closed"
    );
}

/// The control loop saw no more overruns under attack than in the quiet window (plus a small
/// tolerance).
fn the_loop_kept_its_time(quiet: &RunReport, attack: &RunReport) {
    println!(
        "control loop (1 ms, fifo {:?}): quiet window {} ticks, {} overruns, {} skipped; \
         attack window {} ticks, {} overruns, {} skipped",
        quiet.rt.fifo,
        quiet.ticks,
        quiet.overruns,
        quiet.skipped,
        attack.ticks,
        attack.overruns,
        attack.skipped
    );
    let tolerance = 5 + attack.ticks / 100;
    assert!(
        attack.overruns <= quiet.overruns + tolerance,
        "the attacks disturbed the loop: {} overruns against {} quiet (tolerance {tolerance})",
        attack.overruns,
        quiet.overruns
    );
}

/// Names of the server's threads still alive in this process.
fn server_threads() -> Vec<String> {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return Vec::new();
    };
    dir.filter_map(|e| std::fs::read_to_string(e.ok()?.path().join("comm")).ok())
        .map(|n| n.trim().to_string())
        .filter(|n| n.starts_with("pnlp-"))
        .collect()
}

#[test]
fn a_non_loopback_bind_without_a_secret_is_refused() {
    let _serial = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let service = Arc::new(TestService::default());
    let any: SocketAddr = "0.0.0.0:0".parse().unwrap();
    match Server::bind(any, config(None), service.clone()) {
        Err(NetError::SecretRequired(a)) => assert_eq!(a, any),
        other => panic!("expected SecretRequired, got {other:?}"),
    }
    // With a secret it binds, and every client must authenticate.
    let s = Server::bind(
        any,
        config(Some(b"0123456789abcdef0123456789abcdef")),
        service,
    )
    .unwrap();
    let local = SocketAddr::from(([127, 0, 0, 1], s.local_addr().port()));
    assert!(matches!(
        Connection::connect(local, &ClientConfig::new("x")),
        Err(RpcError::Remote(WireError::Protocol(
            ProtocolError::AuthFailed
        )))
    ));
    s.shutdown();
}

#[test]
fn a_truncated_stream_and_a_bye_end_sessions_cleanly() {
    let _serial = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let service = Arc::new(TestService::default());
    let server = Server::bind(
        "127.0.0.1:0".parse().unwrap(),
        config(None),
        service.clone(),
    )
    .unwrap();
    let mut s = raw(server.local_addr()).unwrap();
    let mut bytes = hello();
    bytes.extend(frame(&ClientMsg::Bye));
    s.write_all(&bytes).unwrap();
    assert!(matches!(
        read_frame::<_, ServerMsg>(&mut s, MAX_FRAME),
        Ok(ServerMsg::Hello(_))
    ));
    assert!(matches!(
        read_frame::<_, ServerMsg>(&mut s, MAX_FRAME),
        Err(FrameError::Closed)
    ));
    half_frames(server.local_addr());
    let deadline = Instant::now() + Duration::from_secs(3);
    while service.closed.load(Ordering::Relaxed) < 2 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(service.closed.load(Ordering::Relaxed), 2);
    assert_eq!(server.stats().dropped, 0);
    server.shutdown();
}
