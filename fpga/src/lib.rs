#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]
#![warn(missing_docs)]

// The layers, bottom up (see the README for the tour):
//   fixed    - LabVIEW-style fixed-point words and the one `quantize` primitive
//   sincos   - sine/cosine of a binary angle from the committed table
//   dh       - the DH table as hardware words
//   pipeline - the forward-kinematics and force pipelines, node by node
//   cycles   - the 40 MHz cycle model of the RTL
//   reference- the f64 model of the same chain (the accuracy oracle)
//   kinematics - `FpgaKinematics`, the `penelope_hal::robot::Kinematics` implementation
//   cosim    - (std) driving the Verilog RTL in Verilator or Icarus Verilog
//   synthesis- (std) Yosys synthesis for the XC2V1000: resources and a datasheet timing estimate

pub mod cycles;
pub mod dh;
pub mod fixed;
pub mod kinematics;
pub mod pipeline;
pub mod reference;
pub mod sincos;
mod wide;

#[cfg(feature = "std")]
pub mod cosim;
#[cfg(feature = "std")]
pub mod synthesis;

pub use dh::{Alpha, DhParams, DhRow, DhTable, TableError};
pub use fixed::{FixedError, Format, Fx, Overflow, Rounding};
pub use kinematics::{FkRun, ForceRun, FpgaKinematics};
pub use pipeline::{FkWords, ForceWords};
