//! Sensors: things that measure the world.

use crate::error::Error;
use crate::spatial::{Pose, Wrench};
use crate::time::Timestamp;

/// A sensor producing one reading per call.
///
/// # Real-time
/// Implementations called from the control thread must not block; a sensor on a slow link keeps
/// its own I/O thread, as boards do.
pub trait Sensor {
    /// The sensor's error type.
    type Error: Error;
    /// What one reading holds.
    type Reading: Copy;

    /// The latest reading at time `now`.
    ///
    /// # Errors
    /// A device or communication error, or [`crate::ErrorKind::NonFinite`] for a NaN reading:
    /// the caller never sees a non-finite value as a measurement.
    fn read(&mut self, now: Timestamp) -> Result<Self::Reading, Self::Error>;
}

/// A six-axis force/torque sensor, reporting in its own frame ([`crate::Frame::Sensor`]).
pub trait ForceSensor: Sensor<Reading = Wrench> {
    /// Where the sensor frame sits on the robot's flange: maps sensor coordinates to flange
    /// coordinates (metres, rotation).
    fn mount(&self) -> Pose;

    /// Takes the current reading as the zero (tare): later readings have it subtracted.
    ///
    /// # Errors
    /// As for [`Sensor::read`].
    fn tare(&mut self, now: Timestamp) -> Result<(), Self::Error>;
}
