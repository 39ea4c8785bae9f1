//! `sensor/netft` in the registry: configuring opens the box's stream (its I/O thread) and waits
//! for the first record; cleanup stops it; `describe` shows the driver's counters; `read` and
//! `bias` reach the driver from the non-real-time side.

use crate::objects::error::ObjectError;
use crate::objects::registry::{Kind, not_ready};
use crate::objects::{KindState, Registry, kinds};
use penelope_drivers::netft::{NetFt, NetFtConfig, NetFtReader};
use penelope_protocol::proto::{Reply, SensorMethod, WrenchMsg};
use std::time::Duration;

/// How long `configure` of a Net F/T waits for its first record.
const FIRST_RECORD_TIMEOUT: Duration = Duration::from_secs(2);

/// A `sensor/netft`: its checked settings, and the open stream while configured.
pub(crate) struct NetFtObj {
    pub config: NetFtConfig,
    pub sensor: Option<NetFt>,
}

/// Makes the body of a `sensor/netft` from its configuration text.
pub(super) fn netft_body(config: &str) -> Result<KindState, ObjectError> {
    let k = Kind::NetFtSensor.as_str();
    let cfg: kinds::NetFtSensorConfig = crate::objects::config::parse(k, config)?;
    let config = cfg.check(k)?;
    Ok(KindState::NetFt(Box::new(NetFtObj {
        config,
        sensor: None,
    })))
}

/// `describe`'s lines about a Net F/T.
pub(super) fn netft_relations(s: &NetFtObj) -> Vec<(String, String)> {
    let mut out = vec![("address".to_string(), s.config.address.to_string())];
    if let Some(ft) = &s.sensor {
        let c = ft.counters();
        out.push((
            "stream".to_string(),
            format!(
                "{} records, {} missed in {} gaps ({} loss faults), {} malformed, {} out of \
                 order, {} error status, {} saturated, {} timeouts, {} biases",
                c.records,
                c.missed,
                c.gaps,
                c.loss_faults,
                c.malformed,
                c.out_of_order,
                c.status_errors,
                c.saturated,
                c.timeouts,
                c.biases
            ),
        ));
    }
    out
}

impl Registry {
    /// Opens the stream of Net F/T `name` and waits (bounded) for its first record.
    pub(super) fn configure_netft(&mut self, name: &str) -> Result<(), ObjectError> {
        let KindState::NetFt(s) = &mut self.get_mut(name)?.body else {
            return Err(ObjectError::internal("netft body"));
        };
        let address = s.config.address;
        let ft = NetFt::open(s.config)
            .map_err(|e| ObjectError::device(format!("net f/t at {address}"), e))?;
        if !ft.wait_for_records(1, FIRST_RECORD_TIMEOUT) {
            return Err(ObjectError::DeviceRefused(format!(
                "net f/t at {address}: no RDT record within {} ms (is the box, or `penelope \
                 netft-sim`, there?)",
                FIRST_RECORD_TIMEOUT.as_millis()
            )));
        }
        s.sensor = Some(ft);
        Ok(())
    }

    /// A loop's reader of Net F/T `name`, if `name` is one, with the sensor's mount.
    pub(super) fn netft_reader(&self, name: &str) -> Result<Option<NetFtReader>, ObjectError> {
        let Some(KindState::NetFt(s)) = self.objects.get(name).map(|o| &o.body) else {
            return Ok(None);
        };
        match &s.sensor {
            Some(ft) => Ok(Some(ft.reader())),
            None => Err(not_ready(format!("sensor `{name}` is not configured"))),
        }
    }

    /// `read` and `bias` of a Net F/T.
    pub(super) fn netft_method(
        s: &NetFtObj,
        kind: &str,
        m: SensorMethod,
    ) -> Result<Reply, ObjectError> {
        let Some(ft) = &s.sensor else {
            return Err(not_ready("the sensor is not configured"));
        };
        match m {
            SensorMethod::Read => ft
                .read(penelope_rt_core::clock::MonotonicClock::read())
                .map(|w| Reply::Wrench(WrenchMsg::from(&w)))
                .map_err(|e| ObjectError::device(format!("net f/t at {}", s.config.address), e)),
            SensorMethod::Bias => {
                ft.request_bias();
                Ok(Reply::Unit)
            }
            other => Err(ObjectError::Unsupported {
                kind: kind.into(),
                method: format!(
                    "{other:?} (a Net F/T measures the world; it takes no probe and is read in \
                     the loop of the controller bound to it)"
                )
                .into(),
            }),
        }
    }
}
