//! The cycle model: how many 40 MHz clock cycles the RTL takes, phase by phase.
//!
//! The RTL (`rtl/penelope_kin.v`) decides one operation per cycle, registers that decision
//! (operand codes and datapath actions: the datapath runs one edge behind the state machine),
//! and issues it into three shared 25x25 multipliers followed by a three-stage pipeline (M: products registered; A: exact sum
//! registered; Q: quantized into the destination register), so a result is written
//! [`PIPELINE_DEPTH`] edges after its issue. The sine/cosine unit (block-RAM table, registered
//! read) has three stages and works one joint ahead. The schedule, edges counted from the one that
//! samples `start`:
//!
//! | phase | cycles | what happens |
//! |---|---|---|
//! | start | 1 | the edge that samples `start` latches the inputs, `R = I`, `p = 0` |
//! | decision | 1 | the datapath runs one edge behind the state machine |
//! | sine/cosine warm-up | 3 | the ROM reads joint 0's angle; the interpolation products; sine and cosine loaded |
//! | per joint (x6) | 6 | one rotation entry issued per cycle (`n0_i`, then `n1_i`): 2 multipliers |
//! | | 3 | one position entry per cycle: 2 multipliers; the last commits `R`, and joint `j+1`'s sine and cosine are loaded |
//! | drain | 2 | the last position entry goes through A and Q; `done` rises with it |
//! | force: rotate wrench | 6 | one `f0_i` or `m0_i` issued per cycle: 3 multipliers (overlaps the drain) |
//! | force: moments (x6) | 3 | one `mj_i` per cycle: 2 multipliers |
//! | force: torques (x6) | 1 | `tau_j = z_j . mj`: 3 multipliers, issued after joint `j+1`'s moments |
//! | force: bubble | 1 | `tau_5` waits for joint 5's last moment |
//! | drain | 2 | as above |
//!
//! No operation reads a register before the Q stage has written it (the order above
//! guarantees it; the co-simulation checks every word). `done` rises on the edge that writes
//! the last result, and the machine accepts the next `start` on the following edge, so
//! throughput is one result per latency. Host transfers (DMA FIFOs) are not modelled. The
//! co-simulation test checks every count against the RTL.

use crate::dh::JOINTS;

/// The board's clock, Hz (NI PCI-7831R onboard clock).
pub const CLOCK_HZ: f64 = 40.0e6;

/// Edges from an operation's issue to the write of its result (M, A, Q stages).
pub const PIPELINE_DEPTH: u32 = 3;
/// Cycles before the first joint's first issue: the start edge, the registered decision, and
/// the sine/cosine warm-up.
pub const FK_PROLOGUE_CYCLES: u32 = 1 + 1 + 3;
/// Operations issued per joint of the forward kinematics: 6 rotation entries, 3 positions.
pub const FK_ISSUES_PER_JOINT: u32 = 6 + 3;
/// Cycles of one forward kinematics, from the edge that samples `start` to the edge that raises
/// `done`, both included.
pub const FK_CYCLES: u32 =
    FK_PROLOGUE_CYCLES + JOINTS as u32 * FK_ISSUES_PER_JOINT + (PIPELINE_DEPTH - 1);
/// Operations the force path issues: wrench rotation, then per joint three moment components
/// and one torque, and one bubble before the last torque.
pub const FORCE_ISSUES: u32 = 6 + JOINTS as u32 * (3 + 1) + 1;
/// Cycles the force path adds after the forward kinematics (its issues start on the edge after
/// the last FK issue, so the FK drain overlaps them).
pub const FORCE_EXTRA_CYCLES: u32 = FORCE_ISSUES;
/// Cycles of one force transformation (forward kinematics included).
pub const FORCE_CYCLES: u32 = FK_CYCLES + FORCE_EXTRA_CYCLES;

/// Seconds for `cycles` at [`CLOCK_HZ`].
pub fn seconds(cycles: u32) -> f64 {
    cycles as f64 / CLOCK_HZ
}

/// Results per second when one result takes `cycles` (requests do not overlap).
pub fn per_second(cycles: u32) -> f64 {
    CLOCK_HZ / cycles as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_schedule_adds_up() {
        assert_eq!(FK_CYCLES, 61);
        assert_eq!(FORCE_CYCLES, 92);
        assert!((seconds(FK_CYCLES) - 1.525e-6).abs() < 1e-12);
        assert!((per_second(FORCE_CYCLES) - 434_782.61).abs() < 0.01);
    }
}
