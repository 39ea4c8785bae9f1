//! `board/fpga`: the NI PCI-7831R in front of the FRHC. It reads the joint encoders and drives
//! the motor outputs of the simulated plant behind it (the `board/sim` plant, the same code),
//! and computes the forward kinematics and the force transformation `tau = J^T F` with the
//! bit-exact model of its pipelines ([`penelope_fpga::FpgaKinematics`]). A robot whose joints
//! are on it computes with the board's kinematics
//! ([`RobotKinematics::FpgaBoard`](super::kinematics::RobotKinematics::FpgaBoard)), and its
//! control law's `J^T F` is the board's.
//!
//! # The latency model
//!
//! Every result reaches the host after the pipeline's cycles at 40 MHz
//! ([`penelope_fpga::cycles`]) and the DMA FIFO transfers that carry the words. A transfer
//! costs [`DMA_TRANSFER_NS`] (one FIFO read or write call through the driver, setting up the
//! bus-master transfer and its completion) plus [`DMA_WORD_PS`] per 32-bit element (one data
//! phase of the board's 32-bit, 33 MHz PCI bus, 132 MB/s peak). Both are modelling assumptions
//! of this crate, not measurements of a board: the reference gives no transfer figures.
//!
//! | stage | on the board | to the board | to the host |
//! |---|---|---|---|
//! | [`FK`]: encoders latched, pose and Jacobian frames | 61 cycles | - | 54 words: 6 counts, `p` 3, `R` 9, `z_j` 18, `o_j` 18 |
//! | [`FK_FORCE`]: `tau = J^T F` for the law's wrench | 92 cycles | 6 words: the wrench | 6 words: the torques |
//! | [`COMMAND`]: the motor outputs | - | 6 words: the DAC codes | - |
//!
//! A tick's command therefore reaches the motors [`command_delay_ns`] after its encoders were
//! latched (the host's own computing time not counted); the loop's board models that by
//! holding the previous command on the plant for that long.
//!
//! # Real-time
//! Everything here is constant arithmetic; nothing allocates but [`describe`].

use penelope_fpga::cycles::{CLOCK_HZ, FK_CYCLES, FORCE_CYCLES};

/// One DMA FIFO transfer's fixed cost, ns (an assumption: see the module docs).
pub const DMA_TRANSFER_NS: u64 = 5_000;

/// One 32-bit element's cost on the bus, ps (32-bit PCI at 33 MHz: one element per clock).
pub const DMA_WORD_PS: u64 = 30_303;

/// The board's clock period, ps (40 MHz).
pub const CYCLE_PS: u64 = (1.0e12 / CLOCK_HZ) as u64;

/// One exchange between the host and the board: words to the board, cycles on it, words back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stage {
    /// What it computes, for people.
    pub name: &'static str,
    /// Clock cycles on the board.
    pub cycles: u32,
    /// 32-bit elements the host writes to the board first (0: no transfer).
    pub words_to_board: u32,
    /// 32-bit elements the host reads back (0: no transfer).
    pub words_to_host: u32,
}

/// The forward kinematics of the latched encoders, read back with the frames the host forms
/// the Jacobian from.
pub const FK: Stage = Stage {
    name: "fk",
    cycles: FK_CYCLES,
    words_to_board: 0,
    words_to_host: 6 + 3 + 9 + 18 + 18,
};

/// The force transformation of the law's wrench (the pipeline runs the kinematics again).
pub const FK_FORCE: Stage = Stage {
    name: "fk+force",
    cycles: FORCE_CYCLES,
    words_to_board: 6,
    words_to_host: 6,
};

/// The motor outputs written to the board.
pub const COMMAND: Stage = Stage {
    name: "command",
    cycles: 0,
    words_to_board: 6,
    words_to_host: 0,
};

fn transfer_ns(words: u32) -> u64 {
    if words == 0 {
        0
    } else {
        DMA_TRANSFER_NS + (u64::from(words) * DMA_WORD_PS).div_ceil(1000)
    }
}

impl Stage {
    /// Time on the board, ns (rounded up).
    pub const fn compute_ns(&self) -> u64 {
        (self.cycles as u64 * CYCLE_PS).div_ceil(1000)
    }

    /// Time on the bus, ns (rounded up per transfer).
    pub fn transfer_ns(&self) -> u64 {
        transfer_ns(self.words_to_board) + transfer_ns(self.words_to_host)
    }

    /// From the host's request (or the encoder latch) to the result on the host, ns.
    pub fn latency_ns(&self) -> u64 {
        self.compute_ns() + self.transfer_ns()
    }

    /// One line for people: cycles, time on the board, on the bus, in all.
    pub fn describe(&self) -> String {
        format!(
            "{} cycles = {:.3} us on the board + {:.3} us DMA ({} words in, {} out) = {:.3} us",
            self.cycles,
            self.compute_ns() as f64 / 1e3,
            self.transfer_ns() as f64 / 1e3,
            self.words_to_board,
            self.words_to_host,
            self.latency_ns() as f64 / 1e3
        )
    }
}

/// From the encoder latch to the tick's command on the motors, ns: [`FK`], [`FK_FORCE`] and
/// [`COMMAND`] one after the other.
pub fn command_delay_ns() -> u64 {
    FK.latency_ns() + FK_FORCE.latency_ns() + COMMAND.latency_ns()
}

/// What `describe` shows of an fpga board: one line per stage and the command delay.
pub fn describe() -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = [FK, FK_FORCE]
        .iter()
        .map(|s| (s.name.to_string(), s.describe()))
        .collect();
    out.push((
        "command-delay".to_string(),
        format!(
            "{:.3} us from the encoder latch to the motors (fk, fk+force, {:.3} us command write)",
            command_delay_ns() as f64 / 1e3,
            COMMAND.latency_ns() as f64 / 1e3
        ),
    ));
    out
}

/// Why a robot cannot be on an fpga board.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FpgaBoardError {
    /// The board computes the FRHC's kinematics only.
    #[error(
        "board/fpga `{board}` computes the FRHC's kinematics; robot `{robot}` is a {model} (map it onto board/sim or board/galil)"
    )]
    NotTheFrhc {
        /// The board.
        board: String,
        /// The robot.
        robot: String,
        /// The robot's model.
        model: String,
    },
    /// The board computes the whole chain, so every joint must be on it.
    #[error(
        "robot `{robot}` has joints on board/fpga `{board}` and on `{other}`: the FPGA computes the whole chain, so map every joint onto the one board"
    )]
    SplitChain {
        /// The robot.
        robot: String,
        /// The fpga board.
        board: String,
        /// Another board its joints are on.
        other: String,
    },
}

/// Checks a robot's boards: `Ok(Some(board))` when its joints are on the fpga board `board`,
/// `Ok(None)` when no fpga board is among them. `boards` are the boards its joints are mapped
/// onto, each with whether it is an fpga board.
///
/// # Errors
/// [`FpgaBoardError`] for a robot other than the FRHC on an fpga board, or one whose joints are
/// split between an fpga board and another.
pub fn robot_on_boards(
    robot: &str,
    model: &str,
    boards: &[(&str, bool)],
) -> Result<Option<String>, FpgaBoardError> {
    let Some((fpga, _)) = boards.iter().find(|(_, is_fpga)| *is_fpga) else {
        return Ok(None);
    };
    if model != "frhc" {
        return Err(FpgaBoardError::NotTheFrhc {
            board: fpga.to_string(),
            robot: robot.to_string(),
            model: model.to_string(),
        });
    }
    if let Some((other, _)) = boards.iter().find(|(b, _)| b != fpga) {
        return Err(FpgaBoardError::SplitChain {
            robot: robot.to_string(),
            board: fpga.to_string(),
            other: other.to_string(),
        });
    }
    Ok(Some(fpga.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stages_add_up_from_the_cycle_model_and_the_bus() {
        assert_eq!(CYCLE_PS, 25_000);
        assert_eq!(FK.compute_ns(), 1_525);
        assert_eq!(FK_FORCE.compute_ns(), 2_300);
        // 54 words: one transfer, 1.636 us of data phases.
        assert_eq!(FK.transfer_ns(), 5_000 + 1_637);
        assert_eq!(FK.latency_ns(), 8_162);
        // Two transfers of 6 words each.
        assert_eq!(FK_FORCE.latency_ns(), 2_300 + 2 * (5_000 + 182));
        assert_eq!(COMMAND.latency_ns(), 5_182);
        assert_eq!(command_delay_ns(), 8_162 + 12_664 + 5_182);
        let shown = describe();
        assert_eq!(shown[0].0, "fk");
        assert!(shown[0].1.starts_with("61 cycles = 1.525 us"), "{shown:?}");
        assert!(shown[1].1.starts_with("92 cycles = 2.300 us"), "{shown:?}");
    }

    #[test]
    fn only_the_frhc_goes_on_the_board_and_all_of_it() {
        assert_eq!(
            robot_on_boards("arm", "puma560", &[("io", false)]),
            Ok(None)
        );
        assert_eq!(
            robot_on_boards("frhc", "frhc", &[("io", true)]),
            Ok(Some("io".into()))
        );
        let e = robot_on_boards("arm", "puma200", &[("io", true)]).unwrap_err();
        assert!(matches!(e, FpgaBoardError::NotTheFrhc { .. }));
        assert!(e.to_string().contains("puma200"), "{e}");
        let e = robot_on_boards("frhc", "frhc", &[("io", true), ("sim", false)]).unwrap_err();
        assert!(matches!(e, FpgaBoardError::SplitChain { ref other, .. } if other == "sim"));
    }
}
