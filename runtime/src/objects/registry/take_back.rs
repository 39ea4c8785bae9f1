//! A stopped loop taken back: its board to the robot's objects, its teleoperation end to its
//! channel, its users cleared; what a robot is left holding, in words.

use penelope_hal::{Board, LifecycleState};
use penelope_rt_core::safety::TeleopRole;

use crate::objects::registry::{KindState, Object, Registry};
use crate::objects::runtime::JointBoard;

impl Registry {
    /// Takes a stopped loop of `controller` back: its board to the robot's objects, its
    /// teleoperation channel's end to the channel, and clears the users. A slave stopped on
    /// purpose stays where it is, held by its board's servo; a master, and a slave stopped by a
    /// fault on a board without a servo of its own, gets zero torque and its amplifiers off.
    /// What a thread took down with it is marked `unconfigured` (configure it again). Returns
    /// how the robot was left, in words.
    pub fn take_back(
        &mut self,
        stopped: crate::objects::runtime::StoppedLoop,
        controller: &str,
        after_fault: bool,
    ) -> &'static str {
        let (robot, trajectory) = match self.objects.get(controller).map(|o| &o.body) {
            Some(KindState::Controller(c)) => (
                c.robot.clone().unwrap_or_default(),
                c.trajectory.clone().unwrap_or_default(),
            ),
            _ => (String::new(), String::new()),
        };
        let slave = self.role_of(controller) == Some(TeleopRole::Slave);
        let said = match stopped.control {
            Some(mut t) => {
                let hold = if after_fault {
                    t.holds_with_board_servo()
                } else {
                    slave && t.hand_to_board_servo()
                };
                self.give_back_after_fault(t.into_loop().into_board(), &robot, hold);
                if hold {
                    "held by its board's servo"
                } else {
                    "zero torque, amplifiers off"
                }
            }
            None => {
                if let Ok(o) = self.get_mut(&robot) {
                    o.state = LifecycleState::Unconfigured;
                }
                "its board went down with the thread; configure the robot again"
            }
        };
        let end = stopped.comm.and_then(|c| c.into_teleop_end());
        if let Some(Object {
            body: KindState::Teleop(t),
            state,
            ..
        }) = self.objects.get_mut(&trajectory)
            && let Some(link) = t.link.as_mut()
        {
            match end {
                Some(end) => link.put_back(end),
                None => {
                    // The end went down with its thread: new cells at the next configure.
                    t.link = None;
                    *state = LifecycleState::Unconfigured;
                }
            }
        }
        self.release_users(controller);
        said
    }

    /// The role of the robot controller `controller` drives, if it has one.
    pub fn role_of(&self, controller: &str) -> Option<TeleopRole> {
        let Some(KindState::Controller(c)) = self.objects.get(controller).map(|o| &o.body) else {
            return None;
        };
        self.robot(c.robot.as_deref()?).ok().map(|r| r.role)
    }

    /// Gives a stopped loop's board back to the objects it came from, amplifiers off.
    pub fn give_back(&mut self, board: JointBoard, robot: &str) {
        self.give_back_after_fault(board, robot, false);
    }

    /// Gives a failed loop's board back as the loop left it: still holding with its own servo
    /// when `holding` (a position board the loop stopped at its measured pose), else with its
    /// amplifiers off.
    pub fn give_back_after_fault(&mut self, mut board: JointBoard, robot: &str, holding: bool) {
        if !holding {
            let _ = board.set_enabled(false);
        }
        match board {
            JointBoard::Sim(drive) | JointBoard::Fpga(drive) => {
                let body = drive.into_body();
                if let Some(Object {
                    body: KindState::Robot(r),
                    ..
                }) = self.objects.get_mut(robot)
                {
                    r.body = Some(body);
                }
            }
            JointBoard::Galil(set) => {
                for (name, b) in set.boards {
                    if let Some(Object {
                        body: KindState::Galil(g),
                        ..
                    }) = self.objects.get_mut(&name)
                    {
                        g.board = Some(b);
                    }
                }
            }
        }
    }

    /// Clears `controller` from every object's users.
    pub fn release_users(&mut self, controller: &str) {
        for o in self.objects.values_mut() {
            o.users.remove(controller);
        }
    }
}
