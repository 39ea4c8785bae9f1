//! The Foxglove WebSocket protocol (`foxglove.websocket.v1`, which Foxglove's SDK also serves
//! under the name `foxglove.sdk.v1`): the JSON operations and binary frames this server sends
//! and the client requests it takes. Pure data, no I/O: every encoding and parse is tested here.
//!
//! Server to client: `serverInfo`, `status`, `advertise`, `unadvertise`, `advertiseServices`,
//! `serviceCallFailure` (JSON text), and binary message data (opcode 1), time (2) and service
//! call responses (3), little-endian. Client to server: `subscribe`, `unsubscribe` (JSON) and
//! binary service call requests (opcode 2); anything else is answered with a `status` warning.

use serde::Serialize;
use serde_json::{Value, json};

/// The WebSocket subprotocols served, in order of preference: the protocol's own name, and the
/// name Foxglove's SDK gives the same messages (newer Foxglove and Lichtblick offer either).
pub const SUBPROTOCOLS: [&str; 2] = ["foxglove.websocket.v1", "foxglove.sdk.v1"];

/// Binary opcode of a message on a subscription (server to client).
pub const OP_MESSAGE_DATA: u8 = 0x01;
/// Binary opcode of the server's time (server to client).
pub const OP_TIME: u8 = 0x02;
/// Binary opcode of a service call's response (server to client).
pub const OP_SERVICE_CALL_RESPONSE: u8 = 0x03;
/// Binary opcode of a service call request (client to server).
pub const OP_SERVICE_CALL_REQUEST: u8 = 0x02;

/// A channel as advertised: one topic, its JSON messages and their JSON Schema.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct ChannelAd {
    /// The server's id of the channel.
    pub id: u32,
    /// The topic (`/tf`, `/controllers/follow`, ...).
    pub topic: String,
    /// The messages' encoding: always `json`.
    pub encoding: &'static str,
    /// The schema's name (`foxglove.FrameTransforms`, `penelope.Tick`, ...).
    pub schema_name: String,
    /// The JSON Schema text.
    pub schema: String,
    /// Always `jsonschema`.
    pub schema_encoding: &'static str,
}

impl ChannelAd {
    /// A channel of JSON messages described by the JSON Schema `schema`.
    pub fn json(id: u32, topic: &str, schema_name: &str, schema: &str) -> Self {
        ChannelAd {
            id,
            topic: topic.to_string(),
            encoding: "json",
            schema_name: schema_name.to_string(),
            schema: schema.to_string(),
            schema_encoding: "jsonschema",
        }
    }
}

/// A service as advertised: JSON request and response, each with its JSON Schema.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ServiceAd {
    /// The server's id of the service.
    pub id: u32,
    /// Its name (`/penelope/estop`).
    pub name: String,
    /// Its type (`penelope.EStop`).
    pub kind: String,
    /// The request's schema name and JSON Schema.
    pub request: (String, String),
    /// The response's schema name and JSON Schema.
    pub response: (String, String),
}

/// `serverInfo`: the first message on a connection.
pub fn server_info(name: &str, session_id: &str, services: bool) -> String {
    let mut capabilities = vec!["time"];
    if services {
        capabilities.push("services");
    }
    json!({
        "op": "serverInfo",
        "name": name,
        "capabilities": capabilities,
        "supportedEncodings": ["json"],
        "metadata": {},
        "sessionId": session_id,
    })
    .to_string()
}

/// Status levels of a `status` message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// Information.
    Info = 0,
    /// Something the client asked for was not done.
    Warning = 1,
    /// Something failed.
    Error = 2,
}

/// `status`: a message for the person at the client.
pub fn status(level: Level, message: &str) -> String {
    json!({ "op": "status", "level": level as u8, "message": message }).to_string()
}

/// `advertise`: channels now served.
pub fn advertise(channels: &[ChannelAd]) -> String {
    json!({ "op": "advertise", "channels": channels }).to_string()
}

/// `unadvertise`: channels no longer served.
pub fn unadvertise(ids: &[u32]) -> String {
    json!({ "op": "unadvertise", "channelIds": ids }).to_string()
}

/// `advertiseServices`, in both the current form (`request`/`response` objects) and the
/// earlier one (`requestSchema`/`responseSchema` text), so either kind of client reads it.
pub fn advertise_services(services: &[ServiceAd]) -> String {
    let part = |(name, schema): &(String, String)| json!({ "encoding": "json", "schemaName": name, "schemaEncoding": "jsonschema", "schema": schema });
    let services: Vec<Value> = services
        .iter()
        .map(|s| {
            json!({
                "id": s.id, "name": s.name, "type": s.kind,
                "request": part(&s.request), "response": part(&s.response),
                "requestSchema": s.request.1, "responseSchema": s.response.1,
            })
        })
        .collect();
    json!({ "op": "advertiseServices", "services": services }).to_string()
}

/// `serviceCallFailure`.
pub fn service_call_failure(service_id: u32, call_id: u32, message: &str) -> String {
    json!({ "op": "serviceCallFailure", "serviceId": service_id, "callId": call_id, "message": message })
        .to_string()
}

/// Binary message data: `subscription`'s message logged at `time_ns`.
pub fn message_data(subscription: u32, time_ns: u64, payload: &[u8]) -> Vec<u8> {
    let mut frame = Vec::with_capacity(13 + payload.len());
    frame.push(OP_MESSAGE_DATA);
    frame.extend_from_slice(&subscription.to_le_bytes());
    frame.extend_from_slice(&time_ns.to_le_bytes());
    frame.extend_from_slice(payload);
    frame
}

/// Binary time: the server's clock now, ns.
pub fn time(time_ns: u64) -> Vec<u8> {
    let mut frame = Vec::with_capacity(9);
    frame.push(OP_TIME);
    frame.extend_from_slice(&time_ns.to_le_bytes());
    frame
}

/// Binary service call response, JSON encoded.
pub fn service_call_response(service_id: u32, call_id: u32, payload: &[u8]) -> Vec<u8> {
    let encoding = b"json";
    let mut frame = Vec::with_capacity(13 + encoding.len() + payload.len());
    frame.push(OP_SERVICE_CALL_RESPONSE);
    frame.extend_from_slice(&service_id.to_le_bytes());
    frame.extend_from_slice(&call_id.to_le_bytes());
    frame.extend_from_slice(&(encoding.len() as u32).to_le_bytes());
    frame.extend_from_slice(encoding);
    frame.extend_from_slice(payload);
    frame
}

/// A request of a client.
#[derive(Clone, Debug, PartialEq)]
pub enum ClientOp {
    /// Subscribe: `(subscription id, channel id)` pairs.
    Subscribe(Vec<(u32, u32)>),
    /// Unsubscribe these subscription ids.
    Unsubscribe(Vec<u32>),
    /// Call a service.
    ServiceCall {
        /// The service's id.
        service_id: u32,
        /// The client's id of the call (echoed in the answer).
        call_id: u32,
        /// The request's encoding.
        encoding: String,
        /// The request.
        payload: Vec<u8>,
    },
    /// An operation this server does not offer (client publishing, parameters, ...): its name.
    Unsupported(String),
}

/// Why a client's message was not understood.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ParseError {
    /// Not JSON, or not an object with a string `op`.
    #[error("not a Foxglove operation: {0}")]
    NotAnOperation(String),
    /// An operation missing a field or with a field of the wrong type.
    #[error("`{op}`: {reason}")]
    BadField {
        /// The operation.
        op: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// A binary frame too short for its opcode, or of an unknown opcode.
    #[error("binary frame: {0}")]
    BadFrame(&'static str),
}

/// Reads a text message of a client.
///
/// # Errors
/// [`ParseError`] for anything that is not a well-formed operation.
pub fn parse_text(text: &str) -> Result<ClientOp, ParseError> {
    let value: Value = serde_json::from_str(text)
        .map_err(|e| ParseError::NotAnOperation(e.to_string().chars().take(120).collect()))?;
    let op = value
        .get("op")
        .and_then(Value::as_str)
        .ok_or_else(|| ParseError::NotAnOperation("no string `op`".into()))?;
    let bad = |reason| ParseError::BadField {
        op: op.to_string(),
        reason,
    };
    let id = |v: &Value, key: &str| -> Option<u32> {
        v.get(key)
            .and_then(Value::as_u64)
            .and_then(|n| u32::try_from(n).ok())
    };
    match op {
        "subscribe" => {
            let list = value
                .get("subscriptions")
                .and_then(Value::as_array)
                .ok_or_else(|| bad("`subscriptions` must be an array"))?;
            list.iter()
                .map(|s| match (id(s, "id"), id(s, "channelId")) {
                    (Some(sub), Some(channel)) => Ok((sub, channel)),
                    _ => Err(bad("each subscription needs integer `id` and `channelId`")),
                })
                .collect::<Result<_, _>>()
                .map(ClientOp::Subscribe)
        }
        "unsubscribe" => {
            let list = value
                .get("subscriptionIds")
                .and_then(Value::as_array)
                .ok_or_else(|| bad("`subscriptionIds` must be an array"))?;
            list.iter()
                .map(|v| {
                    v.as_u64()
                        .and_then(|n| u32::try_from(n).ok())
                        .ok_or_else(|| bad("subscription ids are integers"))
                })
                .collect::<Result<_, _>>()
                .map(ClientOp::Unsubscribe)
        }
        other => Ok(ClientOp::Unsupported(other.chars().take(60).collect())),
    }
}

/// Reads a binary message of a client.
///
/// # Errors
/// [`ParseError::BadFrame`] for a truncated frame or an opcode of no request.
pub fn parse_binary(frame: &[u8]) -> Result<ClientOp, ParseError> {
    let (&opcode, rest) = frame.split_first().ok_or(ParseError::BadFrame("empty"))?;
    match opcode {
        OP_SERVICE_CALL_REQUEST => {
            let word = |at: usize| -> Result<u32, ParseError> {
                rest.get(at..at + 4)
                    .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .ok_or(ParseError::BadFrame("service call request too short"))
            };
            let service_id = word(0)?;
            let call_id = word(4)?;
            let length = word(8)? as usize;
            let encoding =
                rest.get(12..12usize.saturating_add(length))
                    .ok_or(ParseError::BadFrame(
                        "service call encoding past the frame's end",
                    ))?;
            Ok(ClientOp::ServiceCall {
                service_id,
                call_id,
                encoding: String::from_utf8_lossy(encoding).into_owned(),
                payload: rest[12 + length..].to_vec(),
            })
        }
        0x01 => Ok(ClientOp::Unsupported("client message data".into())),
        _ => Err(ParseError::BadFrame("unknown opcode")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn message_data_is_opcode_subscription_time_and_payload_little_endian() {
        let f = message_data(7, 0x0102_0304_0506_0708, b"{}");
        assert_eq!(f[0], 1);
        assert_eq!(&f[1..5], &[7, 0, 0, 0]);
        assert_eq!(&f[5..13], &[8, 7, 6, 5, 4, 3, 2, 1]);
        assert_eq!(&f[13..], b"{}");
        assert_eq!(time(5), vec![2, 5, 0, 0, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn a_service_call_request_reads_back_and_its_response_has_the_layout_of_the_spec() {
        let mut req = vec![OP_SERVICE_CALL_REQUEST];
        req.extend_from_slice(&3u32.to_le_bytes());
        req.extend_from_slice(&9u32.to_le_bytes());
        req.extend_from_slice(&4u32.to_le_bytes());
        req.extend_from_slice(b"json{\"a\":1}");
        assert_eq!(
            parse_binary(&req).unwrap(),
            ClientOp::ServiceCall {
                service_id: 3,
                call_id: 9,
                encoding: "json".into(),
                payload: b"{\"a\":1}".to_vec()
            }
        );
        // Truncated anywhere: an error, never a panic.
        for n in 0..req.len() - 7 {
            assert!(parse_binary(&req[..n]).is_err(), "{n} bytes");
        }
        let r = service_call_response(3, 9, b"{}");
        assert_eq!(r[0], 3);
        assert_eq!(&r[1..5], &3u32.to_le_bytes());
        assert_eq!(&r[5..9], &9u32.to_le_bytes());
        assert_eq!(&r[9..13], &4u32.to_le_bytes());
        assert_eq!(&r[13..17], b"json");
        assert_eq!(&r[17..], b"{}");
    }

    #[test]
    fn subscribe_and_unsubscribe_parse_and_malformed_ones_are_typed_errors() {
        assert_eq!(
            parse_text(r#"{"op":"subscribe","subscriptions":[{"id":1,"channelId":4}]}"#),
            Ok(ClientOp::Subscribe(vec![(1, 4)]))
        );
        assert_eq!(
            parse_text(r#"{"op":"unsubscribe","subscriptionIds":[1,2]}"#),
            Ok(ClientOp::Unsubscribe(vec![1, 2]))
        );
        assert_eq!(
            parse_text(r#"{"op":"getParameters","parameterNames":[]}"#),
            Ok(ClientOp::Unsupported("getParameters".into()))
        );
        assert!(matches!(
            parse_text(r#"{"op":"subscribe","subscriptions":[{"id":-1,"channelId":4}]}"#),
            Err(ParseError::BadField { .. })
        ));
        assert!(matches!(
            parse_text("not json"),
            Err(ParseError::NotAnOperation(_))
        ));
        assert!(matches!(
            parse_text(r#"{"op":3}"#),
            Err(ParseError::NotAnOperation(_))
        ));
    }

    #[test]
    fn advertisements_carry_the_fields_clients_read() {
        let ad: Value = serde_json::from_str(&advertise(&[ChannelAd::json(
            1,
            "/tf",
            "foxglove.FrameTransforms",
            "{}",
        )]))
        .unwrap();
        let c = &ad["channels"][0];
        assert_eq!(ad["op"], "advertise");
        assert_eq!(c["id"], 1);
        assert_eq!(c["topic"], "/tf");
        assert_eq!(c["encoding"], "json");
        assert_eq!(c["schemaName"], "foxglove.FrameTransforms");
        assert_eq!(c["schemaEncoding"], "jsonschema");
        let s: Value = serde_json::from_str(&advertise_services(&[ServiceAd {
            id: 2,
            name: "/penelope/estop".into(),
            kind: "penelope.EStop".into(),
            request: ("penelope.EStopRequest".into(), "{}".into()),
            response: ("penelope.EStopReply".into(), "{}".into()),
        }]))
        .unwrap();
        assert_eq!(s["services"][0]["request"]["encoding"], "json");
        assert_eq!(s["services"][0]["type"], "penelope.EStop");
        let info: Value = serde_json::from_str(&server_info("p", "s", true)).unwrap();
        assert_eq!(info["capabilities"], json!(["time", "services"]));
    }
}
