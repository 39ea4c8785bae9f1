//! Sensor kinds read in the control loop's own thread (a device such as a Net F/T): what the
//! registry asks of their objects. Such a kind is its own module and one catalog line: the
//! registry configures, releases, describes and calls it, and gives its reader to a loop,
//! through [`LoopSensorObject`], without knowing the kind.

use penelope_protocol::proto::{Reply, SensorMethod};

use crate::objects::error::ObjectError;
use crate::objects::kinds::Kind;
use crate::objects::runtime::LoopSensorReader;

/// The object of a sensor kind read in the control loop's own thread.
pub(crate) trait LoopSensorObject: Send {
    /// Opens the device (`configure`), bounded in time.
    ///
    /// # Errors
    /// [`ObjectError::Device`] or [`ObjectError::DeviceRefused`] when it cannot be reached.
    fn configure(&mut self) -> Result<(), ObjectError>;

    /// Closes it (`cleanup`, `shutdown`, `reset`): its threads stop and are joined.
    fn release(&mut self);

    /// Where the sensor sits on the flange (its frame in the tool frame).
    fn mount(&self) -> penelope_hal::Pose;

    /// What `describe` shows of it, as `(relation, value)` pairs.
    fn relations(&self) -> Vec<(String, String)>;

    /// A sensor method from the non-real-time side (`read`, `bias`, ...), on a configured
    /// object.
    ///
    /// # Errors
    /// [`ObjectError::Unsupported`] for a method the kind has not; the device's error.
    fn method(&self, kind: Kind, method: SensorMethod) -> Result<Reply, ObjectError>;

    /// The reader a control loop reads it with, while configured.
    ///
    /// # Errors
    /// [`ObjectError::NotReady`] when it is not configured.
    fn loop_reader(&self) -> Result<LoopSensorReader, ObjectError>;
}
