//! The client connection against a real server and against scripted nodes.

use std::net::TcpListener;
use std::sync::Arc;

use super::*;
use crate::net::frame::{read_frame, write_frame};
use crate::net::server::{Server, ServerConfig};
use crate::proto::{CallError, ProtocolError, ServerHello, TelemetryRecord};
use crate::service::{Service, Session};

struct Echo;

impl Service for Echo {
    fn call(&self, session: &Session, call: Call) -> Result<Reply, WireError> {
        match call {
            Call::Ping { payload } => Ok(Reply::Pong(payload)),
            Call::Unsubscribe { subscription } => {
                // A test hook: push that many empty batches first, telemetry and link records
                // in turn.
                for s in 0..subscription {
                    session.outbox.push(if s % 2 == 0 {
                        ServerMsg::Telemetry(TelemetryBatch {
                            subscription: s,
                            dropped: 0,
                            samples: Vec::<TelemetryRecord>::new(),
                            common_offset_ns: 0,
                        })
                    } else {
                        ServerMsg::Link(LinkBatch {
                            subscription: s,
                            dropped: 0,
                            records: Vec::new(),
                        })
                    });
                }
                Ok(Reply::Unit)
            }
            _ => Err(WireError::Call(CallError::NotReady("echo only".into()))),
        }
    }
}

fn server(secret: Option<&[u8]>) -> Server {
    let mut c = ServerConfig::new("unit");
    c.secret = secret.map(Into::into);
    Server::bind("127.0.0.1:0".parse().unwrap(), c, Arc::new(Echo)).unwrap()
}

#[test]
fn calls_pipelines_and_telemetry_over_a_real_server() {
    let s = server(None);
    let mut c = Connection::connect(s.local_addr(), &ClientConfig::new("t")).unwrap();
    assert_eq!(c.node(), "unit");
    assert_eq!(
        c.call(Call::Ping {
            payload: vec![1, 2]
        })
        .unwrap(),
        Reply::Pong(vec![1, 2])
    );
    assert!(matches!(
        c.call(Call::NodeInfo),
        Err(RpcError::Remote(WireError::Call(CallError::NotReady(_))))
    ));
    let calls = (0..2000u32)
        .map(|i| Call::Ping {
            payload: i.to_le_bytes().to_vec(),
        })
        .collect();
    let replies = c.call_many(calls).unwrap();
    assert_eq!(replies.len(), 2000);
    assert_eq!(
        replies[1234],
        Ok(Reply::Pong(1234u32.to_le_bytes().to_vec()))
    );
    assert_eq!(
        c.call(Call::Unsubscribe { subscription: 3 }).unwrap(),
        Reply::Unit
    );
    let mut subs = Vec::new();
    while let Some(b) = c.next_pushed(Duration::from_millis(300)).unwrap() {
        subs.push((b.subscription(), matches!(b, Pushed::Link(_))));
    }
    assert_eq!(subs, [(0, false), (1, true), (2, false)]);
    assert!(c.call_many(Vec::new()).unwrap().is_empty());
    drop(c);
    s.shutdown();
}

#[test]
fn the_secret_is_required_and_checked() {
    let s = server(Some(b"0123456789abcdef0123456789abcdef"));
    let mut cfg = ClientConfig::new("t");
    assert!(matches!(
        Connection::connect(s.local_addr(), &cfg),
        Err(RpcError::Remote(WireError::Protocol(
            ProtocolError::AuthFailed
        )))
    ));
    cfg.secret = Some(b"wrong".into());
    assert!(matches!(
        Connection::connect(s.local_addr(), &cfg),
        Err(RpcError::Remote(WireError::Protocol(
            ProtocolError::AuthFailed
        )))
    ));
    cfg.secret = Some(b"0123456789abcdef0123456789abcdef".into());
    let mut c = Connection::connect(s.local_addr(), &cfg).unwrap();
    assert_eq!(
        c.call(Call::Ping { payload: vec![] }).unwrap(),
        Reply::Pong(vec![])
    );
    assert_eq!(s.stats().auth_failures, 2);
    drop(c);
    s.shutdown();
}

/// A scripted node: answers the hello, then whatever `script` writes.
fn fake_node(script: impl FnOnce(&mut TcpStream) + Send + 'static) -> SocketAddr {
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = l.local_addr().unwrap();
    std::thread::spawn(move || {
        let (mut s, _) = l.accept().unwrap();
        let _: ClientMsg = read_frame(&mut s, 1000).unwrap();
        let hello = ServerMsg::Hello(ServerHello {
            magic: MAGIC,
            version: PROTOCOL_VERSION,
            node: "fake".into(),
            security: Security::Plain,
        });
        write_frame(&mut s, &hello, 1000).unwrap();
        script(&mut s);
        std::thread::sleep(Duration::from_millis(200));
    });
    addr
}

#[test]
fn wrong_ids_errors_garbage_and_silence_are_typed_errors() {
    let mut cfg = ClientConfig::new("t");
    cfg.timeout = Duration::from_millis(300);
    let addr = fake_node(|s| {
        let _: ClientMsg = read_frame(s, 1000).unwrap();
        let r = ServerMsg::Response {
            id: 99,
            result: Ok(Reply::Unit),
        };
        write_frame(s, &r, 1000).unwrap();
    });
    let mut c = Connection::connect(addr, &cfg).unwrap();
    assert!(matches!(c.call(Call::NodeInfo), Err(RpcError::Protocol(_))));
    assert!(!c.is_usable());
    assert!(matches!(c.call(Call::NodeInfo), Err(RpcError::Protocol(_))));

    let addr = fake_node(|s| {
        let e = ServerMsg::Error(WireError::Protocol(ProtocolError::RateLimited { limit: 1 }));
        write_frame(s, &e, 1000).unwrap();
    });
    let mut c = Connection::connect(addr, &cfg).unwrap();
    assert!(matches!(
        c.call(Call::NodeInfo),
        Err(RpcError::Remote(WireError::Protocol(
            ProtocolError::RateLimited { limit: 1 }
        )))
    ));

    let addr = fake_node(|s| s.write_all(&[3, 0, 0, 0, 0xff, 0xff, 0xff]).unwrap());
    let mut c = Connection::connect(addr, &cfg).unwrap();
    assert!(matches!(
        c.call(Call::NodeInfo),
        Err(RpcError::Frame(FrameError::Malformed(_)))
    ));

    let addr = fake_node(|_| {});
    cfg.timeout = Duration::from_millis(100);
    let mut c = Connection::connect(addr, &cfg).unwrap();
    assert!(matches!(c.call(Call::NodeInfo), Err(RpcError::Timeout)));
    assert!(c.next_pushed(Duration::from_millis(10)).unwrap().is_none());
}

#[test]
fn a_late_answer_of_a_timed_out_call_is_skipped() {
    let mut cfg = ClientConfig::new("t");
    cfg.timeout = Duration::from_millis(200);
    let addr = fake_node(|s| {
        let _: ClientMsg = read_frame(s, 1000).unwrap();
        std::thread::sleep(Duration::from_millis(400));
        write_frame(
            s,
            &ServerMsg::Response {
                id: 1,
                result: Ok(Reply::Unit),
            },
            1000,
        )
        .unwrap();
        let _: ClientMsg = read_frame(s, 1000).unwrap();
        let r = ServerMsg::Response {
            id: 2,
            result: Ok(Reply::Pong(vec![7])),
        };
        write_frame(s, &r, 1000).unwrap();
    });
    let mut c = Connection::connect(addr, &cfg).unwrap();
    assert!(matches!(c.call(Call::NodeInfo), Err(RpcError::Timeout)));
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(c.call(Call::NodeInfo).unwrap(), Reply::Pong(vec![7]));
}
