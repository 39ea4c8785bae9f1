//! A lab: its configuration file, and the teleoperation run it describes.

pub mod config;
pub mod devices;
pub mod report;
pub mod run;

pub use config::{ConfigError, LabConfig, Law};
