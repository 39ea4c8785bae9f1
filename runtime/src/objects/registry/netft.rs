//! `sensor/netft`, a whole kind in one module: an ATI Net F/T box streaming RDT over UDP, read
//! in the control loop's own thread. Its name, its configuration, its object (configuring opens
//! the box's stream, its I/O thread, and waits for the first record; cleanup stops it;
//! `describe` shows the driver's counters; `read` and `bias` reach the driver from the
//! non-real-time side) and its catalog entry.

use std::time::Duration;

use penelope_drivers::netft::{NetFt, NetFtConfig};
use penelope_hal::Pose;
use penelope_protocol::proto::{Reply, SensorMethod, WrenchMsg};
use serde::{Deserialize, Serialize};

use super::KindState;
use super::kind_entry::{KindEntry, MakeArgs};
use super::loop_sensor::LoopSensorObject;
use crate::objects::config::describe::{KindConfig, described};
use crate::objects::config::{bad, check_int, check_range, parse};
use crate::objects::error::ObjectError;
use crate::objects::kinds::Kind;
use crate::objects::runtime::LoopSensorReader;

/// `sensor/netft`.
pub const NETFT: Kind = Kind::named("sensor/netft");

/// Its catalog entry.
pub(super) const ENTRY: KindEntry = KindEntry::new(
    NETFT,
    "6-axis force/torque sensor: an ATI Net F/T streaming RDT over UDP (or `penelope netft-sim`), read in the loop; faults give the loop no wrench",
    described::<NetFtSensorConfig>(),
    make,
)
.as_real_device();

/// How long `configure` of a Net F/T waits for its first record.
const FIRST_RECORD_TIMEOUT: Duration = Duration::from_secs(2);

/// `sensor/netft` configuration: an ATI Net F/T box streaming RDT over UDP.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct NetFtSensorConfig {
    /// The box's RDT address (required), ip:port or an IP alone for port 49152;
    /// `penelope netft-sim` prints its own.
    pub address: String,
    /// Counts per N, the box's cfgcpf (its /netftapi2.xml), > 0.
    pub counts_per_force: f64,
    /// Counts per N·m, the box's cfgcpt, > 0.
    pub counts_per_torque: f64,
    /// The sensor frame's origin in the tool frame, m, each -2..=2.
    pub mount_xyz: [f64; 3],
    /// The sensor frame's orientation in the tool frame (roll, pitch, yaw), degrees.
    pub mount_rpy_deg: [f64; 3],
    /// A reading older than this is refused (the loop uses no wrench), ms, 1..=10000. Status
    /// bit 31 (error), saturation (bits 30, 27), a silence past the timeout or a loss burst:
    /// the loop notes a sensor error and uses no wrench, so a master displays zero force.
    pub timeout_ms: u64,
    /// More records lost in one gap than this is a fault (held for timeout_ms).
    pub max_gap: u32,
    /// Ask the box for a software bias when configured (`ctl call NAME bias` any time).
    pub bias_on_start: bool,
}

impl KindConfig for NetFtSensorConfig {
    fn example() -> Self {
        NetFtSensorConfig {
            address: "192.168.1.1:49152".into(),
            ..Self::default()
        }
    }
}

impl Default for NetFtSensorConfig {
    fn default() -> Self {
        NetFtSensorConfig {
            address: String::new(),
            counts_per_force: 1_000_000.0,
            counts_per_torque: 1_000_000.0,
            mount_xyz: [0.0; 3],
            mount_rpy_deg: [0.0; 3],
            timeout_ms: 20,
            max_gap: 4,
            bias_on_start: false,
        }
    }
}

impl NetFtSensorConfig {
    /// Checks ranges and the address, and gives the driver's settings.
    ///
    /// # Errors
    /// [`ObjectError::BadConfig`] naming the key.
    pub fn check(&self, kind: &str) -> Result<penelope_drivers::netft::NetFtConfig, ObjectError> {
        let address = penelope_drivers::netft::parse_address(&self.address)
            .map_err(|e| bad(kind, format!("`address`: {e}")))?;
        check_range(kind, "counts_per_force", self.counts_per_force, 1e-3, 1e12)?;
        check_range(
            kind,
            "counts_per_torque",
            self.counts_per_torque,
            1e-3,
            1e12,
        )?;
        for x in &self.mount_xyz {
            check_range(kind, "mount_xyz", *x, -2.0, 2.0)?;
        }
        for x in &self.mount_rpy_deg {
            check_range(kind, "mount_rpy_deg", *x, -360.0, 360.0)?;
        }
        check_int(kind, "timeout_ms", self.timeout_ms, 1, 10_000)?;
        check_int(kind, "max_gap", self.max_gap.into(), 0, 1_000_000)?;
        let mut c = penelope_drivers::netft::NetFtConfig::new(address);
        c.calibration = penelope_drivers::netft::Calibration {
            counts_per_force: self.counts_per_force,
            counts_per_torque: self.counts_per_torque,
        };
        c.mount = self.mount();
        c.timeout = std::time::Duration::from_millis(self.timeout_ms);
        c.max_gap = self.max_gap;
        c.bias_on_start = self.bias_on_start;
        Ok(c)
    }

    /// The sensor frame's pose in the tool frame.
    pub fn mount(&self) -> Pose {
        let [r, p, y] = self.mount_rpy_deg.map(f64::to_radians);
        Pose::from_parts(
            nalgebra::Translation3::new(self.mount_xyz[0], self.mount_xyz[1], self.mount_xyz[2]),
            nalgebra::UnitQuaternion::from_euler_angles(r, p, y),
        )
    }
}

/// A `sensor/netft`: its checked settings, and the open stream while configured.
struct NetFtObj {
    config: NetFtConfig,
    sensor: Option<NetFt>,
}

/// Makes a `sensor/netft` from its configuration text (checked; nothing opened).
fn make(a: &MakeArgs<'_>) -> Result<KindState, ObjectError> {
    let k = a.kind.as_str();
    let cfg: NetFtSensorConfig = parse(k, a.config)?;
    let config = cfg.check(k)?;
    Ok(KindState::LoopSensor(Box::new(NetFtObj {
        config,
        sensor: None,
    })))
}

impl LoopSensorObject for NetFtObj {
    /// Opens the box's stream and waits (bounded) for its first record.
    fn configure(&mut self) -> Result<(), ObjectError> {
        let address = self.config.address;
        let ft = NetFt::open(self.config)
            .map_err(|e| ObjectError::device(format!("net f/t at {address}"), e))?;
        if !ft.wait_for_records(1, FIRST_RECORD_TIMEOUT) {
            return Err(ObjectError::DeviceRefused(format!(
                "net f/t at {address}: no RDT record within {} ms (is the box, or `penelope \
                 netft-sim`, there?)",
                FIRST_RECORD_TIMEOUT.as_millis()
            )));
        }
        self.sensor = Some(ft);
        Ok(())
    }

    /// A stop request to the box, and the I/O thread joined.
    fn release(&mut self) {
        self.sensor = None;
    }

    fn mount(&self) -> Pose {
        self.config.mount
    }

    fn relations(&self) -> Vec<(String, String)> {
        let mut out = vec![("address".to_string(), self.config.address.to_string())];
        if let Some(ft) = &self.sensor {
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

    fn method(&self, kind: Kind, m: SensorMethod) -> Result<Reply, ObjectError> {
        let Some(ft) = &self.sensor else {
            return Err(ObjectError::NotReady("the sensor is not configured".into()));
        };
        match m {
            SensorMethod::Read => ft
                .read(penelope_rt_core::clock::MonotonicClock::read())
                .map(|w| Reply::Wrench(WrenchMsg::from(&w)))
                .map_err(|e| ObjectError::device(format!("net f/t at {}", self.config.address), e)),
            SensorMethod::Bias => {
                ft.request_bias();
                Ok(Reply::Unit)
            }
            other => Err(ObjectError::Unsupported {
                kind: kind.as_str().into(),
                method: format!(
                    "{other:?} (a Net F/T measures the world; it takes no probe and is read in \
                     the loop of the controller bound to it)"
                )
                .into(),
            }),
        }
    }

    fn loop_reader(&self) -> Result<LoopSensorReader, ObjectError> {
        match &self.sensor {
            Some(ft) => Ok(LoopSensorReader::new(ft.reader())),
            None => Err(ObjectError::NotReady("the sensor is not configured".into())),
        }
    }
}
