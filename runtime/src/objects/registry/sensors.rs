//! Sensors in the registry: a `sensor/virtual` with `publish` serves its readers on the data
//! plane from the moment it is configured until it is cleaned up or destroyed, and `describe`
//! shows its publisher's counters.

use crate::dataplane::endpoint::Endpoint;
use crate::dataplane::sensor_stream::SensorPublisher;
use crate::objects::error::ObjectError;
use crate::objects::registry::{SensorObj, bad_arg, not_ready};
use crate::objects::{KindState, Registry};
use penelope_protocol::proto::Reply;
use std::time::Duration;

/// `describe`'s lines about a sensor's publisher (none for a sensor that does not publish, or
/// is not configured).
pub(super) fn publisher_relations(s: &SensorObj) -> Vec<(String, String)> {
    let Some(p) = &s.publisher else {
        return Vec::new();
    };
    let st = p.stats();
    vec![
        ("publish".to_string(), p.address().to_string()),
        (
            "publisher".to_string(),
            format!(
                "{} subscribers, {} samples published, {} probes taken, {} datagrams refused \
                 ({} bad tags, {} bad probes, {} over the subscriber bound)",
                st.subscribers,
                st.samples,
                st.probes,
                st.refused(),
                st.endpoint.bad_tag,
                st.bad_probes,
                st.refused_full,
            ),
        ),
    ]
}

impl Registry {
    /// Configures a `sensor/virtual`: with `publish`, binds its data-plane endpoint (keyed with
    /// the node's datagram key) and starts its publisher.
    pub(super) fn configure_sensor(&mut self, name: &str) -> Result<(), ObjectError> {
        let kind = crate::objects::kinds::Kind::VIRTUAL_SENSOR.as_str();
        let key = self.datagram_key.clone();
        let KindState::Sensor(s) = &mut self.get_mut(name)?.body else {
            return Err(ObjectError::internal("sensor body"));
        };
        let Some(address) = s.config.publish_address(kind)? else {
            return Ok(());
        };
        if !address.ip().is_loopback() && key.is_none() {
            return Err(bad_arg(format!(
                "sensor `{name}` publishes off loopback ({address}): the nodes need a secret \
                 (--secret-file) so that its datagrams are authenticated"
            )));
        }
        // Keys of this sensor's two directions (name-bound): not another stream's.
        let keys = key.map(|k| crate::dataplane::sensor_stream::sensor_publisher_keys(&k, name));
        let endpoint = Endpoint::bind_directed(address, keys)
            .map_err(|e| ObjectError::device(format!("data plane: cannot bind {address}"), e))?;
        let state = s.state.clone();
        let measure = Box::new(
            move |probe: Option<&crate::dataplane::sensor_stream::Probe>| {
                let mut sensor = state.lock().ok()?;
                Some(match probe {
                    Some(p) => sensor.measure(&p.pose, p.velocity),
                    None => sensor.read(),
                })
            },
        );
        let period = Duration::from_millis(s.config.publish_period_ms);
        let publisher = SensorPublisher::start(name, endpoint, period, measure)
            .map_err(|e| ObjectError::thread(format!("sensor `{name}`: publisher thread"), e))?;
        s.publisher = Some(publisher);
        Ok(())
    }

    /// The address sensor `name` publishes at.
    ///
    /// # Errors
    /// [`ObjectError::NotReady`] naming the sensor and the `publish` key when it does not
    /// publish.
    pub(super) fn sensor_stream(&self, name: &str, s: &SensorObj) -> Result<Reply, ObjectError> {
        match &s.publisher {
            Some(p) => Ok(Reply::Address(p.address().to_string())),
            None => Err(not_ready(format!(
                "sensor `{name}` is not published on the data plane: it has no `publish` key \
                 (host:port), and a controller on another node reads a sensor only over the \
                 data plane"
            ))),
        }
    }
}
