//! The topics served and their messages, named as in the recordings (`docs/recording.md`) so
//! that a Foxglove layout made for a recording works live: `/controllers/<name>`
//! (`penelope.Tick`), `/links/<channel>` (`penelope.LinkStats`), and the gateway's own
//! `/penelope/gateway` (`penelope.GatewayStats`: what it and its clients lost).
//!
//! A live tick is the part of a recorded tick the protocol carries ([`TelemetryRecord`]), in
//! the recording's shape (`{"sample": {..}, "truth": null}`), so its plot paths are the
//! recording's (`/controllers/follow.sample.q[0]`); the plant's truth is not on the wire.

use penelope_protocol::proto::{LinkRecord, TelemetryRecord};
use serde::Serialize;
use serde_json::{Value, json};

use crate::hub::ClientStats;

/// The topic prefix of controllers' ticks.
pub const CONTROLLER_TOPIC: &str = "/controllers/";
/// The topic prefix of links' statistics.
pub const LINK_TOPIC: &str = "/links/";
/// The gateway's own counters.
pub const GATEWAY_TOPIC: &str = "/penelope/gateway";
/// The e-stop service's name.
pub const ESTOP_SERVICE: &str = "/penelope/estop";

/// `penelope.Tick` as the live stream fills it.
pub const TICK_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.Tick","description":"One control tick as the protocol carries it (TelemetryRecord), in the shape of a recorded tick: sample holds what the loop reported; truth (the simulated plant's) is not sent live and is null. Units: SI (rad, rad/s, N·m, m, N); time in ns on the node's clock.","type":"object","properties":{"sample":{"type":"object","properties":{"time":{"type":"integer","description":"the tick's instant, ns on the node's clock"},"seq":{"type":"integer","description":"tick counter of the loop"},"q":{"type":"array","items":{"type":"number"}},"qd":{"type":"array","items":{"type":"number"}},"effort":{"type":"array","items":{"type":"number"}},"tool_position":{"type":"array","items":{"type":"number"},"minItems":3,"maxItems":3},"wrench":{"type":"object","properties":{"force":{"type":"array","items":{"type":"number"}},"torque":{"type":"array","items":{"type":"number"}}},"required":["force","torque"]},"commanded_wrench":{"type":"object","description":"the wrench the loop commanded after its caps: a master's displayed force","properties":{"force":{"type":"array","items":{"type":"number"}},"torque":{"type":"array","items":{"type":"number"}}},"required":["force","torque"]},"state":{"type":"string","description":"safety state after the tick"},"fault":{"description":"the latched fault's cause, null when none"},"port_energy":{"type":["number","null"],"description":"the law's passivity observer energy, J"},"channel_energy":{"type":["number","null"],"description":"the two-port's energy at this side, J"}},"required":["time","seq","q","qd","effort","state"]},"truth":{"type":"null"},"clutch":{"type":["boolean","null"],"description":"the operator held the clutch (null: no hand holds this robot)"}},"required":["sample","truth"]}"#;

/// `penelope.LinkStats`: a [`LinkRecord`] as the protocol has it (as in the recordings).
pub const LINK_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.LinkStats","description":"One end's view of a data-plane link (LinkRecord in docs/wire-format.md); times in ns.","type":"object","properties":{"time_ns":{"type":"integer"},"down":{"type":"boolean"},"losses":{"type":"integer"},"restorations":{"type":"integer"},"samples_taken":{"type":"integer"},"samples_dropped":{"type":"integer"},"samples_missed":{"type":"integer"},"refused":{"type":"integer"},"clock_offset_ns":{"type":["integer","null"]},"round_trip_ns":{"type":["integer","null"]},"one_way_delay_ns":{"type":["integer","null"]},"jitter_ns":{"type":["integer","null"]},"last_heard_ns":{"type":["integer","null"]},"heartbeat_loss":{"type":"number"},"trips":{"type":"integer"},"trip_p50_ns":{"type":["integer","null"]},"trip_p99_ns":{"type":["integer","null"]},"trip_max_ns":{"type":["integer","null"]}},"required":["time_ns","down"]}"#;

/// `penelope.GatewayStats`.
pub const GATEWAY_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.GatewayStats","description":"What penelope foxglove and its clients lost, every second: per client, data frames dropped because it read too slowly; per stream from a node, batches the node dropped because the gateway read too slowly, and messages published.","type":"object","properties":{"clients":{"type":"array","items":{"type":"object","properties":{"id":{"type":"integer"},"address":{"type":"string"},"subscriptions":{"type":"integer"},"queued":{"type":"integer"},"dropped":{"type":"integer"}}}},"evicted_clients":{"type":"integer","description":"clients disconnected for not reading their control messages"},"streams":{"type":"array","items":{"type":"object","properties":{"topic":{"type":"string"},"node_dropped":{"type":"integer"},"published":{"type":"integer"},"decimation":{"type":"integer"},"clock":{"type":"string"},"error":{"type":["string","null"]}}}}},"required":["clients","streams"]}"#;

/// The e-stop service's type.
pub const ESTOP_TYPE: &str = "penelope.EStop";
/// Its request: nothing to say.
pub const ESTOP_REQUEST_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.EStopRequest","description":"Latch the e-stop of every loop on every node (the web page's E-STOP). No fields.","type":"object"}"#;
/// Its answer.
pub const ESTOP_REPLY_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"penelope.EStopReply","description":"Per node, the controllers whose loops latched the e-stop (stopped) and those that had yet to tick (pending).","type":"object","properties":{"nodes":{"type":"array","items":{"type":"object","properties":{"node":{"type":"string"},"stopped":{"type":"array","items":{"type":"string"}},"pending":{"type":"array","items":{"type":"string"}}}}}},"required":["nodes"]}"#;

/// A tick as `/controllers/<name>` carries it.
pub fn tick(r: &TelemetryRecord) -> Value {
    json!({
        "sample": {
            "time": r.time_ns, "seq": r.seq, "q": r.q, "qd": r.qd, "effort": r.effort,
            "tool_position": r.tool_position,
            "wrench": { "force": r.wrench.force, "torque": r.wrench.torque },
            "commanded_wrench": {
                "force": r.commanded_wrench.force, "torque": r.commanded_wrench.torque,
            },
            "state": r.state, "fault": r.fault,
            "port_energy": r.port_energy, "channel_energy": r.channel_energy,
        },
        "truth": null,
        "clutch": r.clutch,
    })
}

/// A link record as `/links/<channel>` carries it.
pub fn link(r: &LinkRecord) -> Value {
    serde_json::to_value(r).unwrap_or(Value::Null)
}

/// One stream from a node, as `/penelope/gateway` reports it.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StreamStats {
    /// The topic it feeds.
    pub topic: String,
    /// Batches the node dropped because the gateway read too slowly.
    pub node_dropped: u64,
    /// Messages published.
    pub published: u64,
    /// The node's decimation of the subscription.
    pub decimation: u32,
    /// How its times become common times (`common`, `offset`, `simulated`, `unknown`).
    pub clock: &'static str,
    /// Why it is not streaming, if it is not.
    pub error: Option<String>,
}

/// A `/penelope/gateway` message.
pub fn gateway(clients: &[ClientStats], evicted: u64, streams: &[StreamStats]) -> Value {
    json!({ "clients": clients, "evicted_clients": evicted, "streams": streams })
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_protocol::proto::WrenchMsg;

    #[test]
    fn a_live_tick_has_the_recorded_ticks_plot_paths_and_the_schemas_are_json() {
        let r = TelemetryRecord {
            time_ns: 5,
            seq: 2,
            q: vec![0.1, 0.2],
            qd: vec![0.0, 0.0],
            effort: vec![1.0, 2.0],
            tool_position: [0.3, 0.0, 0.2],
            wrench: WrenchMsg {
                force: [0.0, 0.0, -1.5],
                torque: [0.0; 3],
            },
            state: "active".into(),
            fault: None,
            commanded_wrench: WrenchMsg {
                force: [0.0, 0.0, 0.75],
                torque: [0.0; 3],
            },
            clutch: Some(true),
            port_energy: None,
            channel_energy: Some(-0.25),
        };
        let t = tick(&r);
        assert_eq!(t["sample"]["q"][1], 0.2);
        assert_eq!(t["sample"]["wrench"]["force"][2], -1.5);
        assert_eq!(t["sample"]["time"], 5);
        assert!(t["truth"].is_null());
        assert_eq!(t["sample"]["commanded_wrench"]["force"][2], 0.75);
        assert_eq!(
            (
                t["clutch"].as_bool(),
                t["sample"]["channel_energy"].as_f64()
            ),
            (Some(true), Some(-0.25))
        );
        for schema in [
            TICK_SCHEMA,
            LINK_SCHEMA,
            GATEWAY_SCHEMA,
            ESTOP_REQUEST_SCHEMA,
            ESTOP_REPLY_SCHEMA,
        ] {
            let v: Value = serde_json::from_str(schema).unwrap();
            assert_eq!(v["type"], "object");
            assert!(v["title"].as_str().unwrap().starts_with("penelope."));
        }
        // Every field the schema requires of a sample is in the message.
        let schema: Value = serde_json::from_str(TICK_SCHEMA).unwrap();
        for key in schema["properties"]["sample"]["required"]
            .as_array()
            .unwrap()
        {
            assert!(!t["sample"][key.as_str().unwrap()].is_null(), "{key}");
        }
    }
}
