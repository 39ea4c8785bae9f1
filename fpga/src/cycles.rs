//! The cycle model: how many 40 MHz clock cycles the RTL takes, state by state.
//!
//! The RTL (`rtl/penelope_kin.v`) is one finite-state machine with three shared 25x25
//! multipliers and one sine/cosine unit (table ROM + two 17x10 multipliers). Its schedule:
//!
//! | phase | cycles | what happens |
//! |---|---|---|
//! | start | 1 | the edge that samples `start` latches the inputs, `R = I`, `p = 0` |
//! | per joint (x6) | 1 | `theta = q + offset`, sine and cosine into registers; `z_j`, `o_j` kept |
//! | | 6 | one rotation entry per cycle (`n0_i`, then `n1_i`): 2 multipliers |
//! | | 3 | one position entry per cycle: 2 multipliers; the last one commits `R` |
//! | force: rotate wrench | 6 | one `f0_i` or `m0_i` per cycle: 3 multipliers |
//! | force: per joint (x6) | 3 | one `mj_i` per cycle: 2 multipliers |
//! | | 1 | `tau_j = z_j . mj`: 3 multipliers |
//!
//! `done` rises on the edge that ends the last phase, and the machine accepts the next `start`
//! on the following edge, so throughput is one result per latency. Host transfers (DMA FIFOs)
//! are not modelled. The co-simulation test checks every count against the RTL.

use crate::dh::JOINTS;

/// The board's clock, Hz (NI PCI-7831R onboard clock).
pub const CLOCK_HZ: f64 = 40.0e6;

/// Cycles per joint of the forward kinematics: angle, 6 rotation entries, 3 position entries.
pub const FK_CYCLES_PER_JOINT: u32 = 1 + 6 + 3;
/// Cycles of one forward kinematics, from the edge that samples `start` to the edge that raises
/// `done`, both included.
pub const FK_CYCLES: u32 = 1 + JOINTS as u32 * FK_CYCLES_PER_JOINT;
/// Cycles the force path adds after the forward kinematics: wrench rotation, then per joint three
/// moment components and one torque.
pub const FORCE_EXTRA_CYCLES: u32 = 6 + JOINTS as u32 * (3 + 1);
/// Cycles of one force transformation (forward kinematics included).
pub const FORCE_CYCLES: u32 = FK_CYCLES + FORCE_EXTRA_CYCLES;

/// Seconds for `cycles` at [`CLOCK_HZ`].
pub fn seconds(cycles: u32) -> f64 {
    cycles as f64 / CLOCK_HZ
}

/// Results per second when one result takes `cycles` (the machine is not pipelined).
pub fn per_second(cycles: u32) -> f64 {
    CLOCK_HZ / cycles as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_schedule_adds_up() {
        assert_eq!(FK_CYCLES, 61);
        assert_eq!(FORCE_CYCLES, 91);
        assert!((seconds(FK_CYCLES) - 1.525e-6).abs() < 1e-12);
        assert!((per_second(FORCE_CYCLES) - 439_560.44).abs() < 0.01);
    }
}
