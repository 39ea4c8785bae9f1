//! Keep out, door by door, against a real server on loopback: no session slot before the secret
//! is proven in a way that cannot be replayed; one address cannot hold every slot; short
//! secrets are refused and failed handshakes are slowed per address; roles hold on every object
//! call (a reader watches and stops, an operator runs, an admin creates); one address cannot
//! take every subscription. Clients of "other hosts" are bound to 127.0.0.2 and up. Every wait
//! has a deadline.

use std::io::Write;
use std::net::{SocketAddr, TcpStream};
use std::os::fd::{FromRawFd, IntoRawFd};
use std::sync::Arc;
use std::time::{Duration, Instant};

use nix::sys::socket::{
    AddressFamily, SockFlag, SockType, SockaddrIn, bind, connect, setsockopt, socket, sockopt,
};
use penelope_protocol::net::auth::{self, ClientHandshake, Secret};
use penelope_protocol::net::conn::{ClientConfig, Connection, RpcError};
use penelope_protocol::net::frame::{encode, read_frame};
use penelope_protocol::net::server::{NetError, Server, ServerConfig};
use penelope_protocol::proto::{
    BoardMethod, Call, CallError, ClientHello, ClientMsg, ControllerMethod, CreatorCall,
    DEFAULT_MAX_FRAME, JointAxis, Method, NamingCall, ProtocolError, Reply, RobotMethod, Role,
    ServerMsg, WireError,
};
use penelope_protocol::service::{Service, Session};
use penelope_supervisor::naming::{NamingLimits, NamingService};
use penelope_supervisor::node::{NamingChoice, Node, NodeConfig, NodeError};
use penelope_testkit::wait::wait_until;

const SECRET: &[u8] = b"5f0c2d9e8b7a61403f2e1d0c9b8a7f6e";
const ADMIN: &[u8] = b"a1b2c3d4e5f60718293a4b5c6d7e8f90";
const MAX: usize = DEFAULT_MAX_FRAME;

struct Echo;

impl Service for Echo {
    fn call(&self, _: &Session, call: Call) -> Result<Reply, WireError> {
        match call {
            Call::Ping { payload } => Ok(Reply::Pong(payload)),
            _ => Err(WireError::Call(CallError::NotReady("echo only".into()))),
        }
    }
}

fn local() -> SocketAddr {
    "127.0.0.1:0".parse().unwrap()
}

/// A TCP connection to `to` from the loopback address `from` (127.0.0.x: another "host").
fn connect_from(from: [u8; 4], to: SocketAddr) -> TcpStream {
    let fd = socket(
        AddressFamily::Inet,
        SockType::Stream,
        SockFlag::SOCK_CLOEXEC,
        None,
    )
    .unwrap();
    setsockopt(&fd, sockopt::ReuseAddr, &true).unwrap();
    let [a, b, c, d] = from;
    bind(
        std::os::fd::AsRawFd::as_raw_fd(&fd),
        &SockaddrIn::new(a, b, c, d, 0),
    )
    .unwrap();
    let SocketAddr::V4(v4) = to else {
        panic!("IPv4 only")
    };
    connect(std::os::fd::AsRawFd::as_raw_fd(&fd), &SockaddrIn::from(v4)).unwrap();
    // SAFETY: `fd` is a connected TCP socket that nothing else owns.
    let s = unsafe { TcpStream::from_raw_fd(fd.into_raw_fd()) };
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s.set_nodelay(true).unwrap();
    s
}

fn with_secret(mut c: ClientConfig) -> ClientConfig {
    c.secret = Some(SECRET.into());
    c.timeout = Duration::from_secs(5);
    c
}

/// The bytes a genuine client sends to `server` before its first sealed frame (its hello and
/// its first Noise message), as an eavesdropper on the path records them.
fn sniff_a_handshake(server: SocketAddr) -> Vec<u8> {
    let mut s = TcpStream::connect(server).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let hello = ClientMsg::Hello(ClientHello::new("operator", Role::Operator));
    let mut wire = encode(&hello, MAX).unwrap();
    s.write_all(&wire).unwrap();
    let theirs: ServerMsg = read_frame(&mut s, MAX).unwrap();
    let p = auth::prologue(
        &postcard::to_stdvec(&hello).unwrap(),
        &postcard::to_stdvec(&theirs).unwrap(),
    );
    let (_, first) = ClientHandshake::start(&auth::member_psk(SECRET), &p).unwrap();
    let msg = encode(&ClientMsg::Handshake { noise: first }, MAX).unwrap();
    s.write_all(&msg).unwrap();
    wire.extend_from_slice(&msg);
    wire
}

#[test]
fn sixty_replays_of_a_sniffed_handshake_hold_no_slot_and_the_operator_connects() {
    let mut c = ServerConfig::new("lab");
    c.secret = Some(SECRET.into());
    // Long on purpose: a replay that held a slot would hold it this long.
    c.handshake_timeout = Duration::from_secs(60);
    let server = Server::bind(local(), c, Arc::new(Echo)).unwrap();
    let addr = server.local_addr();
    let recorded = sniff_a_handshake(addr);

    // 60 replays from another host, each answered (the first message verifies again: it
    // cannot tell a replay), each left open and silent.
    let mut replays = Vec::new();
    let mut answered = 0;
    for _ in 0..60 {
        let mut s = connect_from([127, 0, 0, 2], addr);
        s.write_all(&recorded).unwrap();
        if let Ok(ServerMsg::Hello(_)) = read_frame::<_, ServerMsg>(&mut s, MAX)
            && let Ok(ServerMsg::Handshake { .. }) = read_frame::<_, ServerMsg>(&mut s, MAX)
        {
            answered += 1;
        }
        replays.push(s);
    }
    println!(
        "{answered} of 60 replays answered; stats after them: {:?}",
        server.stats()
    );
    assert!(answered >= 50, "the replays verified: {answered}");
    assert_eq!(server.stats().sessions, 0, "no replay became a session");

    let start = Instant::now();
    let mut op = Connection::connect(addr, &with_secret(ClientConfig::operator("ops"))).unwrap();
    assert_eq!(
        op.call(Call::Ping { payload: vec![7] }).unwrap(),
        Reply::Pong(vec![7])
    );
    println!("operator connected and answered in {:?}", start.elapsed());
    assert!(start.elapsed() < Duration::from_secs(3));
    assert_eq!(server.stats().sessions, 1);
    drop(replays);
    drop(op);
    server.shutdown();
}

#[test]
fn sixty_four_idle_sessions_from_one_address_do_not_lock_out_another() {
    // No secret: a session opens at the hello, so idle sessions are cheap to hold.
    let server = Server::bind(local(), ServerConfig::new("lab"), Arc::new(Echo)).unwrap();
    let addr = server.local_addr();
    let mut idle = Vec::new();
    for _ in 0..64 {
        let mut s = connect_from([127, 0, 0, 2], addr);
        let hello = ClientMsg::Hello(ClientHello::new("idle", Role::Reader));
        s.write_all(&encode(&hello, MAX).unwrap()).unwrap();
        let answer: ServerMsg = read_frame(&mut s, MAX).unwrap();
        idle.push((s, answer));
    }
    let sessions = idle
        .iter()
        .filter(|(_, a)| matches!(a, ServerMsg::Hello(_)))
        .count();
    println!(
        "one address opened {sessions} idle sessions of 64 tried: {:?}",
        server.stats()
    );
    assert_eq!(sessions, 60, "every slot but the admin reserve");

    // Another host's operator gets in at once (an idle session of the address over its quota
    // is evicted for it), and so does an administrator (the reserve).
    let start = Instant::now();
    let mut other = connect_from([127, 0, 0, 3], addr);
    let hello = ClientMsg::Hello(ClientHello::new("ops", Role::Operator));
    other.write_all(&encode(&hello, MAX).unwrap()).unwrap();
    assert!(matches!(
        read_frame::<_, ServerMsg>(&mut other, MAX),
        Ok(ServerMsg::Hello(_))
    ));
    let ping = ClientMsg::Request {
        id: 1,
        call: Call::Ping { payload: vec![1] },
    };
    other.write_all(&encode(&ping, MAX).unwrap()).unwrap();
    assert!(matches!(
        read_frame::<_, ServerMsg>(&mut other, MAX),
        Ok(ServerMsg::Response { id: 1, .. })
    ));
    println!("the other address was served in {:?}", start.elapsed());
    assert!(start.elapsed() < Duration::from_secs(3));
    let mut admin = Connection::connect(addr, &ClientConfig::admin("root")).unwrap();
    assert!(admin.call(Call::Ping { payload: vec![] }).is_ok());
    // The evicted idle session was told why.
    let told = idle.iter_mut().any(|(s, _)| {
        s.set_read_timeout(Some(Duration::from_millis(20))).unwrap();
        matches!(
            read_frame::<_, ServerMsg>(s, MAX),
            Ok(ServerMsg::Error(WireError::Protocol(
                ProtocolError::TooManyConnections { .. }
            )))
        )
    });
    assert!(told, "the evicted session gets TooManyConnections");
    drop(idle);
    server.shutdown();
}

/// One failed handshake from `from`: the node's verdict (`AuthFailed` once it checked the
/// guess, `RateLimited` when it refused to).
fn guess(from: [u8; 4], addr: SocketAddr) -> WireError {
    let mut s = connect_from(from, addr);
    let hello = ClientMsg::Hello(ClientHello::new("guesser", Role::Reader));
    s.write_all(&encode(&hello, MAX).unwrap()).unwrap();
    let theirs: ServerMsg = read_frame(&mut s, MAX).unwrap();
    let ServerMsg::Hello(_) = &theirs else {
        match theirs {
            ServerMsg::Error(e) => return e,
            other => panic!("unexpected {other:?}"),
        }
    };
    let p = auth::prologue(
        &postcard::to_stdvec(&hello).unwrap(),
        &postcard::to_stdvec(&theirs).unwrap(),
    );
    let (_, first) = ClientHandshake::start(&auth::member_psk(b"a wrong guess"), &p).unwrap();
    s.write_all(&encode(&ClientMsg::Handshake { noise: first }, MAX).unwrap())
        .unwrap();
    match read_frame::<_, ServerMsg>(&mut s, MAX).unwrap() {
        ServerMsg::Error(e) => e,
        other => panic!("unexpected {other:?}"),
    }
}

#[test]
fn failed_handshakes_are_slowed_per_address_while_another_address_connects_at_once() {
    let mut c = ServerConfig::new("lab");
    c.secret = Some(SECRET.into());
    let (burst, per_s) = (c.auth_failure_burst, c.auth_failures_per_s);
    let server = Server::bind(local(), c, Arc::new(Echo)).unwrap();
    let addr = server.local_addr();

    // Before: the burst is checked as fast as the node answers.
    let start = Instant::now();
    for _ in 0..burst {
        assert_eq!(
            guess([127, 0, 0, 2], addr),
            WireError::Protocol(ProtocolError::AuthFailed)
        );
    }
    let before = f64::from(burst) / start.elapsed().as_secs_f64();
    // After: for two seconds, guesses as fast as they go; only about `per_s` a second are
    // checked, the rest refused before the check.
    let window = Instant::now();
    let (mut checked, mut refused) = (0u32, 0u32);
    while window.elapsed() < Duration::from_secs(2) && checked + refused < 5000 {
        match guess([127, 0, 0, 2], addr) {
            WireError::Protocol(ProtocolError::AuthFailed) => checked += 1,
            WireError::Protocol(ProtocolError::RateLimited { .. }) => refused += 1,
            other => panic!("unexpected {other:?}"),
        }
    }
    let after = f64::from(checked) / window.elapsed().as_secs_f64();
    println!(
        "guesses checked: {before:.0}/s during the burst of {burst}, then {after:.1}/s \
         ({checked} checked, {refused} refused in {:?}; the limit is {per_s}/s)",
        window.elapsed()
    );
    assert!(refused > 0, "the throttle refused nothing");
    assert!(
        f64::from(checked) <= per_s * window.elapsed().as_secs_f64() + 2.0,
        "{checked} guesses checked"
    );

    // Another address, meanwhile, connects at once.
    let start = Instant::now();
    let mut other = connect_from([127, 0, 0, 3], addr);
    let hello = ClientMsg::Hello(ClientHello::new("ops", Role::Operator));
    other.write_all(&encode(&hello, MAX).unwrap()).unwrap();
    assert!(matches!(
        read_frame::<_, ServerMsg>(&mut other, MAX),
        Ok(ServerMsg::Hello(_))
    ));
    drop(other);
    let mut ok = Connection::connect(addr, &with_secret(ClientConfig::operator("ops"))).unwrap();
    assert!(ok.call(Call::Ping { payload: vec![] }).is_ok());
    println!("the other addresses were answered in {:?}", start.elapsed());
    assert!(start.elapsed() < Duration::from_secs(2));
    server.shutdown();
}

#[test]
fn a_short_secret_is_refused_at_start_with_how_to_make_one() {
    let mut config = NodeConfig::new("weak", NamingChoice::Host);
    config.secret = Some(b"ab".into());
    let Err(e) = Node::start(config) else {
        panic!("a 2-character secret was accepted")
    };
    println!("{e}");
    assert!(
        matches!(&e, NodeError::Listen(NetError::WeakSecret(_))),
        "{e:?}"
    );
    assert!(e.to_string().contains("penelope secret new"), "{e}");
    // The naming service alone: the same.
    let naming = Arc::new(NamingService::new("naming", NamingLimits::default()));
    let mut c = ServerConfig::new("naming");
    c.secret = Some(b"password".into());
    let Err(e) = Server::bind(local(), c, naming) else {
        panic!("a weak secret was accepted")
    };
    assert!(matches!(&e, NetError::WeakSecret(_)), "{e:?}");
    assert!(e.to_string().contains("too weak"), "{e}");
    // And secrets never show in a configuration's debug output.
    let mut c = ServerConfig::new("n");
    c.secret = Some(SECRET.into());
    c.admin_secret = Some(ADMIN.into());
    let shown = format!("{c:?} {:?}", with_secret(ClientConfig::admin("a")));
    assert!(shown.contains("<redacted>"), "{shown}");
    for s in [SECRET, ADMIN] {
        assert!(!shown.contains(std::str::from_utf8(s).unwrap()), "{shown}");
        assert!(!shown.contains(&format!("{:?}", s.to_vec())), "{shown}");
    }
    assert_eq!(format!("{:?}", Secret::from(SECRET)), "Secret(<redacted>)");
}

/// A node with both secrets, and a running PID controller (set up in-process).
fn node_with_a_running_controller() -> Node {
    let mut config = NodeConfig::new("lab", NamingChoice::Host);
    config.secret = Some(SECRET.into());
    config.server.admin_secret = Some(ADMIN.into());
    let node = Node::start(config).unwrap();
    let create = |kind: &str, name: &str, cfg: &str| {
        node.call(Call::Creator(CreatorCall::Create {
            kind: kind.into(),
            name: name.into(),
            config: cfg.into(),
        }))
        .unwrap();
    };
    let call = |object: &str, method: Method| {
        node.call(Call::Object {
            object: object.into(),
            method,
        })
        .unwrap();
    };
    create("board/sim", "sim0", "axes = 6\nsubstep_us = 200");
    create("robot/puma560", "slave", "");
    create("trajectory/step", "hold", "pose = \"start\"");
    create("controller/joint-pid", "pid", "period_us = 2000");
    call(
        "slave",
        Method::Robot(RobotMethod::MapJoints {
            board: "sim0".into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    let t = |object: &str, tr| call(object, Method::Transition(tr));
    use penelope_hal::Transition::{Activate, Configure};
    t("sim0", Configure);
    t("slave", Configure);
    call(
        "pid",
        Method::Controller(ControllerMethod::SetRobot {
            robot: "slave".into(),
        }),
    );
    call(
        "pid",
        Method::Controller(ControllerMethod::SetTrajectory {
            trajectory: "hold".into(),
        }),
    );
    t("hold", Configure);
    t("pid", Configure);
    t("pid", Activate);
    node
}

fn forbidden(r: Result<Reply, RpcError>) -> bool {
    matches!(
        r,
        Err(RpcError::Remote(WireError::Call(CallError::Forbidden(_))))
    )
}

fn status(c: &mut Connection) -> String {
    match c.call(Call::Object {
        object: "pid".into(),
        method: Method::Controller(ControllerMethod::Status),
    }) {
        Ok(Reply::Status(s)) => s.last.map(|l| l.state).unwrap_or_default(),
        other => panic!("status: {other:?}"),
    }
}

#[test]
fn a_reader_cannot_create_rearm_or_record_but_can_stop() {
    let node = node_with_a_running_controller();
    let addr = node.address();
    let mut reader = Connection::connect(addr, &with_secret(ClientConfig::new("web"))).unwrap();
    wait_until("the loop to run", || status(&mut reader) == "running");

    let create = Call::Creator(CreatorCall::Create {
        kind: "board/sim".into(),
        name: "intruder".into(),
        config: String::new(),
    });
    let object = |method| Call::Object {
        object: "pid".into(),
        method,
    };
    let record = Call::Creator(CreatorCall::RecordStart {
        path: std::env::temp_dir()
            .join(format!("reader-{}.mcap", std::process::id()))
            .to_string_lossy()
            .into_owned(),
        objects: Vec::new(),
    });
    assert!(forbidden(reader.call(create.clone())));
    assert!(forbidden(reader.call(Call::Creator(
        CreatorCall::Destroy {
            name: "pid".into(),
            force: true,
        }
    ))));
    assert!(forbidden(
        reader.call(object(Method::Controller(ControllerMethod::Rearm)))
    ));
    assert!(forbidden(reader.call(Call::Object {
        object: "sim0".into(),
        method: Method::Board(BoardMethod::Rearm),
    })));
    assert!(forbidden(reader.call(record.clone())));
    assert!(forbidden(reader.call(object(Method::Controller(
        ControllerMethod::SetGains {
            gains: "kp = [1, 1, 1, 1, 1, 1]".into()
        }
    )))));
    // It lists and watches...
    assert!(matches!(
        reader.call(Call::Creator(CreatorCall::List)),
        Ok(Reply::Objects(o)) if o.len() == 4
    ));
    assert!(matches!(
        reader.call(Call::Subscribe {
            object: "pid".into(),
            decimation: 10
        }),
        Ok(Reply::Subscribed { .. })
    ));
    // ... and stops: the e-stop latches.
    reader
        .call(object(Method::Controller(ControllerMethod::EStop)))
        .unwrap();
    wait_until("the e-stop", || status(&mut reader) == "estop");

    // An operator (the shared secret alone) re-arms but does not create; an admin creates.
    let mut operator =
        Connection::connect(addr, &with_secret(ClientConfig::operator("ops"))).unwrap();
    assert!(forbidden(operator.call(create.clone())));
    operator
        .call(object(Method::Controller(ControllerMethod::Rearm)))
        .unwrap();
    let mut admin_cfg = with_secret(ClientConfig::admin("root"));
    admin_cfg.admin_secret = Some(ADMIN.into());
    let mut admin = Connection::connect(addr, &admin_cfg).unwrap();
    assert!(matches!(admin.call(create), Ok(Reply::Object(_))));
    drop((reader, operator, admin));
    node.shutdown();
}

/// A system file for node `lab`: a board, a robot on it, a trajectory and a controller that
/// comes up active.
const SMALL_SYSTEM: &str = r#"
[boards.io2]
kind = "sim"

[robots.arm2]
kind = "puma560"
start = "start"
joints = [{ board = "io2", joints = [0, 1, 2, 3, 4, 5] }]

[trajectories.hold2]
kind = "spline"
waypoints = [{ at_s = 1.0, pose = "start" }]

[controllers.pid2]
kind = "joint-pid"
robot = "arm2"
trajectory = "hold2"
period_us = 2000
"#;

fn names(objects: &[penelope_protocol::proto::ObjectInfo]) -> Vec<&str> {
    objects.iter().map(|o| o.name.as_str()).collect()
}

#[test]
fn a_reader_cannot_apply_a_system_file_an_admin_can_and_a_bad_one_is_a_typed_error() {
    let node = node_with_a_running_controller();
    let addr = node.address();
    let apply = |text: &str| {
        Call::Creator(CreatorCall::ApplySystem {
            text: text.to_string(),
        })
    };
    let mut reader = Connection::connect(addr, &with_secret(ClientConfig::new("web"))).unwrap();
    assert!(forbidden(reader.call(apply(SMALL_SYSTEM))));
    // Refused before the text is read: a reader's malformed file is still just forbidden.
    assert!(forbidden(reader.call(apply("[[[ not toml"))));
    let mut operator =
        Connection::connect(addr, &with_secret(ClientConfig::operator("ops"))).unwrap();
    assert!(forbidden(operator.call(apply(SMALL_SYSTEM))));
    let list = |c: &mut Connection| match c.call(Call::Creator(CreatorCall::List)) {
        Ok(Reply::Objects(o)) => o,
        other => panic!("list: {other:?}"),
    };
    assert_eq!(
        list(&mut reader).len(),
        4,
        "nothing created by the refusals"
    );

    let mut admin_cfg = with_secret(ClientConfig::admin("root"));
    admin_cfg.admin_secret = Some(ADMIN.into());
    let mut admin = Connection::connect(addr, &admin_cfg).unwrap();
    // Malformed: a typed error naming the line, and nothing created.
    match admin.call(apply("[boards.x]\nkind = \"sim\"\n[[[")) {
        Err(RpcError::Remote(WireError::Call(CallError::BadConfig { kind, message }))) => {
            assert_eq!(kind, "system file");
            assert!(message.starts_with("line 3"), "{message}");
        }
        other => panic!("a malformed file: {other:?}"),
    }
    // A refused step (an unknown key of the robot's kind): typed, and nothing kept.
    let refused = SMALL_SYSTEM.replace("start = \"start\"", "speed = 3");
    match admin.call(apply(&refused)) {
        Err(RpcError::Remote(WireError::Call(CallError::BadConfig { kind, message }))) => {
            assert_eq!(kind, "system file");
            assert!(message.contains("robots.arm2"), "{message}");
            assert!(
                message.contains("nothing from the file was kept"),
                "{message}"
            );
        }
        other => panic!("a refused step: {other:?}"),
    }
    assert_eq!(names(&list(&mut admin)), ["hold", "pid", "sim0", "slave"]);

    let created = match admin.call(apply(SMALL_SYSTEM)) {
        Ok(Reply::Objects(o)) => o,
        other => panic!("apply: {other:?}"),
    };
    assert_eq!(names(&created), ["io2", "arm2", "hold2", "pid2"]);
    let mut all = names(&list(&mut admin))
        .into_iter()
        .map(String::from)
        .collect::<Vec<_>>();
    all.sort();
    assert_eq!(
        all,
        [
            "arm2", "hold", "hold2", "io2", "pid", "pid2", "sim0", "slave"
        ]
    );
    // Bound in the naming tree like any created object, and the controller runs.
    match admin.call(Call::Naming(NamingCall::Resolve {
        path: "/lab/controllers/pid2".into(),
    })) {
        Ok(Reply::Resolved(r)) => assert_eq!(r.name, "pid2"),
        other => panic!("resolve: {other:?}"),
    }
    wait_until("the file's controller to run", || {
        matches!(admin.call(Call::Object {
            object: "pid2".into(),
            method: Method::Controller(ControllerMethod::Status),
        }), Ok(Reply::Status(s)) if s.last.as_ref().is_some_and(|l| l.state == "running"))
    });
    drop((reader, operator, admin));
    node.shutdown();
}

#[test]
fn one_address_cannot_take_every_subscription() {
    let node = node_with_a_running_controller();
    let addr = node.address();
    let subscribe = |c: &mut Connection| {
        c.call(Call::Subscribe {
            object: "pid".into(),
            decimation: 1000,
        })
    };
    // From 127.0.0.1: as many as it is given (one connection is enough to ask for all).
    let mut greedy = Connection::connect(addr, &with_secret(ClientConfig::new("greedy"))).unwrap();
    let mut held = 0;
    let refusal = loop {
        match subscribe(&mut greedy) {
            Ok(_) => held += 1,
            Err(e) => break e,
        }
        assert!(held <= 64, "more subscriptions than the pool");
    };
    println!("one address held {held} subscriptions, then: {refusal}");
    assert!(matches!(
        refusal,
        RpcError::Remote(WireError::Call(CallError::LimitReached { .. }))
    ));
    assert!(held < 64, "one address took the whole pool");
    // Another host still subscribes (its hello and handshake by hand, bound to 127.0.0.2).
    let mut other = connect_from([127, 0, 0, 2], addr);
    let hello = ClientMsg::Hello(ClientHello::new("other", Role::Reader));
    let mut session = handshake_by_hand(&mut other, &hello);
    let reply = session.call(
        &mut other,
        Call::Subscribe {
            object: "pid".into(),
            decimation: 1000,
        },
    );
    assert!(matches!(reply, Ok(Reply::Subscribed { .. })), "{reply:?}");
    drop(greedy);
    drop(other);
    node.shutdown();
}

/// A sealed session done by hand over `s` (for a client bound to another address).
struct HandSession {
    sealer: auth::Sealer,
    opener: auth::Opener,
    next_id: u64,
}

fn handshake_by_hand(s: &mut TcpStream, hello: &ClientMsg) -> HandSession {
    s.write_all(&encode(hello, MAX).unwrap()).unwrap();
    let theirs: ServerMsg = read_frame(s, MAX).unwrap();
    let p = auth::prologue(
        &postcard::to_stdvec(hello).unwrap(),
        &postcard::to_stdvec(&theirs).unwrap(),
    );
    let (hs, first) = ClientHandshake::start(&auth::member_psk(SECRET), &p).unwrap();
    s.write_all(&encode(&ClientMsg::Handshake { noise: first }, MAX).unwrap())
        .unwrap();
    let ServerMsg::Handshake { noise } = read_frame(s, MAX).unwrap() else {
        panic!("no handshake answer");
    };
    let (sealer, opener) = hs.finish(&noise).unwrap().split();
    HandSession {
        sealer,
        opener,
        next_id: 1,
    }
}

impl HandSession {
    fn call(&mut self, s: &mut TcpStream, call: Call) -> Result<Reply, WireError> {
        let id = self.next_id;
        self.next_id += 1;
        let mut out = Vec::new();
        self.sealer
            .seal_frames(
                &encode(&ClientMsg::Request { id, call }, MAX).unwrap(),
                &mut out,
            )
            .unwrap();
        s.write_all(&out).unwrap();
        loop {
            let mut header = [0u8; 4];
            std::io::Read::read_exact(s, &mut header).unwrap();
            let mut body = vec![0u8; u32::from_le_bytes(header) as usize];
            std::io::Read::read_exact(s, &mut body).unwrap();
            let plain = self.opener.open(&body).unwrap().to_vec();
            match postcard::from_bytes::<ServerMsg>(&plain).unwrap() {
                ServerMsg::Response { id: got, result } if got == id => return result,
                ServerMsg::Error(e) => return Err(e),
                _ => {}
            }
        }
    }
}
