//! Which messages a recording holds: Penelope's own channels or the ROS 2 topic set.

/// Which messages a recording holds: `penelope` (every tick in full, safety events, links,
/// streams, lifecycle, clock and the 3D scene: [`mcap_log`](super::mcap_log); what Penelope's readers, replay
/// and task reports need) or `ros2` (the ROS 2 topic set as CDR: [`ros2_log`](super::ros2_log)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RecordProfile {
    /// Penelope's own channels (JSON): the default.
    #[default]
    Penelope,
    /// The ROS 2 topic set (CDR, `ros2msg` schemas).
    Ros2,
}

impl RecordProfile {
    /// Every profile, by name.
    pub const ALL: [RecordProfile; 2] = [RecordProfile::Penelope, RecordProfile::Ros2];

    /// `penelope` or `ros2`.
    pub const fn as_str(self) -> &'static str {
        match self {
            RecordProfile::Penelope => "penelope",
            RecordProfile::Ros2 => "ros2",
        }
    }

    /// The profile named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.as_str() == name)
    }
}

impl std::fmt::Display for RecordProfile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for RecordProfile {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::from_name(s)
            .ok_or_else(|| format!("unknown recording profile `{s}` (penelope or ros2)"))
    }
}
