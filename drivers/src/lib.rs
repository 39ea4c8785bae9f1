#![doc = include_str!("../README.md")]
//!
//! # A tour
//!
//! - [`model`]: robot models from DH tables (PUMA 560, PUMA 200, FRHC, or any lab's file):
//!   kinematics, inverse kinematics, dynamics.
//! - [`sim`]: the simulated lab: rigid-body plants, a simulated board, environments, a virtual
//!   operator and a virtual force sensor.
//! - [`galil`]: the Galil DMC protocol over any byte stream, its `Board`, and an emulator.
//! - [`netft`]: the ATI Net F/T six-axis force/torque sensor over UDP (RDT), and an emulator.
//! - [`pinhole`]: a camera's pinhole intrinsics, shared by the simulated and V4L2 cameras.
//! - [`v4l2`]: cameras on Linux V4L2 (UVC webcams), their kernel capture timestamps on the
//!   node's clock, frames as JPEG.
#![warn(missing_docs)]

pub mod galil;
pub mod model;
pub mod netft;
pub mod pinhole;
pub mod sim;
pub mod v4l2;
