#![doc = include_str!("../README.md")]
//!
//! # A tour
//!
//! - [`model`]: robot models from DH tables (PUMA 560, PUMA 200, FRHC, or any lab's file):
//!   kinematics, inverse kinematics, dynamics.
//! - [`galil`]: the Galil DMC protocol over any byte stream, its `Board`, and an emulator.
#![warn(missing_docs)]

pub mod galil;
pub mod model;
