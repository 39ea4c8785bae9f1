//! Unit tests of the server.

use super::*;
use crate::net::frame::{read_frame, write_frame};
use crate::proto::{
    Call, CallError, ClientHello, DEFAULT_MAX_FRAME, Reply, Role, Security, ServerHello,
};

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

#[test]
fn a_non_loopback_bind_needs_a_secret() {
    let any: SocketAddr = "0.0.0.0:0".parse().unwrap();
    let e = Server::bind(any, ServerConfig::new("n"), Arc::new(Echo)).unwrap_err();
    assert!(matches!(e, NetError::SecretRequired(_)), "{e}");
    let mut c = ServerConfig::new("n");
    c.secret = Some(Vec::new().into());
    assert!(matches!(
        Server::bind(any, c, Arc::new(Echo)),
        Err(NetError::SecretRequired(_))
    ));
    let mut c = ServerConfig::new("n");
    c.admin_secret = Some(b"admin".into());
    assert!(matches!(
        Server::bind(local(), c, Arc::new(Echo)),
        Err(NetError::AdminSecretWithoutSecret)
    ));
    // A short secret is refused, saying how to make one; so is a short admin secret.
    let mut c = ServerConfig::new("n");
    c.secret = Some(b"ab".into());
    let e = Server::bind(local(), c, Arc::new(Echo)).unwrap_err();
    assert!(matches!(e, NetError::WeakSecret(_)), "{e}");
    assert!(e.to_string().contains("penelope secret new"), "{e}");
    let mut c = ServerConfig::new("n");
    c.secret = Some(b"0123456789abcdef0123456789abcdef".into());
    c.admin_secret = Some(b"admin".into());
    let e = Server::bind(local(), c, Arc::new(Echo)).unwrap_err();
    assert!(matches!(e, NetError::WeakSecret(_)), "{e}");
    assert!(e.to_string().contains("admin secret is too weak"), "{e}");
}

#[test]
fn hello_then_pipelined_requests_are_answered_in_order() {
    let server = Server::bind(local(), ServerConfig::new("unit"), Arc::new(Echo)).unwrap();
    let mut s = TcpStream::connect(server.local_addr()).unwrap();
    let max = DEFAULT_MAX_FRAME;
    let mut batch = Vec::new();
    encode_into(
        &ClientMsg::Hello(ClientHello::new("t", Role::Reader)),
        max,
        &mut batch,
    )
    .unwrap();
    for id in 0..50u64 {
        let call = Call::Ping {
            payload: vec![id as u8; id as usize],
        };
        encode_into(&ClientMsg::Request { id, call }, max, &mut batch).unwrap();
    }
    s.write_all(&batch).unwrap();
    let hello: ServerMsg = read_frame(&mut s, max).unwrap();
    assert!(
        matches!(hello, ServerMsg::Hello(ServerHello { ref node, security: Security::Plain, .. }) if node == "unit")
    );
    for id in 0..50u64 {
        let r: ServerMsg = read_frame(&mut s, max).unwrap();
        assert_eq!(
            r,
            ServerMsg::Response {
                id,
                result: Ok(Reply::Pong(vec![id as u8; id as usize]))
            }
        );
    }
    write_frame(&mut s, &ClientMsg::Bye, max).unwrap();
    assert!(matches!(
        read_frame::<_, ServerMsg>(&mut s, max),
        Err(FrameError::Closed)
    ));
    let st = server.stats();
    assert_eq!(st.requests, 50);
    assert_eq!(st.accepted, 1);
    server.shutdown();
}
