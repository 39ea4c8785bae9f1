//! A controller's methods other than its lifecycle: its status, what it is following, and gains
//! changed while it runs (merged into its configuration, checked, routed to its loop).

use super::laws::{default_joint_gains, pid_gains};
use crate::objects::Registry;
use crate::objects::error::ObjectError;
use crate::objects::registry::{
    ControllerConfig, ImpedanceConfigToml, JointPidConfig, impedance, not_ready,
};
use crate::objects::runtime::{GainsUpdate, RoutedGains};
use crate::objects::teleop_laws::{
    ForceDisplayToml, FourChannelSlaveToml, FourChannelToml, PositionErrorToml, SlaveTrackingToml,
};
use crate::objects::teleop_wave::{WaveMasterToml, WaveSlaveToml};
use penelope_drivers::model::SerialRobotModel;
use penelope_hal::{Kinematics, LifecycleState, MAX_JOINTS};
use penelope_protocol::proto::{Class, ControlStatus, ControllerMethod, Reply};

impl Registry {
    /// Controller methods other than the lifecycle (the creator handles those).
    pub fn controller_method(
        &mut self,
        name: &str,
        m: ControllerMethod,
    ) -> Result<Reply, ObjectError> {
        let o = self.expect_class(name, Class::Controller)?;
        let state = o.shown_state();
        let kind = o.kind;
        let set_guard = |what: &str| -> Result<(), ObjectError> {
            if state == LifecycleState::Active {
                Err(not_ready(format!(
                    "deactivate `{name}` before changing its {what}"
                )))
            } else {
                Ok(())
            }
        };
        match m {
            ControllerMethod::SetRobot { robot } => {
                set_guard("robot")?;
                penelope_protocol::proto::check_name(&robot)?;
                self.controller_mut(name)?.robot = Some(robot);
                Ok(Reply::Unit)
            }
            ControllerMethod::SetTrajectory { trajectory } => {
                set_guard("trajectory")?;
                penelope_protocol::proto::check_name(&trajectory)?;
                self.controller_mut(name)?.trajectory = Some(trajectory);
                Ok(Reply::Unit)
            }
            ControllerMethod::SetSensor { sensor } => {
                set_guard("sensor")?;
                if let Some(path) = sensor.strip_prefix('/') {
                    for part in path.split('/') {
                        penelope_protocol::proto::check_name(part)?;
                    }
                } else {
                    penelope_protocol::proto::check_name(&sensor)?;
                }
                self.controller_mut(name)?.sensor = Some(sensor);
                Ok(Reply::Unit)
            }
            ControllerMethod::SetGains { gains } => self.set_gains(name, kind, &gains),
            ControllerMethod::EStop => {
                let c = self.controller_mut(name)?;
                let run = c
                    .running
                    .as_mut()
                    .ok_or_else(|| not_ready(format!("controller `{name}` is not running")))?;
                // The latch, not the command ring: a stop is never refused for want of room.
                run.stop.request();
                Ok(Reply::Unit)
            }
            // Re-arming may start threads: the creator's job (`Creator::rearm`).
            ControllerMethod::Rearm => Err(ObjectError::internal("rearm is served by the creator")),
            ControllerMethod::Status => self.status(name, state),
        }
    }

    /// New gains for controller `name` (the keys given replace the configuration's), sent to
    /// its running loop, or to the running joint group it is a member of.
    fn set_gains(
        &mut self,
        name: &str,
        kind: crate::objects::kinds::Kind,
        gains: &str,
    ) -> Result<Reply, ObjectError> {
        let k = kind.as_str();
        let model = self
            .controller_mut(name)?
            .robot
            .clone()
            .and_then(|r| self.robot(&r).ok().map(|r| r.model.clone()));
        let c = self.controller_mut(name)?;
        if matches!(c.config, ControllerConfig::Position(_)) {
            return Err(ObjectError::Unsupported {
                kind: k.to_string(),
                method: "set-gains (its only setting, max_velocity, is fixed at creation)".into(),
            });
        }
        if matches!(c.config, ControllerConfig::Groups(_)) {
            return Err(ObjectError::Unsupported {
                kind: k.to_string(),
                method: "set-gains (set its members' gains: they reach the running group)".into(),
            });
        }
        // The new keys replace those of the configuration; the rest stays.
        let text = merged_gains(k, &c.config_text, gains)?;
        let (config, update) = gains_from(k, &c.config, &text, model.as_ref())?;
        // To the running loop: its own, or the joint group's that runs this member.
        if let Some(update) = update {
            let (run, member) = match self.controller_mut(name)?.running.is_some() {
                true => (self.controller_mut(name)?.running.as_mut(), None),
                false => match self.running_group_of(name) {
                    Some((group, index)) => {
                        (self.controller_mut(&group)?.running.as_mut(), Some(index))
                    }
                    None => (None, None),
                },
            };
            if let Some(run) = run {
                run.gains
                    .push(RoutedGains { member, update })
                    .map_err(|_| not_ready("gain changes queued; retry"))?;
            }
        }
        let c = self.controller_mut(name)?;
        c.config = config;
        c.config_text = text;
        Ok(Reply::Unit)
    }

    /// Controller `name`'s running state and newest sample, shown as `state`.
    fn status(&mut self, name: &str, state: LifecycleState) -> Result<Reply, ObjectError> {
        let joints = self
            .controller_mut(name)?
            .robot
            .clone()
            .and_then(|r| self.robot(&r).ok().map(|r| r.model.joint_count()))
            .unwrap_or(MAX_JOINTS);
        let c = self.controller_mut(name)?;
        let (running, ticks, overruns, dropped, last) = match c.running.as_mut() {
            Some(run) => {
                let newest = run.shared.newest().map(|n| n.sample);
                let overruns = run.overruns();
                (
                    true,
                    newest.map_or(0, |s| s.seq),
                    overruns,
                    run.shared
                        .dropped
                        .load(std::sync::atomic::Ordering::Relaxed),
                    newest,
                )
            }
            None => (false, c.last.map_or(0, |s| s.seq), 0, 0, c.last),
        };
        Ok(Reply::Status(ControlStatus {
            state,
            running,
            ticks,
            overruns,
            telemetry_dropped: dropped,
            last: last.map(|s| Box::new(crate::objects::runtime::record(&s, None, joints))),
        }))
    }
}

/// The keys of every loop (fixed while the loop runs).
const LOOP_TIMING_KEYS: [&str; 6] = [
    "period_us",
    "comm_period_us",
    "watchdog_ms",
    "sensor_period_ms",
    "sensor_timeout_ms",
    "telemetry_period_ms",
];

/// `current` (a configuration's TOML text) with the keys of `gains` replaced: refused for loop
/// timing keys (set at creation) and for text that is not a TOML table.
fn merged_gains(kind: &str, current: &str, gains: &str) -> Result<String, ObjectError> {
    let bad = |message: String| ObjectError::BadConfig {
        kind: kind.into(),
        message,
    };
    let new: toml::Table = gains
        .parse()
        .map_err(|e: toml::de::Error| bad(e.message().to_string()))?;
    if let Some(k) = new.keys().find(|k| LOOP_TIMING_KEYS.contains(&k.as_str())) {
        return Err(bad(format!(
            "`{k}` is a loop timing key, set at creation; set-gains changes gains"
        )));
    }
    let mut table: toml::Table = current
        .parse()
        .map_err(|e: toml::de::Error| bad(e.message().to_string()))?;
    table.extend(new);
    Ok(table.to_string())
}

/// A controller's configuration from `text`, checked, and the update for its running loop
/// (a joint PID's needs its robot's `model` for the default gains; without one, none is sent).
fn gains_from(
    kind: &str,
    current: &ControllerConfig,
    text: &str,
    model: Option<&SerialRobotModel>,
) -> Result<(ControllerConfig, Option<GainsUpdate>), ObjectError> {
    Ok(match current {
        ControllerConfig::Pid(_) => {
            let cfg: JointPidConfig = crate::objects::config::parse(kind, text)?;
            cfg.check(kind)?;
            let update = match model {
                Some(m) => {
                    let n = m.joint_count();
                    let (kp, kd) = default_joint_gains(m, n);
                    Some(GainsUpdate::Pid(pid_gains(&cfg, kind, n, kp, kd)?))
                }
                None => None,
            };
            (ControllerConfig::Pid(cfg), update)
        }
        ControllerConfig::Impedance(_) => {
            let cfg: ImpedanceConfigToml = crate::objects::config::parse(kind, text)?;
            cfg.check(kind)?;
            let update = GainsUpdate::Impedance(impedance(&cfg));
            (ControllerConfig::Impedance(cfg), Some(update))
        }
        ControllerConfig::ForceDisplay(_) => {
            let cfg: ForceDisplayToml = crate::objects::config::parse(kind, text)?;
            let law = cfg.law(kind)?;
            (
                ControllerConfig::ForceDisplay(cfg),
                Some(GainsUpdate::ForceDisplay(*law.config())),
            )
        }
        ControllerConfig::PositionError(_) => {
            let cfg: PositionErrorToml = crate::objects::config::parse(kind, text)?;
            let law = cfg.law(kind)?;
            (
                ControllerConfig::PositionError(cfg),
                Some(GainsUpdate::PositionError(*law.config())),
            )
        }
        ControllerConfig::FourChannel(_) => {
            let cfg: FourChannelToml = crate::objects::config::parse(kind, text)?;
            let law = cfg.law(kind)?;
            (
                ControllerConfig::FourChannel(cfg),
                Some(GainsUpdate::FourChannel(*law.config())),
            )
        }
        ControllerConfig::FourChannelSlave(_) => {
            let cfg: FourChannelSlaveToml = crate::objects::config::parse(kind, text)?;
            let law = cfg.law(kind)?;
            (
                ControllerConfig::FourChannelSlave(cfg),
                Some(GainsUpdate::FourChannelSlave(*law.config())),
            )
        }
        ControllerConfig::Tracking(_, servo) => {
            let cfg: SlaveTrackingToml = crate::objects::config::parse(kind, text)?;
            let law = cfg.law(kind, *servo)?;
            (
                ControllerConfig::Tracking(cfg, *servo),
                Some(GainsUpdate::Tracking(*law.config())),
            )
        }
        // The display and tracking gains change live; the wave keys when the loop next starts
        // (both sides' transforms must restart together).
        ControllerConfig::WaveMaster(_) => {
            let cfg: WaveMasterToml = crate::objects::config::parse(kind, text)?;
            cfg.wave(kind)?;
            let law = cfg.law(kind)?;
            (
                ControllerConfig::WaveMaster(cfg),
                Some(GainsUpdate::ForceDisplay(*law.config())),
            )
        }
        ControllerConfig::WaveSlave(_) => {
            let cfg: WaveSlaveToml = crate::objects::config::parse(kind, text)?;
            cfg.wave(kind)?;
            let law = cfg.law(kind)?;
            (
                ControllerConfig::WaveSlave(cfg),
                Some(GainsUpdate::Tracking(*law.config())),
            )
        }
        ControllerConfig::Position(_) | ControllerConfig::Groups(_) => {
            return Err(ObjectError::Internal(format!("{kind} has no gains").into()));
        }
    })
}
