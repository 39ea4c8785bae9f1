//! What the safety layer and the control loop report from a tick: [`SafetyEvent`]s, gathered
//! one bit each in an [`EventSet`] for telemetry.

/// Something the safety layer or the control loop noticed during a tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum SafetyEvent {
    /// Activated (commands start from the measured state).
    Activated = 0,
    /// Deactivated.
    Deactivated,
    /// The reference went stale: hold position (slave) or zero force (master).
    ReferenceStale,
    /// A fresh reference came back after a stale spell; the controller was re-activated.
    ReferenceRecovered,
    /// A reference with NaN or infinity was rejected (the previous one is kept, and ages).
    ReferenceRejected,
    /// A commanded torque was clamped to its limit.
    EffortClamped,
    /// A commanded position was clamped to its range.
    PositionClamped,
    /// A master's reference wrench was scaled down to the force limits.
    ForceLimited,
    /// A fault latched (see [`Safety::fault_cause`](super::Safety::fault_cause)).
    Faulted,
    /// The e-stop latched.
    EStopped,
    /// A fault or e-stop was cleared by an explicit re-arm.
    Rearmed,
    /// The active controller changed.
    ControllerSwitched,
    /// A command was refused (unknown controller, activation while latched, ...).
    CommandRejected,
    /// A board read or write failed.
    BoardError,
    /// The force sensor failed to read (no wrench this tick).
    SensorError,
    /// The telemetry ring was full: this tick's sample was dropped.
    TelemetryDropped,
    /// The link that carries the reference (a teleoperation channel to another node) was lost:
    /// until it returns the reference is neutral (a slave holds its pose, a master displays no
    /// force). Raised by the communication thread that noticed it.
    LinkLost,
    /// The link that carries the reference came back; the motion was re-anchored where the
    /// robot is, so nothing jumps. Raised by the communication thread that noticed it.
    LinkRestored,
}

impl SafetyEvent {
    /// Every event, in bit order.
    pub const ALL: [SafetyEvent; 18] = [
        SafetyEvent::Activated,
        SafetyEvent::Deactivated,
        SafetyEvent::ReferenceStale,
        SafetyEvent::ReferenceRecovered,
        SafetyEvent::ReferenceRejected,
        SafetyEvent::EffortClamped,
        SafetyEvent::PositionClamped,
        SafetyEvent::ForceLimited,
        SafetyEvent::Faulted,
        SafetyEvent::EStopped,
        SafetyEvent::Rearmed,
        SafetyEvent::ControllerSwitched,
        SafetyEvent::CommandRejected,
        SafetyEvent::BoardError,
        SafetyEvent::SensorError,
        SafetyEvent::TelemetryDropped,
        SafetyEvent::LinkLost,
        SafetyEvent::LinkRestored,
    ];

    /// A kebab-case name for logs.
    pub const fn as_str(self) -> &'static str {
        match self {
            SafetyEvent::Activated => "activated",
            SafetyEvent::Deactivated => "deactivated",
            SafetyEvent::ReferenceStale => "reference-stale",
            SafetyEvent::ReferenceRecovered => "reference-recovered",
            SafetyEvent::ReferenceRejected => "reference-rejected",
            SafetyEvent::EffortClamped => "effort-clamped",
            SafetyEvent::PositionClamped => "position-clamped",
            SafetyEvent::ForceLimited => "force-limited",
            SafetyEvent::Faulted => "faulted",
            SafetyEvent::EStopped => "estopped",
            SafetyEvent::Rearmed => "rearmed",
            SafetyEvent::ControllerSwitched => "controller-switched",
            SafetyEvent::CommandRejected => "command-rejected",
            SafetyEvent::BoardError => "board-error",
            SafetyEvent::SensorError => "sensor-error",
            SafetyEvent::TelemetryDropped => "telemetry-dropped",
            SafetyEvent::LinkLost => "link-lost",
            SafetyEvent::LinkRestored => "link-restored",
        }
    }
}

/// A set of [`SafetyEvent`]s, one bit each (`Copy`, for telemetry).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct EventSet(pub u32);

impl EventSet {
    /// No events.
    pub const EMPTY: EventSet = EventSet(0);

    /// Adds `event`.
    pub fn insert(&mut self, event: SafetyEvent) {
        self.0 |= 1 << event as u8;
    }

    /// True when `event` is in the set.
    pub fn contains(self, event: SafetyEvent) -> bool {
        self.0 & (1 << event as u8) != 0
    }

    /// True when no event is in the set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Both sets together.
    pub fn union(self, other: EventSet) -> EventSet {
        EventSet(self.0 | other.0)
    }

    /// True when the set holds an event `before` did not (a new safety event since then).
    pub fn gained_since(self, before: EventSet) -> bool {
        self.0 & !before.0 != 0
    }

    /// The events in the set, in bit order.
    pub fn iter(self) -> impl Iterator<Item = SafetyEvent> {
        SafetyEvent::ALL
            .into_iter()
            .filter(move |e| self.contains(*e))
    }
}
