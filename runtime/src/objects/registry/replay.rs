//! The replay kinds in the registry (`sensor/replay`, `sensor/operator-replay`): made from their
//! configuration, loaded at `configure`, dropped at `cleanup`; and the hand that holds a
//! master, scripted or replayed.

use std::sync::atomic::AtomicBool;

use penelope_drivers::sim::environment::Environment;
use penelope_hal::Pose;

use crate::objects::error::ObjectError;
use crate::objects::registry::{Kind, not_ready};
use crate::objects::replay::{
    OperatorReplayConfig, OperatorReplayObj, ReplaySensor, ReplaySensorConfig, ReplaySensorObj,
};
use crate::objects::{KindState, Registry};
use penelope_drivers::sim::ToolContact;
use penelope_drivers::sim::operator::VirtualOperator;
use penelope_hal::Timestamp;
use std::sync::Arc;

/// The body of a new replay object of `kind` (configuration checked; nothing read yet).
pub(super) fn replay_body(kind: Kind, config: &str) -> Result<KindState, ObjectError> {
    let k = kind.as_str();
    Ok(match kind {
        Kind::REPLAY_SENSOR => {
            let cfg: ReplaySensorConfig = crate::objects::config::parse(k, config)?;
            cfg.check(k)?;
            KindState::ReplaySensor(Box::new(ReplaySensorObj {
                config: cfg,
                readings: None,
            }))
        }
        _ => {
            let cfg: OperatorReplayConfig = crate::objects::config::parse(k, config)?;
            cfg.check(k)?;
            KindState::OperatorReplay(Box::new(OperatorReplayObj {
                config: cfg,
                motion: None,
                clutch: Arc::default(),
            }))
        }
    })
}

impl Registry {
    /// Configures a replay object: reads its recording (typed errors: missing file, missing
    /// channel, no ticks, a NaN, no truth for a hand).
    pub(super) fn configure_replay(&mut self, name: &str) -> Result<(), ObjectError> {
        let o = self.get_mut(name)?;
        let kind = o.kind.as_str();
        match &mut o.body {
            KindState::ReplaySensor(s) => s.load().map_err(|e| e.for_kind(kind)),
            KindState::OperatorReplay(h) => h.load().map_err(|e| e.for_kind(kind)),
            _ => Err(ObjectError::internal("replay body")),
        }
    }

    /// Drops a replay object's loaded recording (`cleanup`).
    pub(super) fn release_replay(body: &mut KindState) {
        match body {
            KindState::ReplaySensor(s) => s.readings = None,
            KindState::OperatorReplay(h) => h.motion = None,
            _ => {}
        }
    }

    /// What touches the tool of simulated robot `robot`: the operator's hand (scripted, or
    /// replayed from a recording) if one holds it, else the board's environment. The scripted
    /// hand's script is anchored at `anchor`, the tool's start pose.
    ///
    /// # Errors
    /// [`ObjectError::NotReady`] for a replayed hand that is not configured (its recording not
    /// read).
    pub(super) fn tool_contact(
        &self,
        robot: &str,
        anchor: Pose,
        env: Environment,
    ) -> Result<ToolContact, ObjectError> {
        for (name, o) in &self.objects {
            match &o.body {
                KindState::Hand(h) if h.config.robot == robot => {
                    return Ok(ToolContact::Hand {
                        operator: VirtualOperator::new(
                            h.script.clone(),
                            h.config.impedance(),
                            anchor,
                            Timestamp::ZERO,
                        ),
                        clutch: h.clutch.clone(),
                    });
                }
                KindState::OperatorReplay(h) if h.config.robot == robot => {
                    let hand = h.hand().ok_or_else(|| {
                        not_ready(format!(
                            "hand `{name}` (holding `{robot}`) is not configured: its recording \
                             is read at configure"
                        ))
                    })?;
                    return Ok(ToolContact::Recorded(hand));
                }
                _ => {}
            }
        }
        Ok(ToolContact::Environment(env))
    }

    /// The clutch button of the hand holding `robot`, scripted or replayed, if one does.
    pub(super) fn clutch_of(&self, robot: &str) -> Option<Arc<AtomicBool>> {
        self.objects.values().find_map(|o| match &o.body {
            KindState::Hand(h) if h.config.robot == robot => Some(h.clutch.clone()),
            KindState::OperatorReplay(h) if h.config.robot == robot => Some(h.clutch.clone()),
            _ => None,
        })
    }

    /// The loop's side of `sensor/replay` `name`, if `name` is one (configured).
    ///
    /// # Errors
    /// [`ObjectError::NotReady`] when it is not configured.
    pub(super) fn replay_sensor(&self, name: &str) -> Result<Option<ReplaySensor>, ObjectError> {
        let Some(KindState::ReplaySensor(s)) = self.objects.get(name).map(|o| &o.body) else {
            return Ok(None);
        };
        let readings = s
            .readings
            .clone()
            .ok_or_else(|| not_ready(format!("sensor `{name}` is not configured")))?;
        Ok(Some(ReplaySensor::new(readings, s.config.mount())))
    }
}
