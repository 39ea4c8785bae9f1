#![doc = include_str!("../README.md")]
//!
//! # A tour
//!
//! - [`lab`]: the lab configuration file and the teleoperation run it describes (the demo).
#![warn(missing_docs)]

pub mod lab;
