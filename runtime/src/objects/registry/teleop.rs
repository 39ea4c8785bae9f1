//! Teleoperation channels in the registry: configuring one (its two ends on this node, or this
//! node's end linked over the data plane to the other node's), and what `describe` shows of
//! its link.

use crate::dataplane::endpoint::Endpoint;
use crate::objects::error::ObjectError;
use crate::objects::registry::{TeleopObj, bad_arg};
use crate::objects::teleop_end::{Side, TeleopLink};
use crate::objects::{KindState, Registry};
use penelope_protocol::proto::Class;

use crate::dataplane::end_clock::LinkTime;
use crate::objects::clock::ClockMode;

/// `describe`'s lines about a channel's link to another node (none for a channel on this
/// node, or before its first communication tick).
pub(super) fn link_relations(
    name: &str,
    t: &TeleopObj,
    bridged: &crate::objects::bridged::BridgedChannels,
) -> Vec<(String, String)> {
    if t.config.zenoh_reference.is_some()
        && let Some(c) = bridged.counts(name)
    {
        let last = c
            .last_refusal
            .map_or(String::new(), |why| format!(" (the last: {why})"));
        return vec![(
            "zenoh".to_string(),
            format!(
                "master poses from `{}`: {} taken, {} refused{last}",
                c.key, c.taken, c.refused
            ),
        )];
    }
    let Some(r) = t.link.as_ref().and_then(TeleopLink::stats) else {
        return Vec::new();
    };
    let peer = t.config.peer.clone().unwrap_or_default();
    let micros = |v: Option<i64>| {
        v.map_or("unknown".to_string(), |ns| {
            format!("{:.1} µs", ns as f64 / 1e3)
        })
    };
    // A link down because the other node runs another build says so, not just "down".
    let other_build = match r.endpoint.other_version {
        Some(v) if r.endpoint.wrong_version > 0 => format!(
            "; {} datagrams of data-plane version {v} refused (this node speaks {}: the other \
             node runs another build)",
            r.endpoint.wrong_version,
            crate::dataplane::frame::DATAPLANE_VERSION
        ),
        _ => String::new(),
    };
    vec![
        (
            "link".to_string(),
            format!(
                "{} to {peer}, lost {} times, restored {} times{other_build}",
                if r.down { "down" } else { "up" },
                r.losses,
                r.restorations
            ),
        ),
        (
            "link-stats".to_string(),
            format!(
                "{} samples taken, {} datagrams refused, clock offset {}, round trip {}, \
                 one-way delay {}, jitter {}, heartbeats lost {:.1}%, last heard {} ago",
                r.stream.accepted,
                r.refused(),
                micros(r.clock_offset_ns),
                micros(r.round_trip_ns),
                micros(r.one_way_delay_ns),
                micros(r.jitter_ns),
                r.heartbeat_loss * 100.0,
                micros(r.last_heard_ns)
            ),
        ),
        (
            "link-trips".to_string(),
            format!(
                "samples' one-way trip p50 {}, p99 {}, max {} ({} trips)",
                micros(r.one_way.quantile(0.5)),
                micros(r.one_way.quantile(0.99)),
                micros((r.one_way.count() > 0).then(|| r.one_way.max_ns())),
                r.one_way.count()
            ),
        ),
    ]
}

impl Registry {
    pub(super) fn configure_teleop(&mut self, name: &str) -> Result<(), ObjectError> {
        let kind = crate::objects::kinds::Kind::TELEOP.as_str();
        let KindState::Teleop(t) = &self.get(name)?.body else {
            return Err(ObjectError::internal("teleop body"));
        };
        let (master, slave, mapping) = (
            t.config.master.clone(),
            t.config.slave.clone(),
            t.config.mapping(),
        );
        let data_plane = t.config.data_plane(kind)?;
        let faults = t.config.faults.clone().map(|f| (f, t.config.fault_seed));
        penelope_rt_core::teleop::WorkspaceMapping::new(mapping).map_err(|e| {
            ObjectError::BadConfig {
                kind: kind.into(),
                message: format!("{e:?}"),
            }
        })?;
        if let Some(key) = t.config.zenoh_reference.clone() {
            // The master is an operator station behind the bridge: only the slave is here.
            self.expect_class(&slave, Class::Robot)?;
            if self.expect_class(&master, Class::Robot).is_ok() {
                return Err(bad_arg(format!(
                    "`{name}` takes its master's poses from Zenoh, but `{master}` is a robot on \
                     this node (name the operator station instead)"
                )));
            }
            let (link, end) = TeleopLink::bridged(Side::Slave);
            self.bridged.insert(name, &key, &slave, end);
            if let KindState::Teleop(t) = &mut self.get_mut(name)?.body {
                t.link = Some(link);
            }
            return Ok(());
        }
        let link = match data_plane {
            None => {
                self.expect_class(&master, Class::Robot)?;
                self.expect_class(&slave, Class::Robot)?;
                match &faults {
                    None => TeleopLink::new(),
                    Some((f, seed)) => {
                        TeleopLink::delayed(f, *seed).map_err(|e| ObjectError::BadConfig {
                            kind: kind.into(),
                            message: format!("`faults`: {e}"),
                        })?
                    }
                }
            }
            Some((listen, peer)) => {
                self.remote_link(name, (&master, &slave), (listen, peer), faults.as_ref())?
            }
        };
        if let KindState::Teleop(t) = &mut self.get_mut(name)?.body {
            t.link = Some(link);
        }
        Ok(())
    }

    /// One end of channel `name` (of `master` and `slave`) on the data plane, bound at
    /// `listen` to `peer`: the side whose robot is on this node, its datagrams authenticated
    /// off loopback, clocked as the creator is, with the configured faults.
    fn remote_link(
        &self,
        name: &str,
        (master, slave): (&str, &str),
        (listen, peer): (std::net::SocketAddr, std::net::SocketAddr),
        faults: Option<&(crate::dataplane::faults::FaultConfig, u64)>,
    ) -> Result<TeleopLink, ObjectError> {
        let kind = crate::objects::kinds::Kind::TELEOP.as_str();
        let here = |r: &str| self.expect_class(r, Class::Robot).is_ok();
        let side = match (here(master), here(slave)) {
            (true, false) => Side::Master,
            (false, true) => Side::Slave,
            (true, true) => {
                return Err(bad_arg(format!(
                    "`{name}` has a `peer`, but both `{master}` and `{slave}` are on \
                     this node (leave out listen and peer)"
                )));
            }
            (false, false) => {
                return Err(bad_arg(format!(
                    "neither `{master}` nor `{slave}` is a robot on this node"
                )));
            }
        };
        let off_loopback = !(listen.ip().is_loopback() && peer.ip().is_loopback());
        if off_loopback && self.datagram_key.is_none() {
            return Err(bad_arg(format!(
                "`{name}` crosses off loopback ({listen} to {peer}): the nodes need a \
                 secret (--secret-file) so that its datagrams are authenticated"
            )));
        }
        // One key per direction of this channel, bound to both robots' names (the
        // same on both nodes): another channel's datagrams do not verify here.
        let (here, there) = match side {
            Side::Master => (master, slave),
            Side::Slave => (slave, master),
        };
        let keys = self
            .datagram_key
            .as_ref()
            .map(|k| k.directed("teleop", here, there));
        let endpoint = Endpoint::bind_directed(listen, keys)
            .map_err(|e| ObjectError::device(format!("data plane: cannot bind {listen}"), e))?;
        // Real times and kernel receive stamps on real time; the tick's on a
        // simulated clock, so that simulated runs stay reproducible.
        let time = match self.clock {
            ClockMode::RealTime => LinkTime::Real,
            ClockMode::Simulated => LinkTime::Tick,
        };
        TeleopLink::remote(
            side,
            endpoint,
            peer,
            time,
            faults.map(|(f, seed)| (f, *seed)),
        )
        .map_err(|e| ObjectError::BadConfig {
            kind: kind.into(),
            message: format!("`faults`: {e}"),
        })
    }
}
