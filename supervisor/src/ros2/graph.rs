//! rmw_zenoh's graph format: what a ROS 2 node on Zenoh declares so that other ROS 2 nodes
//! (and `ros2 node list`, `ros2 topic list`, `ros2 topic echo`) find it, and the keys its
//! messages travel on. Text only: no Zenoh here, so the format is tested on any build.
//!
//! Followed: rmw_zenoh_cpp as released for ROS 2 Jazzy and Kilted (`docs/design.md`,
//! `liveliness_utils.cpp`, `qos.cpp`):
//!
//! - a message of topic `/<a>/<b>` of type `pkg/msg/T` in domain `d` is put on
//!   `d/<a>/<b>/pkg::msg::dds_::T_/RIHS01_<hash>` ([`topic_key`]);
//! - every entity holds a liveliness token
//!   `@ros2_lv/<d>/<zid>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node>[/<topic>/<type>/<hash>/<qos>]`
//!   with `/` in names written `%` ([`node_token`], [`endpoint_token`]); a node's token
//!   repeats its id;
//! - the QoS chunk lists reliability, durability, history and depth, deadline, lifespan and
//!   liveliness, each left empty where it equals rmw_zenoh's default ([`Qos::encode`]);
//! - an entity's GID (16 bytes, in every message's attachment) is XXH3-128 of its token, low
//!   64 bits then high, little-endian ([`gid`]).

use std::fmt::Write as _;

/// The key space of the liveliness tokens.
pub const ADMIN_SPACE: &str = "@ros2_lv";

/// What an entity is, as its token says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EntityKind {
    /// A node (`NN`).
    Node,
    /// A publisher (`MP`).
    Publisher,
    /// A subscription (`MS`).
    Subscription,
}

impl EntityKind {
    /// The token's two letters.
    pub fn code(self) -> &'static str {
        match self {
            EntityKind::Node => "NN",
            EntityKind::Publisher => "MP",
            EntityKind::Subscription => "MS",
        }
    }
}

/// A QoS reliability.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reliability {
    /// Every message arrives (rmw_zenoh's default).
    Reliable,
    /// A message may be dropped (ROS 2's sensor-data profile).
    BestEffort,
}

/// The QoS an endpoint declares: keep-last `depth`, volatile, the rest rmw_zenoh's defaults
/// (infinite deadline, lifespan and lease; automatic liveliness).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Qos {
    /// Reliability.
    pub reliability: Reliability,
    /// History depth (keep last).
    pub depth: u32,
}

/// rmw_zenoh's default history depth.
const DEFAULT_DEPTH: u32 = 42;

impl Qos {
    /// ROS 2's sensor-data profile: best effort, keep last 5.
    pub const SENSOR_DATA: Qos = Qos {
        reliability: Reliability::BestEffort,
        depth: 5,
    };
    /// ROS 2's default profile: reliable, keep last 10.
    pub const DEFAULT: Qos = Qos {
        reliability: Reliability::Reliable,
        depth: 10,
    };

    /// The token's QoS chunk:
    /// `<reliability>:<durability>:<history>,<depth>:<deadline s>,<ns>:<lifespan s>,<ns>:<liveliness>,<lease s>,<ns>`,
    /// a field empty where it is rmw_zenoh's default (reliable, volatile, keep last 42,
    /// infinite durations, automatic liveliness). ROS 2's enum values: best effort is 2.
    pub fn encode(&self) -> String {
        let reliability = match self.reliability {
            Reliability::Reliable => String::new(),
            Reliability::BestEffort => "2".into(),
        };
        let depth = if self.depth == DEFAULT_DEPTH {
            String::new()
        } else {
            self.depth.to_string()
        };
        format!("{reliability}::,{depth}:,:,:,,")
    }
}

/// `name` with every `/` written `%` (a token's chunks hold no `/`).
pub fn mangle(name: &str) -> String {
    name.replace('/', "%")
}

/// The DDS-style name rmw_zenoh puts in keys and tokens: `sensor_msgs/msg/JointState` →
/// `sensor_msgs::msg::dds_::JointState_`.
pub fn dds_type_name(type_name: &str) -> String {
    match type_name.rsplit_once('/') {
        Some((package, name)) => format!("{}::dds_::{name}_", package.replace('/', "::")),
        None => format!("{type_name}_"),
    }
}

/// The key a topic's messages are put on: `<domain>/<topic without its outer slashes>/<DDS
/// type name>/<type hash>`.
pub fn topic_key(domain_id: u32, topic: &str, type_name: &str, type_hash: &str) -> String {
    format!(
        "{domain_id}/{}/{}/{type_hash}",
        topic.trim_matches('/'),
        dds_type_name(type_name)
    )
}

/// Who a node is in the ROS graph.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeIdentity {
    /// `ROS_DOMAIN_ID`.
    pub domain_id: u32,
    /// The Zenoh session's id, as Zenoh prints it.
    pub zid: String,
    /// The node's id in its session.
    pub node_id: u32,
    /// The node's name (`penelope_<node>`).
    pub name: String,
    /// Its namespace (`/`).
    pub namespace: String,
    /// Its security enclave (`/`).
    pub enclave: String,
}

impl NodeIdentity {
    /// The token's chunks up to the node's name: admin space, domain, zid, node id, entity
    /// id, kind, enclave, namespace, name.
    fn prefix(&self, entity_id: u32, kind: EntityKind) -> String {
        format!(
            "{ADMIN_SPACE}/{}/{}/{}/{entity_id}/{}/{}/{}/{}",
            self.domain_id,
            self.zid,
            self.node_id,
            kind.code(),
            mangle(&self.enclave),
            mangle(&self.namespace),
            mangle(&self.name)
        )
    }
}

/// A node's liveliness token (its id repeated as the entity id).
pub fn node_token(node: &NodeIdentity) -> String {
    node.prefix(node.node_id, EntityKind::Node)
}

/// What a publisher or subscription carries.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Endpoint {
    /// The topic, `/puma/measured_js`.
    pub topic: String,
    /// The ROS type name, `sensor_msgs/msg/JointState`.
    pub type_name: String,
    /// Its RIHS01 hash.
    pub type_hash: String,
    /// Its QoS.
    pub qos: Qos,
}

/// A publisher's or subscription's liveliness token: the node's chunks, then topic, DDS type
/// name, hash and QoS.
pub fn endpoint_token(
    node: &NodeIdentity,
    entity_id: u32,
    kind: EntityKind,
    endpoint: &Endpoint,
) -> String {
    let mut token = node.prefix(entity_id, kind);
    let _ = write!(
        token,
        "/{}/{}/{}/{}",
        mangle(&endpoint.topic),
        mangle(&dds_type_name(&endpoint.type_name)),
        mangle(&endpoint.type_hash),
        endpoint.qos.encode()
    );
    token
}

/// The entity's GID: XXH3-128 of its liveliness token, the low 64 bits then the high 64,
/// each little-endian (as rmw_zenoh copies the hash's two halves into the GID).
pub fn gid(token: &str) -> [u8; 16] {
    let hash = xxhash_rust::xxh3::xxh3_128(token.as_bytes());
    let mut out = [0; 16];
    out[..8].copy_from_slice(&(hash as u64).to_le_bytes());
    out[8..].copy_from_slice(&((hash >> 64) as u64).to_le_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hash of `std_msgs/msg/String` in rmw_zenoh's design document.
    const STRING_HASH: &str =
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18";

    fn node(zid: &str, name: &str) -> NodeIdentity {
        NodeIdentity {
            domain_id: 0,
            zid: zid.into(),
            node_id: 0,
            name: name.into(),
            namespace: "/".into(),
            enclave: "/".into(),
        }
    }

    fn chatter(depth: u32) -> Endpoint {
        Endpoint {
            topic: "/chatter".into(),
            type_name: "std_msgs/msg/String".into(),
            type_hash: STRING_HASH.into(),
            qos: Qos {
                reliability: Reliability::Reliable,
                depth,
            },
        }
    }

    #[test]
    fn tokens_are_those_of_rmw_zenohs_design_document() {
        // Verbatim from rmw_zenoh's docs/design.md (a listener node, a talker's publisher,
        // a listener's subscription).
        assert_eq!(
            node_token(&node("aac3178e146ba6f1fc6e6a4085e77f21", "listener")),
            "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
        );
        assert_eq!(
            endpoint_token(
                &node("8b20917502ee955ac4476e0266340d5c", "talker"),
                10,
                EntityKind::Publisher,
                &chatter(7)
            ),
            "@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/\
             std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db12880\
             21743503259e948f6b1a18/::,7:,:,:,,"
        );
        assert_eq!(
            endpoint_token(
                &node("aac3178e146ba6f1fc6e6a4085e77f21", "listener"),
                10,
                EntityKind::Subscription,
                &chatter(10)
            ),
            "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/\
             std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db12880\
             21743503259e948f6b1a18/::,10:,:,:,,"
        );
    }

    #[test]
    fn topic_keys_and_type_names() {
        assert_eq!(
            topic_key(0, "/chatter", "std_msgs/msg/String", STRING_HASH),
            format!("0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}")
        );
        assert_eq!(
            topic_key(
                7,
                "/puma/measured_js",
                "sensor_msgs/msg/JointState",
                "RIHS01_x"
            ),
            "7/puma/measured_js/sensor_msgs::msg::dds_::JointState_/RIHS01_x"
        );
        assert_eq!(
            dds_type_name("crtk_msgs/msg/OperatingState"),
            "crtk_msgs::msg::dds_::OperatingState_"
        );
    }

    #[test]
    fn qos_chunks() {
        assert_eq!(Qos::SENSOR_DATA.encode(), "2::,5:,:,:,,");
        assert_eq!(Qos::DEFAULT.encode(), "::,10:,:,:,,");
        let default_depth = Qos {
            reliability: Reliability::Reliable,
            depth: 42,
        };
        assert_eq!(default_depth.encode(), "::,:,:,:,,");
    }

    #[test]
    fn a_gid_is_the_tokens_xxh3_128_in_two_little_endian_halves() {
        // XXH3-128 of the empty input (the reference implementation's test vector):
        // 0x99aa06d3014798d86001c324468d497f.
        let empty = gid("");
        assert_eq!(
            u64::from_le_bytes(empty[..8].try_into().unwrap()),
            0x6001_c324_468d_497f
        );
        assert_eq!(
            u64::from_le_bytes(empty[8..].try_into().unwrap()),
            0x99aa_06d3_0147_98d8
        );
        assert_ne!(gid("@ros2_lv/0/a"), gid("@ros2_lv/0/b"));
    }
}
