//! Property tests of the frame layer: messages round-trip, the incremental decoder never panics
//! and stays bounded on arbitrary bytes in arbitrary chunkings, and a valid stream decodes the
//! same however it is split. Plus a seeded, bounded fuzz run of the decoder (what the cargo-fuzz
//! target `protocol/fuzz` explores without end).

use penelope_protocol::net::frame::{FrameDecoder, FrameError, encode, encode_into, read_frame};
use penelope_protocol::proto::{
    Call, CallError, ClientHello, ClientMsg, CreatorCall, FRAME_HEADER_LEN, Method, ProtocolError,
    Reply, RobotMethod, Role, Security, ServerHello, ServerMsg, TelemetryBatch, WireError,
};
use proptest::prelude::*;

fn noise() -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(any::<u8>(), 0..100)
}

fn role() -> impl Strategy<Value = Role> {
    prop_oneof![Just(Role::Reader), Just(Role::Node), Just(Role::Admin)]
}

fn security() -> impl Strategy<Value = Security> {
    prop_oneof![
        Just(Security::Plain),
        any::<bool>().prop_map(|admin| Security::Noise { admin }),
    ]
}

fn call() -> impl Strategy<Value = Call> {
    prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..300).prop_map(|payload| Call::Ping { payload }),
        Just(Call::NodeInfo),
        Just(Call::Creator(CreatorCall::Kinds)),
        (".{0,20}", ".{0,20}", ".{0,60}").prop_map(|(kind, name, config)| Call::Creator(
            CreatorCall::Create { kind, name, config }
        )),
        (".{0,20}", any::<bool>())
            .prop_map(|(name, force)| Call::Creator(CreatorCall::Destroy { name, force })),
        (
            ".{0,20}",
            proptest::option::of(proptest::collection::vec(-10.0f64..10.0, 0..7))
        )
            .prop_map(|(object, q)| Call::Object {
                object,
                method: Method::Robot(RobotMethod::ForwardKinematics { q }),
            }),
        (".{0,20}", any::<u32>())
            .prop_map(|(object, decimation)| Call::Subscribe { object, decimation }),
        any::<u64>().prop_map(|subscription| Call::Unsubscribe { subscription }),
    ]
}

fn client_msg() -> impl Strategy<Value = ClientMsg> {
    prop_oneof![
        (any::<[u8; 4]>(), any::<u16>(), ".{0,30}", role()).prop_map(
            |(magic, version, client, role)| {
                ClientMsg::Hello(ClientHello {
                    magic,
                    version,
                    client,
                    role,
                })
            }
        ),
        noise().prop_map(|noise| ClientMsg::Handshake { noise }),
        (any::<u64>(), call()).prop_map(|(id, call)| ClientMsg::Request { id, call }),
        Just(ClientMsg::Bye),
    ]
}

fn wire_error() -> impl Strategy<Value = WireError> {
    prop_oneof![
        ".{0,40}".prop_map(|m| WireError::Protocol(ProtocolError::Malformed(m))),
        (any::<u64>(), any::<u64>())
            .prop_map(|(len, max)| WireError::Protocol(ProtocolError::FrameTooLarge { len, max })),
        Just(WireError::Protocol(ProtocolError::BadMagic)),
        Just(WireError::Protocol(ProtocolError::AuthFailed)),
        ".{0,40}".prop_map(|m| WireError::Call(CallError::Forbidden(m))),
        any::<u32>().prop_map(|limit| WireError::Protocol(ProtocolError::RateLimited { limit })),
        any::<u32>()
            .prop_map(|limit| WireError::Protocol(ProtocolError::TooManyConnections { limit })),
        ".{0,40}".prop_map(|m| WireError::Call(CallError::UnknownName(m))),
        (".{0,20}", proptest::collection::vec(".{0,10}", 0..4))
            .prop_map(|(name, dependents)| WireError::Call(CallError::InUse { name, dependents })),
    ]
}

fn server_msg() -> impl Strategy<Value = ServerMsg> {
    prop_oneof![
        (".{0,30}", security()).prop_map(|(node, security)| {
            ServerMsg::Hello(ServerHello {
                magic: *b"PNLP",
                version: 2,
                node,
                security,
            })
        }),
        noise().prop_map(|noise| ServerMsg::Handshake { noise }),
        (
            any::<u64>(),
            prop_oneof![
                proptest::collection::vec(any::<u8>(), 0..300).prop_map(|p| Ok(Reply::Pong(p))),
                Just(Ok(Reply::Unit)),
                wire_error().prop_map(Err),
            ]
        )
            .prop_map(|(id, result)| ServerMsg::Response { id, result }),
        (any::<u64>(), any::<u64>()).prop_map(|(subscription, dropped)| {
            ServerMsg::Telemetry(TelemetryBatch {
                subscription,
                dropped,
                samples: Vec::new(),
                common_offset_ns: -7,
            })
        }),
        wire_error().prop_map(ServerMsg::Error),
    ]
}

/// Feeds `bytes` to a decoder in chunks of the given sizes (cycled), taking every message out
/// after each push; checks the memory bound all along. Returns the messages, and the error that
/// stopped decoding if any.
fn feed<T: serde::de::DeserializeOwned>(
    bytes: &[u8],
    chunks: &[usize],
    max: usize,
) -> (Vec<T>, Option<FrameError>) {
    let mut d = FrameDecoder::new(max);
    let mut out = Vec::new();
    let mut at = 0;
    let mut i = 0;
    while at < bytes.len() {
        let want = chunks[i % chunks.len()].max(1);
        i += 1;
        let n = want.min(bytes.len() - at).min(d.free());
        if let Err(e) = d.push(&bytes[at..at + n]) {
            return (out, Some(e));
        }
        at += n;
        assert!(
            d.allocated() <= FRAME_HEADER_LEN + max,
            "decoder grew past its bound"
        );
        assert!(d.buffered() <= FRAME_HEADER_LEN + max);
        loop {
            match d.next::<T>() {
                Ok(Some(m)) => out.push(m),
                Ok(None) => break,
                Err(e) => return (out, Some(e)),
            }
        }
    }
    (out, None)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn client_messages_round_trip(m in client_msg()) {
        let bytes = encode(&m, 1 << 20).unwrap();
        prop_assert_eq!(read_frame::<_, ClientMsg>(&mut &bytes[..], 1 << 20).unwrap(), m);
    }

    #[test]
    fn server_messages_round_trip(m in server_msg()) {
        let bytes = encode(&m, 1 << 20).unwrap();
        prop_assert_eq!(read_frame::<_, ServerMsg>(&mut &bytes[..], 1 << 20).unwrap(), m);
    }

    #[test]
    fn arbitrary_bytes_never_panic_and_stay_bounded(
        bytes in proptest::collection::vec(any::<u8>(), 0..4096),
        chunks in proptest::collection::vec(1usize..600, 1..8),
        max in 0usize..2000,
    ) {
        let _ = feed::<ClientMsg>(&bytes, &chunks, max);
        let _ = feed::<ServerMsg>(&bytes, &chunks, max);
    }

    #[test]
    fn framed_garbage_is_malformed_never_a_panic(
        bodies in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..200), 1..6),
    ) {
        let mut bytes = Vec::new();
        for b in &bodies {
            bytes.extend((b.len() as u32).to_le_bytes());
            bytes.extend(b);
        }
        let (_, err) = feed::<ClientMsg>(&bytes, &[7, 300, 1], 1000);
        prop_assert!(matches!(err, None | Some(FrameError::Malformed(_))));
    }

    #[test]
    fn a_valid_stream_decodes_the_same_however_it_is_split(
        msgs in proptest::collection::vec(client_msg(), 1..20),
        chunks in proptest::collection::vec(1usize..100, 1..10),
    ) {
        let mut bytes = Vec::new();
        for m in &msgs {
            encode_into(m, 4096, &mut bytes).unwrap();
        }
        let (got, err) = feed::<ClientMsg>(&bytes, &chunks, 4096);
        prop_assert!(err.is_none(), "{:?}", err);
        prop_assert_eq!(got, msgs);
    }

    #[test]
    fn an_oversized_length_is_refused_on_its_header(
        len in 1001u32..,
        prefix in proptest::collection::vec(client_msg(), 0..3),
    ) {
        let mut bytes = Vec::new();
        for m in &prefix {
            encode_into(m, 1000, &mut bytes).unwrap_or(());
        }
        let good = prefix.iter().filter(|m| encode(*m, 1000).is_ok()).count();
        bytes.extend(len.to_le_bytes());
        let (got, err) = feed::<ClientMsg>(&bytes, &[3], 1000);
        prop_assert_eq!(got.len(), good);
        prop_assert!(
            matches!(err, Some(FrameError::TooLarge { len: l, max: 1000 }) if l == u64::from(len)),
            "{:?}", err
        );
    }
}

/// A small deterministic generator (xorshift), so the fuzz run is the same on every machine.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }
}

/// Mutates valid frames (flip, insert, delete, splice lengths) and feeds them in random chunks:
/// the decoder must only ever return messages or typed errors within its memory bound.
#[test]
fn seeded_fuzz_of_the_decoder() {
    let mut rng = Rng(0x5eed_1234_abcd_0001);
    let seeds: Vec<Vec<u8>> = [
        ClientMsg::Hello(ClientHello::new("fuzz", Role::Node)),
        ClientMsg::Handshake { noise: vec![9; 48] },
        ClientMsg::Request {
            id: 3,
            call: Call::Ping {
                payload: vec![1; 56],
            },
        },
        ClientMsg::Request {
            id: 4,
            call: Call::Object {
                object: "slave".into(),
                method: Method::Robot(RobotMethod::Jacobian {
                    q: Some(vec![0.1; 6]),
                }),
            },
        },
        ClientMsg::Bye,
    ]
    .iter()
    .map(|m| encode(m, 4096).unwrap())
    .collect();
    let (mut messages, mut errors) = (0u64, 0u64);
    let start = std::time::Instant::now();
    for _ in 0..20_000 {
        let mut bytes = Vec::new();
        for _ in 0..1 + rng.below(4) {
            bytes.extend(&seeds[rng.below(seeds.len() as u64) as usize]);
        }
        for _ in 0..rng.below(6) {
            let at = rng.below(bytes.len() as u64) as usize;
            match rng.below(5) {
                0 => bytes[at] ^= 1 << rng.below(8),
                1 => bytes[at] = rng.next() as u8,
                2 => bytes.insert(at, rng.next() as u8),
                3 => {
                    bytes.remove(at);
                    if bytes.is_empty() {
                        bytes.push(0);
                    }
                }
                _ => {
                    let len = (rng.next() as u32).to_le_bytes();
                    let end = (at + 4).min(bytes.len());
                    bytes.splice(at..end, len);
                }
            }
        }
        let chunks = [1 + rng.below(64) as usize, 1 + rng.below(8) as usize];
        let max = 16 + rng.below(300) as usize;
        let (got, err) = feed::<ClientMsg>(&bytes, &chunks, max);
        messages += got.len() as u64;
        errors += u64::from(err.is_some());
        assert!(!matches!(err, Some(FrameError::Overflow { .. })));
    }
    println!(
        "decoder fuzz: 20000 inputs, {messages} messages, {errors} typed errors, {:?}",
        start.elapsed()
    );
    assert!(
        messages > 0 && errors > 0,
        "the mutations must exercise both paths"
    );
}
