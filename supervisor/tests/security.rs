//! Fail safe and keep out: both ends prove the shared secret before a request crosses, every frame
//! after the handshake is authenticated, the naming service authorizes by role, and silent
//! connections cannot lock an operator out. Loopback only; every wait has a deadline.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use penelope_protocol::client::Client;
use penelope_protocol::net::auth::{self, ClientHandshake, Opener, Sealer};
use penelope_protocol::net::conn::{ClientConfig, Connection, RpcError};
use penelope_protocol::net::frame::{FrameDecoder, decode_body, encode, read_frame};
use penelope_protocol::net::server::{Server, ServerConfig};
use penelope_protocol::proto::{
    Call, CallError, Class, ClientHello, ClientMsg, DEFAULT_MAX_FRAME, MAGIC, NamingCall,
    ObjectRef, PROTOCOL_VERSION, ProtocolError, Reply, Role, Security, ServerHello, ServerMsg,
    WireError,
};
use penelope_protocol::service::{Service, Session};
use penelope_supervisor::naming::{NamingLimits, NamingService};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig, NodeError};

const SECRET: &[u8] = b"correct horse battery staple";
const ADMIN: &[u8] = b"the operator's own, longer admin secret";
const MAX: usize = DEFAULT_MAX_FRAME;

/// Echo, counting what it serves.
#[derive(Default)]
struct Counting {
    calls: AtomicU64,
}

impl Service for Counting {
    fn call(&self, _: &Session, call: Call) -> Result<Reply, WireError> {
        self.calls.fetch_add(1, Ordering::SeqCst);
        match call {
            Call::Ping { payload } => Ok(Reply::Pong(payload)),
            _ => Err(WireError::Call(CallError::NotReady("echo only".into()))),
        }
    }
}

fn local() -> SocketAddr {
    "127.0.0.1:0".parse().unwrap()
}

fn secured(service: Arc<dyn Service>) -> Server {
    let mut c = ServerConfig::new("lab-a");
    c.secret = Some(SECRET.into());
    c.handshake_timeout = Duration::from_secs(2);
    Server::bind(local(), c, service).unwrap()
}

fn with_secret(mut c: ClientConfig) -> ClientConfig {
    c.secret = Some(SECRET.into());
    c.timeout = Duration::from_secs(3);
    c
}

/// A fake node that answers the hello with `security` and then, under Noise, a handshake made
/// with another secret. Returns its address and, once the client is gone, every client message
/// it received after the hello.
fn fake_node(security: Security) -> (SocketAddr, thread::JoinHandle<Vec<ClientMsg>>) {
    let l = TcpListener::bind(local()).unwrap();
    let addr = l.local_addr().unwrap();
    let t = thread::spawn(move || {
        let (mut s, _) = l.accept().unwrap();
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let hello: ClientMsg = read_frame(&mut s, MAX).unwrap();
        let client_body = postcard::to_stdvec(&hello).unwrap();
        let ours = ServerMsg::Hello(ServerHello {
            magic: MAGIC,
            version: PROTOCOL_VERSION,
            node: "impostor".into(),
            security,
        });
        s.write_all(&encode(&ours, MAX).unwrap()).unwrap();
        let mut got = Vec::new();
        while let Ok(msg) = read_frame::<_, ClientMsg>(&mut s, MAX) {
            if let ClientMsg::Handshake { noise } = &msg {
                // Answer as a node with another secret would.
                let psk = auth::member_psk(b"not the secret");
                let p = auth::prologue(&client_body, &postcard::to_stdvec(&ours).unwrap());
                let (_, first) = ClientHandshake::start(&psk, &p).unwrap();
                let (second, _) = auth::answer(&psk, &p, &first).unwrap();
                assert_eq!(noise.len(), auth::HANDSHAKE_LEN);
                let answer = ServerMsg::Handshake { noise: second };
                let _ = s.write_all(&encode(&answer, MAX).unwrap());
            }
            got.push(msg);
        }
        got
    });
    (addr, t)
}

#[test]
fn a_node_that_never_proves_the_secret_gets_no_request() {
    // A node that offers no authentication at all.
    let (addr, seen) = fake_node(Security::Plain);
    match Connection::connect(addr, &with_secret(ClientConfig::new("ctl"))) {
        Err(RpcError::Unauthenticated(a)) => assert_eq!(a, addr),
        other => panic!("expected Unauthenticated, got {other:?}"),
    }
    assert_eq!(seen.join().unwrap(), Vec::new(), "nothing after the hello");

    // A node that runs the handshake without the secret.
    let (addr, seen) = fake_node(Security::Noise { admin: false });
    assert!(matches!(
        Connection::connect(addr, &with_secret(ClientConfig::new("ctl"))),
        Err(RpcError::Unauthenticated(_))
    ));
    let got = seen.join().unwrap();
    assert_eq!(got.len(), 1, "{got:?}");
    assert!(matches!(got[0], ClientMsg::Handshake { .. }));

    // The client library, asked for the naming tree: the same, and no request either.
    let (addr, seen) = fake_node(Security::Plain);
    let client = Client::connect(addr, with_secret(ClientConfig::new("ctl")));
    assert!(matches!(client, Err(RpcError::Unauthenticated(_))));
    assert!(seen.join().unwrap().is_empty());

    // A node with the secret does not register with such a naming service: its start fails at
    // once (waiting cannot fix it), having sent nothing.
    let (addr, seen) = fake_node(Security::Plain);
    let mut config = NodeConfig::new("lab-a", NamingChoice::Remote(addr));
    config.secret = Some(SECRET.into());
    match Node::start(config) {
        Err(NodeError::NamingRefused {
            cause: RpcError::Unauthenticated(_),
            ..
        }) => {}
        Err(other) => panic!("expected NamingRefused(Unauthenticated), got {other}"),
        Ok(_) => panic!("the node started against a naming service that never proved the secret"),
    }
    assert!(seen.join().unwrap().is_empty());
}

#[test]
fn a_client_without_the_secret_is_refused_and_serves_nothing() {
    let service = Arc::new(Counting::default());
    let server = secured(service.clone());
    let addr = server.local_addr();
    assert!(matches!(
        Connection::connect(addr, &ClientConfig::new("guest")),
        Err(RpcError::Remote(WireError::Protocol(
            ProtocolError::AuthFailed
        )))
    ));
    let mut wrong = ClientConfig::new("guest");
    wrong.secret = Some(b"password".into());
    assert!(matches!(
        Connection::connect(addr, &wrong),
        Err(RpcError::Remote(WireError::Protocol(
            ProtocolError::AuthFailed
        )))
    ));
    // A raw client that skips the handshake and sends a request: refused, never served.
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
    let mut bytes = encode(&ClientMsg::Hello(ClientHello::new("raw", Role::Admin)), MAX).unwrap();
    let ping = ClientMsg::Request {
        id: 1,
        call: Call::Ping { payload: vec![1] },
    };
    bytes.extend(encode(&ping, MAX).unwrap());
    s.write_all(&bytes).unwrap();
    assert!(matches!(
        read_frame::<_, ServerMsg>(&mut s, MAX),
        Ok(ServerMsg::Hello(ServerHello {
            security: Security::Noise { admin: false },
            ..
        }))
    ));
    assert!(matches!(
        read_frame::<_, ServerMsg>(&mut s, MAX),
        Ok(ServerMsg::Error(WireError::Protocol(
            ProtocolError::AuthFailed
        )))
    ));
    assert_eq!(server.stats().auth_failures, 3);
    assert_eq!(service.calls.load(Ordering::SeqCst), 0);
    // The right secret is served.
    let mut c = Connection::connect(addr, &with_secret(ClientConfig::new("ctl"))).unwrap();
    assert_eq!(
        c.call(Call::Ping { payload: vec![2] }).unwrap(),
        Reply::Pong(vec![2])
    );
    // Its ping, and the one that proved the secret before `connect` returned.
    assert_eq!(service.calls.load(Ordering::SeqCst), 2);
    drop(c);
    server.shutdown();
}

/// A hand-driven authenticated session: the handshake done with the library's pieces, frames
/// sealed by the test so it can alter, replay and reorder them.
struct Raw {
    stream: TcpStream,
    sealer: Sealer,
    opener: Opener,
    decoder: FrameDecoder,
}

impl Raw {
    fn open(addr: SocketAddr) -> Raw {
        let mut stream = TcpStream::connect(addr).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(3)))
            .unwrap();
        let hello = ClientMsg::Hello(ClientHello::new("raw", Role::Reader));
        stream.write_all(&encode(&hello, MAX).unwrap()).unwrap();
        let theirs: ServerMsg = read_frame(&mut stream, MAX).unwrap();
        let p = auth::prologue(
            &postcard::to_stdvec(&hello).unwrap(),
            &postcard::to_stdvec(&theirs).unwrap(),
        );
        let psk = auth::member_psk(SECRET);
        let (hs, first) = ClientHandshake::start(&psk, &p).unwrap();
        let msg = ClientMsg::Handshake { noise: first };
        stream.write_all(&encode(&msg, MAX).unwrap()).unwrap();
        let ServerMsg::Handshake { noise } = read_frame(&mut stream, MAX).unwrap() else {
            panic!("no handshake answer");
        };
        let (sealer, opener) = hs.finish(&noise).unwrap().split();
        Raw {
            stream,
            sealer,
            opener,
            decoder: FrameDecoder::new(auth::sealed_len(MAX)),
        }
    }

    fn sealed_ping(&mut self, id: u64) -> Vec<u8> {
        let ping = ClientMsg::Request {
            id,
            call: Call::Ping {
                payload: id.to_le_bytes().to_vec(),
            },
        };
        let mut out = Vec::new();
        self.sealer
            .seal_frames(&encode(&ping, MAX).unwrap(), &mut out)
            .unwrap();
        out
    }

    /// The node's next message, or `None` once it closed.
    fn next(&mut self) -> Option<ServerMsg> {
        let deadline = Instant::now() + Duration::from_secs(3);
        loop {
            let opener = &mut self.opener;
            let msg = self
                .decoder
                .next_with(|b| decode_body::<ServerMsg>(opener.open(b).unwrap()))
                .unwrap();
            if msg.is_some() {
                return msg;
            }
            assert!(
                Instant::now() < deadline,
                "the node neither answered nor closed"
            );
            match self.decoder.read_from(&mut self.stream) {
                Ok(0) | Err(_) => return None,
                Ok(_) => {}
            }
        }
    }

    /// The node answers `Error(Malformed)` and closes.
    fn expect_closed(&mut self) {
        assert!(matches!(
            self.next(),
            Some(ServerMsg::Error(WireError::Protocol(
                ProtocolError::Malformed(_)
            )))
        ));
        assert!(self.next().is_none(), "the node must close the connection");
    }
}

#[test]
fn a_tampered_replayed_or_reordered_frame_closes_the_connection() {
    let service = Arc::new(Counting::default());
    let server = secured(service.clone());
    let addr = server.local_addr();

    // Good frames are answered.
    let mut raw = Raw::open(addr);
    let first = raw.sealed_ping(1);
    raw.stream.write_all(&first).unwrap();
    assert!(matches!(
        raw.next(),
        Some(ServerMsg::Response { id: 1, .. })
    ));
    // The same frame again: replayed.
    raw.stream.write_all(&first).unwrap();
    raw.expect_closed();

    // A flipped bit.
    let mut raw = Raw::open(addr);
    let mut frame = raw.sealed_ping(1);
    frame[6] ^= 0x01;
    raw.stream.write_all(&frame).unwrap();
    raw.expect_closed();

    // Two frames in the wrong order.
    let mut raw = Raw::open(addr);
    let a = raw.sealed_ping(1);
    let b = raw.sealed_ping(2);
    raw.stream.write_all(&b).unwrap();
    raw.stream.write_all(&a).unwrap();
    raw.expect_closed();

    // A plain (unsealed) request after the handshake.
    let mut raw = Raw::open(addr);
    let plain = ClientMsg::Request {
        id: 1,
        call: Call::Ping { payload: vec![] },
    };
    raw.stream.write_all(&encode(&plain, MAX).unwrap()).unwrap();
    raw.expect_closed();

    assert_eq!(
        service.calls.load(Ordering::SeqCst),
        1,
        "only the good frame"
    );
    server.shutdown();
}

/// A relay between one client and `node` that flips the last bit of the node's frame number
/// `flip` (0: its hello, 1: its handshake answer, 2: the first sealed frame, ...).
fn tampering_relay(node: SocketAddr, flip: usize) -> SocketAddr {
    let l = TcpListener::bind(local()).unwrap();
    let addr = l.local_addr().unwrap();
    thread::spawn(move || {
        let (client, _) = l.accept().unwrap();
        let upstream = TcpStream::connect(node).unwrap();
        for s in [&client, &upstream] {
            s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        }
        let (mut c_in, mut u_out) = (client.try_clone().unwrap(), upstream.try_clone().unwrap());
        let up = thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = c_in.read(&mut buf) {
                if n == 0 || u_out.write_all(&buf[..n]).is_err() {
                    break;
                }
            }
            let _ = u_out.shutdown(std::net::Shutdown::Write);
        });
        let (mut u_in, mut c_out) = (upstream, client);
        for i in 0.. {
            let mut header = [0u8; 4];
            if u_in.read_exact(&mut header).is_err() {
                break;
            }
            let mut body = vec![0u8; u32::from_le_bytes(header) as usize];
            if u_in.read_exact(&mut body).is_err() {
                break;
            }
            if i == flip
                && let Some(last) = body.last_mut()
            {
                *last ^= 1;
            }
            if c_out.write_all(&header).is_err() || c_out.write_all(&body).is_err() {
                break;
            }
        }
        let _ = c_out.shutdown(std::net::Shutdown::Both);
        let _ = up.join();
    });
    addr
}

#[test]
fn the_client_refuses_a_tampered_frame_of_the_node() {
    let service = Arc::new(Counting::default());
    let server = secured(service.clone());
    let cfg = with_secret(ClientConfig::new("ctl"));

    // A changed hello (the node's `Security`): the handshake fails on both sides.
    let relay = tampering_relay(server.local_addr(), 0);
    assert!(Connection::connect(relay, &cfg).is_err());

    // A changed handshake answer: the client sends no request.
    let relay = tampering_relay(server.local_addr(), 1);
    assert!(matches!(
        Connection::connect(relay, &cfg),
        Err(RpcError::Unauthenticated(_))
    ));
    assert_eq!(service.calls.load(Ordering::SeqCst), 0);

    // A changed response (frame 3: frame 2 answered the ping that proved the secret): the call
    // fails and the connection is unusable.
    let relay = tampering_relay(server.local_addr(), 3);
    let mut c = Connection::connect(relay, &cfg).unwrap();
    assert!(matches!(
        c.call(Call::Ping { payload: vec![1] }),
        Err(RpcError::Frame(_))
    ));
    assert!(!c.is_usable());
    drop(c);
    server.shutdown();
}

fn naming_server(admin_secret: Option<&[u8]>) -> (Server, Arc<NamingService>) {
    let service = Arc::new(NamingService::new("naming", NamingLimits::default()));
    let mut c = ServerConfig::new("naming");
    c.secret = Some(SECRET.into());
    c.admin_secret = admin_secret.map(Into::into);
    let server = Server::bind(local(), c, service.clone()).unwrap();
    (server, service)
}

fn naming(conn: &mut Connection, call: NamingCall) -> Result<Reply, WireError> {
    match conn.call(Call::Naming(call)) {
        Ok(r) => Ok(r),
        Err(RpcError::Remote(e)) => Err(e),
        Err(e) => panic!("transport: {e}"),
    }
}

fn reference(node: &str, name: &str) -> ObjectRef {
    ObjectRef {
        node: node.into(),
        address: "127.0.0.1:7301".into(),
        name: name.into(),
        class: Class::Sensor,
        kind: "sensor/virtual".into(),
    }
}

fn register(node: &str) -> NamingCall {
    NamingCall::Register {
        node: node.into(),
        address: "127.0.0.1:7301".into(),
        lease_ms: 60_000,
    }
}

fn bind(path: &str, node: &str, rebind: bool) -> NamingCall {
    NamingCall::Bind {
        path: path.into(),
        reference: reference(node, "ft"),
        rebind,
    }
}

fn forbidden(r: Result<Reply, WireError>) -> bool {
    matches!(r, Err(WireError::Call(CallError::Forbidden(_))))
}

#[test]
fn a_node_writes_only_its_own_context_and_only_an_admin_writes_anywhere() {
    let (server, tree) = naming_server(Some(ADMIN));
    let addr = server.local_addr();
    let mut a = Connection::connect(addr, &with_secret(ClientConfig::node("lab-a"))).unwrap();
    let mut b = Connection::connect(addr, &with_secret(ClientConfig::node("lab-b"))).unwrap();
    for (conn, node) in [(&mut a, "lab-a"), (&mut b, "lab-b")] {
        naming(conn, register(node)).unwrap();
        naming(conn, bind(&format!("/{node}/sensors/ft"), node, false)).unwrap();
    }

    node_a_cannot_touch_node_bs_context_or_registration(&mut a);
    // B's entry is untouched.
    assert_eq!(
        tree.snapshot().resolve("/lab-b/sensors/ft").unwrap().node,
        "lab-b"
    );
    // A in its own context: rebind and unbind work.
    naming(&mut a, bind("/lab-a/sensors/ft", "lab-a", true)).unwrap();
    naming(
        &mut a,
        NamingCall::Unbind {
            path: "/lab-a/sensors/ft".into(),
        },
    )
    .unwrap();

    let reader = a_reader_reads_and_writes_nothing(addr);

    let mut admin = only_the_admin_secret_makes_an_admin(addr);
    naming(&mut admin, bind("/shared/ft", "lab-b", false)).unwrap();
    naming(
        &mut admin,
        NamingCall::Unregister {
            node: "lab-b".into(),
        },
    )
    .unwrap();
    assert!(tree.snapshot().node("lab-b").is_none());
    // B may unregister itself (it is gone already: the answer is the tree's, not Forbidden).
    assert!(!forbidden(naming(
        &mut b,
        NamingCall::Unregister {
            node: "lab-b".into()
        }
    )));
    drop((a, b, reader, admin));
    server.shutdown();

    an_admin_claim_at_a_node_without_an_admin_secret_is_a_reader();
}

/// Node A against node B's context and registration: every write is forbidden.
fn node_a_cannot_touch_node_bs_context_or_registration(a: &mut Connection) {
    assert!(forbidden(naming(
        a,
        NamingCall::Unbind {
            path: "/lab-b/sensors/ft".into()
        }
    )));
    assert!(forbidden(naming(
        a,
        bind("/lab-b/sensors/ft", "lab-a", true)
    )));
    assert!(forbidden(naming(a, bind("/lab-b/other", "lab-a", false))));
    assert!(forbidden(naming(a, bind("/shared/ft", "lab-a", false))));
    assert!(forbidden(naming(
        a,
        NamingCall::Unregister {
            node: "lab-b".into()
        }
    )));
    assert!(forbidden(naming(a, register("lab-b"))));
    assert!(forbidden(naming(
        a,
        NamingCall::Renew {
            node: "lab-b".into()
        }
    )));
}

/// A reader reads and writes nothing; returns its connection, open.
fn a_reader_reads_and_writes_nothing(addr: SocketAddr) -> Connection {
    let mut reader = Connection::connect(addr, &with_secret(ClientConfig::new("ctl"))).unwrap();
    assert!(
        naming(
            &mut reader,
            NamingCall::List {
                context: "/".into()
            }
        )
        .is_ok()
    );
    assert!(forbidden(naming(
        &mut reader,
        bind("/lab-a/x", "lab-a", false)
    )));
    assert!(forbidden(naming(
        &mut reader,
        NamingCall::Unregister {
            node: "lab-a".into()
        }
    )));
    reader
}

/// An admin claim without the admin secret, or with a wrong one, is refused; with it, the
/// connection is an admin's (returned).
fn only_the_admin_secret_makes_an_admin(addr: SocketAddr) -> Connection {
    assert!(matches!(
        Connection::connect(addr, &with_secret(ClientConfig::admin("ops"))),
        Err(RpcError::Remote(WireError::Protocol(
            ProtocolError::AuthFailed
        )))
    ));
    let mut wrong = with_secret(ClientConfig::admin("ops"));
    wrong.admin_secret = Some(b"guess".into());
    assert!(Connection::connect(addr, &wrong).is_err());
    let mut cfg = with_secret(ClientConfig::admin("ops"));
    cfg.admin_secret = Some(ADMIN.into());
    Connection::connect(addr, &cfg).unwrap()
}

/// At a node without an admin secret, an admin claim is served as a reader.
fn an_admin_claim_at_a_node_without_an_admin_secret_is_a_reader() {
    let (server, _) = naming_server(None);
    let mut cfg = with_secret(ClientConfig::admin("ops"));
    cfg.admin_secret = Some(ADMIN.into());
    let mut ops = Connection::connect(server.local_addr(), &cfg).unwrap();
    assert!(forbidden(naming(&mut ops, register("lab-c"))));
    drop(ops);
    server.shutdown();
}

#[test]
fn two_hundred_silent_connections_do_not_keep_the_operator_out() {
    // The handshake time is long on purpose: if silent connections held their slots, the
    // operator would wait for it.
    let service = Arc::new(NamingService::new("naming", NamingLimits::default()));
    let mut c = ServerConfig::new("naming");
    c.secret = Some(SECRET.into());
    c.handshake_timeout = Duration::from_secs(30);
    let server = Server::bind(local(), c, service).unwrap();
    let addr = server.local_addr();

    let silent: Vec<TcpStream> = (0..200)
        .map(|_| TcpStream::connect(addr).unwrap())
        .collect();
    // Wait (bounded) until the node has taken every one of them.
    let deadline = Instant::now() + Duration::from_secs(10);
    while server.stats().accepted < 200 {
        assert!(Instant::now() < deadline, "accepted {:?}", server.stats());
        thread::sleep(Duration::from_millis(5));
    }

    let start = Instant::now();
    let client = Client::connect(addr, with_secret(ClientConfig::new("ctl"))).unwrap();
    let names = client.naming().list("/").unwrap();
    let took = start.elapsed();
    println!(
        "ls with 200 silent connections open: {took:?} ({} evicted)",
        server.stats().refused
    );
    assert!(names.is_empty());
    // Generous: a tenth of the handshake time the silent connections could otherwise hold.
    assert!(took < Duration::from_secs(3), "ls took {took:?}");
    assert!(
        server.stats().refused >= 200 - 32,
        "the pending pool is bounded: {:?}",
        server.stats()
    );
    // The evicted ones were told why and closed (wait, bounded, until most have been read).
    let mut told = vec![false; silent.len()];
    let deadline = Instant::now() + Duration::from_secs(5);
    for s in &silent {
        s.set_nonblocking(true).unwrap();
    }
    while told.iter().filter(|t| **t).count() < 200 - 32 {
        assert!(
            Instant::now() < deadline,
            "evicted connections were not told why"
        );
        for (s, t) in silent.iter().zip(told.iter_mut()).filter(|(_, t)| !**t) {
            let mut buf = [0u8; 64];
            if let Ok(n) = (&*s).read(&mut buf)
                && n > 0
            {
                assert!(matches!(
                    read_frame::<_, ServerMsg>(&mut &buf[..n], MAX),
                    Ok(ServerMsg::Error(WireError::Protocol(
                        ProtocolError::TooManyConnections { .. }
                    )))
                ));
                *t = true;
            }
        }
        thread::sleep(Duration::from_millis(5));
    }
    drop(silent);
    drop(client);
    server.shutdown();
}
