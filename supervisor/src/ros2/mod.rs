//! A node's ROS 2 presence over rmw_zenoh (`penelope node --ros2`, docs/ros2.md): on the Zenoh
//! bridge's session, the node appears in the ROS 2 graph as node `penelope_<node>` and speaks
//! rmw_zenoh's wire format, so that ROS 2 nodes using `RMW_IMPLEMENTATION=rmw_zenoh_cpp` (and
//! `ros2 node list`, `ros2 topic list`, `ros2 topic echo`) see it without a bridge program.
//!
//! - Published, per robot a controller on this node drives, at [`Ros2Settings::rate_hz`] of
//!   tick time: the CRTK topic set of
//!   [`ros2_topics`](penelope_runtime::objects::recording::ros2_topics) (`/<robot>/measured_js`,
//!   `measured_cp`, `measured_cf`, `setpoint_js`, `operating_state`, and `/tf`), the same
//!   messages a recording's `ros2` profile writes; per channel linked to another node,
//!   `/diagnostics` with its link statistics; per channel fed from Zenoh, what its slave end
//!   sends back for the operator station (`/<channel>/feedback_cp`, `feedback_cf`).
//! - Subscribed, per robot: `/<robot>/servo_jp` (`sensor_msgs/msg/JointState`) into the
//!   robot's CRTK `servo_jp`; `/<robot>/servo_cp` (`geometry_msgs/msg/PoseStamped`) into the
//!   operator pose of the teleoperation channel fed from Zenoh (`zenoh_reference`) that drives
//!   the robot when one does (the channel maps it, anchored and scaled, and its law and force
//!   feedback apply), else into the robot's `servo_cp`; `/<robot>/clutch`
//!   (`sensor_msgs/msg/Joy`, button 0 held, as the dVRK's foot pedal) the operator's clutch.
//!   Every input goes through the checks of the path it takes (finite, within limits and
//!   reach, the servo step limit, the channel's pose checks). A payload that does not decode
//!   is counted and dropped; none reaches a loop but through those methods and cells.
//!
//! [`graph`] is the format (tokens, keys, QoS, GIDs); `attachment` and `presence` (feature
//! `zenoh`) put it on the session. Who may put is the bridge's access control (docs/zenoh.md:
//! with `operators`, only they).

pub mod graph;

#[cfg(feature = "zenoh")]
pub(crate) mod attachment;
#[cfg(feature = "zenoh")]
pub(crate) mod presence;

/// The highest rate the topics are published at, Hz (a 1 kHz loop's every tick).
pub const MAX_RATE_HZ: u32 = 1000;
/// The highest ROS domain id (ROS 2 allows 0 to 232).
pub const MAX_DOMAIN_ID: u32 = 232;

/// A node's ROS 2 settings: `ros2 = true` or `ros2 = { domain_id = 0, rate_hz = 100 }` in its
/// `[nodes.<name>]` table, or `penelope node --ros2 [--ros2-domain-id N] [--ros2-rate-hz R]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ros2Settings {
    /// The ROS domain (`ROS_DOMAIN_ID`), 0..=232; default 0.
    pub domain_id: u32,
    /// The topics' rate, Hz of tick time, 1..=1000; default 100 (every tenth tick of a 1 kHz
    /// loop).
    pub rate_hz: u32,
}

impl Default for Ros2Settings {
    fn default() -> Self {
        Ros2Settings {
            domain_id: 0,
            rate_hz: 100,
        }
    }
}

impl Ros2Settings {
    /// Checks the ranges.
    ///
    /// # Errors
    /// What is out of range.
    pub fn check(&self) -> Result<(), String> {
        if self.domain_id > MAX_DOMAIN_ID {
            return Err(format!(
                "ros2 domain_id {} is out of 0..={MAX_DOMAIN_ID}",
                self.domain_id
            ));
        }
        if !(1..=MAX_RATE_HZ).contains(&self.rate_hz) {
            return Err(format!(
                "ros2 rate_hz {} is out of 1..={MAX_RATE_HZ}",
                self.rate_hz
            ));
        }
        Ok(())
    }
}

impl<'de> serde::Deserialize<'de> for Ros2Settings {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Table {
            domain_id: Option<u32>,
            rate_hz: Option<u32>,
        }
        #[derive(serde::Deserialize)]
        #[serde(
            untagged,
            expecting = "true or a table { domain_id = 0..=232, rate_hz = 1..=1000 }"
        )]
        enum Either {
            On(bool),
            Table(Table),
        }
        let settings = match Either::deserialize(d)? {
            Either::On(true) => Ros2Settings::default(),
            Either::On(false) => {
                return Err(serde::de::Error::custom(
                    "`ros2 = false`: leave the key out for no ROS 2 presence",
                ));
            }
            Either::Table(t) => Ros2Settings {
                domain_id: t.domain_id.unwrap_or(0),
                rate_hz: t.rate_hz.unwrap_or(Ros2Settings::default().rate_hz),
            },
        };
        settings.check().map_err(serde::de::Error::custom)?;
        Ok(settings)
    }
}

/// Why a node's ROS 2 presence could not start.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Ros2Error {
    /// The node's liveliness token could not be declared on the session.
    #[error("the ROS 2 node's liveliness token {0}")]
    NodeToken(String),
}

/// What a node's ROS 2 presence did so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Ros2Stats {
    /// Liveliness tokens declared (the node, its publishers and subscriptions).
    pub tokens: u64,
    /// Messages published.
    pub published: u64,
    /// Messages taken on its subscriptions and passed on.
    pub taken: u64,
    /// Messages refused: a payload that does not decode, or one the method or channel refused.
    pub refused: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Deserialize)]
    struct Node {
        ros2: Ros2Settings,
    }

    fn parse(text: &str) -> Result<Ros2Settings, String> {
        toml::from_str::<Node>(text)
            .map(|n| n.ros2)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn settings_from_a_system_file() {
        assert_eq!(parse("ros2 = true"), Ok(Ros2Settings::default()));
        assert_eq!(
            parse("ros2 = { domain_id = 7, rate_hz = 250 }"),
            Ok(Ros2Settings {
                domain_id: 7,
                rate_hz: 250
            })
        );
        for (bad, says) in [
            ("ros2 = false", "leave the key out"),
            ("ros2 = { domain_id = 233 }", "out of 0..=232"),
            ("ros2 = { rate_hz = 0 }", "out of 1..=1000"),
            ("ros2 = { rate = 5 }", "true or a table"),
        ] {
            let e = parse(bad).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn a_nodes_table_takes_ros2() {
        let file = crate::system::SystemFile::parse(
            "[nodes.lab]\nros2 = { domain_id = 4 }\n\n[boards.io]\nkind = \"sim\"\n",
        )
        .unwrap();
        assert_eq!(
            file.nodes["lab"].ros2,
            Some(Ros2Settings {
                domain_id: 4,
                rate_hz: 100
            })
        );
    }
}
