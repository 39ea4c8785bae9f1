//! Which `board/fpga` a robot's joints are on, checked: the board computes the FRHC's whole
//! chain.

use crate::objects::error::ObjectError;
use crate::objects::fpga_board::robot_on_boards;
use crate::objects::{KindState, Registry};

impl Registry {
    /// The `board/fpga` robot `name`'s joints are on, if any (boards not yet created count as
    /// other boards).
    ///
    /// # Errors
    /// [`ObjectError::FpgaBoard`]: a robot other than the FRHC, or joints split between the
    /// fpga board and another.
    pub fn fpga_board_of(&self, name: &str) -> Result<Option<String>, ObjectError> {
        let r = self.robot(name)?;
        let boards: Vec<(&str, bool)> = r
            .maps
            .iter()
            .map(|(b, _)| {
                let fpga = self
                    .objects
                    .get(b)
                    .is_some_and(|o| matches!(&o.body, KindState::SimBoard(s) if s.fpga));
                (b.as_str(), fpga)
            })
            .collect();
        Ok(robot_on_boards(name, r.model.name(), &boards)?)
    }
}
