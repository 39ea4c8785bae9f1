//! Keeps `docs/wire-format.md` true: every byte block of the document is compared with what the
//! real encoder makes of the message it names.
//!
//! A block is marked by an HTML comment naming it, `<!-- wire: NAME -->` (or
//! `<!-- wire: NAME prefix -->` when the block shows only the first bytes of a long message),
//! followed by a fenced block whose lines are hex bytes, each line optionally ending in a
//! `# comment`. The bytes are a whole frame: the 4-byte little-endian length, then the postcard
//! body (`<!-- wire: NAME sealed -->`: then the sealed body, which is not postcard). The Noise
//! handshake of the examples uses fixed ephemeral keys, so its bytes are reproducible. Run with `WIRE_FORMAT_PRINT=1 -- --nocapture` to print every message's bytes.

use std::collections::BTreeMap;

use penelope_protocol::net::auth::{self, ClientHandshake};
use penelope_protocol::net::frame;
use penelope_protocol::proto::{
    Call, CallError, ClientHello, ClientMsg, CreatorCall, DEFAULT_MAX_FRAME, LinkBatch, LinkRecord,
    MAGIC, Method, OperatingStateMsg, PROTOCOL_VERSION, PoseMsg, ProtocolError, Reply, RobotMethod,
    Role, Security, ServerHello, ServerMsg, SetpointsMsg, StopReport, TelemetryBatch,
    TelemetryRecord, WireError, WrenchMsg,
};
use serde::Serialize;

/// The document, relative to this crate.
const DOC: &str = include_str!("../../docs/wire-format.md");

/// The ephemeral private keys of the example handshake: the client's bytes 0x00 to 0x1f, the
/// node's 0x20 to 0x3f (a real handshake draws them from the operating system).
fn example_ephemerals() -> ([u8; 32], [u8; 32]) {
    (
        std::array::from_fn(|i| i as u8),
        std::array::from_fn(|i| 0x20 + i as u8),
    )
}

/// The shared secret of the examples.
const EXAMPLE_SECRET: &[u8] = b"correct horse battery staple";

/// A telemetry record of a six-joint robot.
fn record(seq: u64) -> TelemetryRecord {
    TelemetryRecord {
        time_ns: 1_000_000 * seq,
        seq,
        q: vec![0.0, -0.5, 0.5, 0.0, 0.25, 0.0],
        qd: vec![0.0; 6],
        effort: vec![0.0, 12.5, -3.0, 0.0, 0.1, 0.0],
        tool_position: [0.5, 0.0, 0.25],
        wrench: WrenchMsg {
            force: [0.0, 0.0, -2.0],
            torque: [0.0; 3],
        },
        state: "active".into(),
        fault: None,
        commanded_wrench: WrenchMsg {
            force: [0.0; 3],
            torque: [0.0; 3],
        },
        clutch: None,
        port_energy: None,
        channel_energy: None,
    }
}

/// A link record of a channel linked to another node over loopback: up, 1,234 samples taken,
/// the other node's clock 2.5 µs ahead.
fn link_record() -> LinkRecord {
    LinkRecord {
        time_ns: 1_000_000_000,
        down: false,
        losses: 0,
        restorations: 0,
        samples_taken: 1234,
        samples_dropped: 0,
        samples_missed: 2,
        refused: 0,
        clock_offset_ns: Some(2500),
        round_trip_ns: Some(60_000),
        one_way_delay_ns: Some(30_000),
        jitter_ns: Some(1000),
        last_heard_ns: Some(400_000),
        heartbeat_loss: 0.0,
        trips: 1234,
        trip_p50_ns: Some(31_000),
        trip_p99_ns: Some(90_000),
        trip_max_ns: None,
    }
}

/// A frame as the real encoder makes it: the length, then the postcard body; checked against
/// [`frame::encode`].
fn framed<T: Serialize>(msg: &T) -> Vec<u8> {
    let body = postcard::to_stdvec(msg).expect("every example serializes");
    let mut bytes = u32::try_from(body.len())
        .expect("small")
        .to_le_bytes()
        .to_vec();
    bytes.extend_from_slice(&body);
    let encoded = frame::encode(msg, DEFAULT_MAX_FRAME).expect("the frame encoder accepts it");
    assert_eq!(
        encoded, bytes,
        "net::frame::encode disagrees with length + postcard"
    );
    bytes
}

/// Every message the document shows, by the name its block carries.
fn examples() -> BTreeMap<&'static str, Vec<u8>> {
    let mut m = BTreeMap::new();
    session_examples(&mut m);
    call_examples(&mut m);
    creator_examples(&mut m);
    crtk_examples(&mut m);
    m
}

/// The ping the examples send, plain and sealed.
fn ping() -> ClientMsg {
    ClientMsg::Request {
        id: 300,
        call: Call::Ping {
            payload: vec![0, 1, 2, 3, 4, 5, 6, 7],
        },
    }
}

/// A session's opening and closing: the hellos, the Noise handshake as both sides make it, the
/// first request sealed after it, a refused secret, and the goodbye.
fn session_examples(m: &mut BTreeMap<&'static str, Vec<u8>>) {
    let client_hello = ClientMsg::Hello(ClientHello::new("ctl", Role::Reader));
    m.insert("client-hello", framed(&client_hello));
    m.insert(
        "server-hello",
        framed(&ServerMsg::Hello(ServerHello {
            magic: MAGIC,
            version: PROTOCOL_VERSION,
            node: "lab-a".into(),
            security: Security::Plain,
        })),
    );
    let server_hello = ServerMsg::Hello(ServerHello {
        magic: MAGIC,
        version: PROTOCOL_VERSION,
        node: "lab-a".into(),
        security: Security::Noise { admin: false },
    });
    m.insert("server-hello-noise", framed(&server_hello));
    // The handshake, as both sides make it.
    let psk = auth::member_psk(EXAMPLE_SECRET);
    let prologue = auth::prologue(&framed(&client_hello)[4..], &framed(&server_hello)[4..]);
    let (e_client, e_node) = example_ephemerals();
    let (client, first) = ClientHandshake::start_for_test_vectors(&psk, &prologue, &e_client)
        .expect("the handshake starts");
    let (second, node_keys) = auth::answer_for_test_vectors(&psk, &prologue, &first, &e_node)
        .expect("the node accepts the client's first message");
    let client_keys = client
        .finish(&second)
        .expect("the client accepts the answer");
    m.insert(
        "client-handshake",
        framed(&ClientMsg::Handshake { noise: first }),
    );
    m.insert(
        "server-handshake",
        framed(&ServerMsg::Handshake { noise: second }),
    );
    // The first request after it, sealed; the node opens it back to the plain body.
    let (mut sealer, _) = client_keys.split();
    let (_, mut opener) = node_keys.split();
    let plain = framed(&ping());
    let mut sealed = Vec::new();
    sealer.seal_frames(&plain, &mut sealed).expect("seals");
    assert_eq!(
        opener.open(&sealed[4..]).expect("opens"),
        &plain[4..],
        "the node opens the sealed request"
    );
    m.insert("sealed-request-ping", sealed);
    m.insert(
        "server-auth-failed",
        framed(&ServerMsg::Error(WireError::Protocol(
            ProtocolError::AuthFailed,
        ))),
    );
    m.insert("client-bye", framed(&ClientMsg::Bye));
}

/// Calls to objects and their answers, errors, and the batches a subscription streams.
fn call_examples(m: &mut BTreeMap<&'static str, Vec<u8>>) {
    let pose = PoseMsg {
        position: [0.5, 0.0, 0.25],
        n: [1.0, 0.0, 0.0],
        o: [0.0, -1.0, 0.0],
        a: [0.0, 0.0, -1.0],
    };
    m.insert(
        "response-forbidden",
        framed(&ServerMsg::Response {
            id: 3,
            result: Err(WireError::Call(CallError::Forbidden(
                "node `lab-a` may unbind only under `/lab-a/`, not `/lab-b/sensors/ft`".into(),
            ))),
        }),
    );
    m.insert(
        "request-forward-kinematics",
        framed(&ClientMsg::Request {
            id: 1,
            call: Call::Object {
                object: "slave".into(),
                method: Method::Robot(RobotMethod::ForwardKinematics { q: None }),
            },
        }),
    );
    m.insert(
        "response-pose",
        framed(&ServerMsg::Response {
            id: 1,
            result: Ok(Reply::Pose(pose)),
        }),
    );
    m.insert(
        "response-unknown-name",
        framed(&ServerMsg::Response {
            id: 2,
            result: Err(WireError::Call(CallError::UnknownName("slave2".into()))),
        }),
    );
    m.insert("request-ping", framed(&ping()));
    m.insert(
        "telemetry-batch",
        framed(&ServerMsg::Telemetry(TelemetryBatch {
            subscription: 1,
            dropped: 0,
            samples: vec![record(1000), record(1001)],
            common_offset_ns: 0,
        })),
    );
    m.insert(
        "link-batch",
        framed(&ServerMsg::Link(LinkBatch {
            subscription: 2,
            dropped: 0,
            records: vec![link_record()],
        })),
    );
    m.insert(
        "response-no-link",
        framed(&ServerMsg::Response {
            id: 3,
            result: Err(WireError::Call(CallError::NoLink("link".into()))),
        }),
    );
    m.insert(
        "error-frame-too-large",
        framed(&ServerMsg::Error(WireError::Protocol(
            ProtocolError::FrameTooLarge {
                len: u64::from(u32::MAX),
                max: DEFAULT_MAX_FRAME as u64,
            },
        ))),
    );
}

/// Calls to a node's creator and their answers: recording, its clock, the node-wide e-stop
/// and a system file.
fn creator_examples(m: &mut BTreeMap<&'static str, Vec<u8>>) {
    m.insert(
        "request-record-start",
        framed(&ClientMsg::Request {
            id: 4,
            call: Call::Creator(CreatorCall::RecordStart {
                path: "run.mcap".into(),
                objects: vec!["follow".into()],
            }),
        }),
    );
    m.insert(
        "response-recorded",
        framed(&ServerMsg::Response {
            id: 4,
            result: Ok(Reply::Recorded {
                path: "run.mcap".into(),
                ticks: 1000,
            }),
        }),
    );
    m.insert(
        "request-time",
        framed(&ClientMsg::Request {
            id: 5,
            call: Call::Time,
        }),
    );
    m.insert(
        "response-time",
        framed(&ServerMsg::Response {
            id: 5,
            result: Ok(Reply::Time {
                received_ns: 1_000_000,
                sent_ns: 1_000_064,
            }),
        }),
    );
    m.insert(
        "request-estop",
        framed(&ClientMsg::Request {
            id: 6,
            call: Call::Creator(CreatorCall::EStop),
        }),
    );
    m.insert(
        "response-stopped",
        framed(&ServerMsg::Response {
            id: 6,
            result: Ok(Reply::Stopped(StopReport {
                node: "lab".into(),
                stopped: vec!["pid".into()],
                pending: vec![],
            })),
        }),
    );
    m.insert(
        "request-apply-system",
        framed(&ClientMsg::Request {
            id: 7,
            call: Call::Creator(CreatorCall::ApplySystem {
                text: "[boards.io]\nkind = \"sim\"\n".into(),
            }),
        }),
    );
}

/// The CRTK verbs: a joint move, a servo target, the setpoints and the operating state.
fn crtk_examples(m: &mut BTreeMap<&'static str, Vec<u8>>) {
    let robot = |id: u64, method: RobotMethod| {
        framed(&ClientMsg::Request {
            id,
            call: Call::Object {
                object: "slave".into(),
                method: Method::Robot(method),
            },
        })
    };
    m.insert(
        "request-move-joints",
        robot(
            8,
            RobotMethod::MoveJoints {
                q: vec![0.0, -0.5, 0.5],
                duration_s: 2.0,
            },
        ),
    );
    m.insert(
        "request-servo-joints",
        robot(
            9,
            RobotMethod::ServoJoints {
                q: vec![0.0, -0.5, 0.5],
            },
        ),
    );
    m.insert(
        "response-setpoints",
        framed(&ServerMsg::Response {
            id: 10,
            result: Ok(Reply::Setpoints(SetpointsMsg {
                time_ns: 1000,
                joints: Some(vec![0.0, 0.5]),
                pose: None,
            })),
        }),
    );
    m.insert(
        "request-operating-state",
        robot(11, RobotMethod::OperatingState),
    );
    m.insert(
        "response-operating-state",
        framed(&ServerMsg::Response {
            id: 11,
            result: Ok(Reply::OperatingState(OperatingStateMsg {
                state: "ENABLED".into(),
                is_homed: true,
                is_busy: true,
            })),
        }),
    );
}

/// One marked block of the document.
#[derive(Debug)]
struct Block {
    name: String,
    prefix: bool,
    /// The body is sealed (not postcard).
    sealed: bool,
    line: usize,
    bytes: Vec<u8>,
}

/// Every `<!-- wire: NAME [prefix|sealed] -->` block of `doc`.
fn blocks(doc: &str) -> Result<Vec<Block>, String> {
    let lines: Vec<&str> = doc.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let Some(marker) = lines[i]
            .trim()
            .strip_prefix("<!-- wire:")
            .and_then(|r| r.strip_suffix("-->"))
        else {
            i += 1;
            continue;
        };
        let mut words = marker.split_whitespace();
        let name = words
            .next()
            .ok_or(format!("line {}: marker without a name", i + 1))?;
        let (prefix, sealed) = match words.next() {
            None => (false, false),
            Some("prefix") => (true, false),
            Some("sealed") => (false, true),
            Some(other) => return Err(format!("line {}: unknown marker word {other:?}", i + 1)),
        };
        let start = i + 1;
        if !lines
            .get(start)
            .is_some_and(|l| l.trim_start().starts_with("```"))
        {
            return Err(format!(
                "line {}: a fenced block must follow the marker",
                i + 1
            ));
        }
        let mut bytes = Vec::new();
        let mut j = start + 1;
        loop {
            let Some(l) = lines.get(j) else {
                return Err(format!("line {}: unterminated block", start + 1));
            };
            if l.trim_start().starts_with("```") {
                break;
            }
            let data = l.split('#').next().unwrap_or("");
            for tok in data.split_whitespace() {
                let ok = tok.len() == 2 && tok.bytes().all(|b| b.is_ascii_hexdigit());
                let byte = u8::from_str_radix(tok, 16).ok().filter(|_| ok);
                bytes.push(byte.ok_or(format!("line {}: {tok:?} is not a hex byte", j + 1))?);
            }
            j += 1;
        }
        out.push(Block {
            name: name.to_string(),
            prefix,
            sealed,
            line: i + 1,
            bytes,
        });
        i = j + 1;
    }
    Ok(out)
}

fn hex(bytes: &[u8]) -> String {
    bytes
        .chunks(16)
        .map(|c| {
            c.iter()
                .map(|b| format!("{b:02x}"))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn every_byte_block_of_the_wire_format_document_is_what_the_encoder_makes() {
    let examples = examples();
    if std::env::var_os("WIRE_FORMAT_PRINT").is_some() {
        for (name, bytes) in &examples {
            println!("== {name} ({} bytes)\n{}", bytes.len(), hex(bytes));
        }
    }
    let blocks = blocks(DOC).unwrap();
    for b in &blocks {
        let expected = examples
            .get(b.name.as_str())
            .unwrap_or_else(|| panic!("line {}: no example named {:?}", b.line, b.name));
        let shown = if b.prefix {
            assert!(
                b.bytes.len() < expected.len(),
                "line {}: a prefix block shows the whole message",
                b.line
            );
            &expected[..b.bytes.len().min(expected.len())]
        } else {
            expected.as_slice()
        };
        assert_eq!(
            hex(&b.bytes),
            hex(shown),
            "docs/wire-format.md line {}: block {:?} differs from the encoder",
            b.line,
            b.name
        );
        // What the document shows also decodes back to a message.
        let body = &b.bytes[4.min(b.bytes.len())..];
        if !b.prefix && !b.sealed {
            let as_client = postcard::from_bytes::<ClientMsg>(body).is_ok();
            let as_server = postcard::from_bytes::<ServerMsg>(body).is_ok();
            assert!(
                as_client || as_server,
                "line {}: {:?} does not decode",
                b.line,
                b.name
            );
        }
    }
    // Every example appears in the document.
    for name in examples.keys() {
        assert!(
            blocks.iter().any(|b| b.name == *name),
            "docs/wire-format.md has no block for {name:?}"
        );
    }
}

#[test]
fn the_block_parser_refuses_what_it_cannot_read() {
    assert!(blocks("<!-- wire: x -->\nno fence").is_err());
    assert!(blocks("<!-- wire: x -->\n```text\n0g\n```").is_err());
    assert!(blocks("<!-- wire: x -->\n```text\n00 01").is_err());
    assert!(blocks("<!-- wire: x whatever -->\n```text\n00\n```").is_err());
    let ok =
        blocks("text\n<!-- wire: x prefix -->\n```text\n0a 0B  # ten, eleven 99\n```\n").unwrap();
    assert_eq!(ok.len(), 1);
    assert_eq!(
        (ok[0].name.as_str(), ok[0].prefix, ok[0].bytes.clone()),
        ("x", true, vec![10, 11])
    );
    assert!(blocks("<!-- wire: y sealed -->\n```text\n00\n```\n").unwrap()[0].sealed);
}
