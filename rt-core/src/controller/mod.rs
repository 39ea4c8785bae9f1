//! Control laws implementing [`penelope_hal::Controller`], and [`ControllerSet`], the collection a
//! control loop owns and switches between by index.
//!
//! - [`JointPid`]: joint-space PID with gravity compensation.
//! - [`JointPositionServo`]: position targets for a board's own servo.
//! - [`JointGroups`]: different laws on different joints of one robot.

use penelope_hal::Controller;

mod joint_groups;
mod joint_pid;
mod joint_position;

pub use joint_groups::{JointGroups, JointGroupsError};
pub use joint_pid::{JointPid, JointPidGains};
pub use joint_position::JointPositionServo;

/// Several controllers owned by one control loop, addressed by index. Switching is a change of
/// index: nothing is allocated or moved.
///
/// Implemented for arrays of one controller type (`[JointPid; 2]`), tuples of up to four different
/// controller types, slices of `&mut dyn Controller`, and (with `std`) `Vec<Box<dyn Controller +
/// Send>>` (allocated before the loop starts).
pub trait ControllerSet {
    /// How many controllers there are.
    fn count(&self) -> usize;

    /// Controller `index`, or `None` past the end.
    ///
    /// # Real-time
    /// Constant time, no allocation.
    fn get_mut(&mut self, index: usize) -> Option<&mut dyn Controller>;
}

impl<C: Controller, const N: usize> ControllerSet for [C; N] {
    fn count(&self) -> usize {
        N
    }
    fn get_mut(&mut self, index: usize) -> Option<&mut dyn Controller> {
        self.as_mut_slice()
            .get_mut(index)
            .map(|c| c as &mut dyn Controller)
    }
}

impl ControllerSet for [&mut dyn Controller] {
    fn count(&self) -> usize {
        self.len()
    }
    fn get_mut(&mut self, index: usize) -> Option<&mut dyn Controller> {
        match <[&mut dyn Controller]>::get_mut(self, index) {
            Some(c) => Some(&mut **c),
            None => None,
        }
    }
}

impl<S: ControllerSet + ?Sized> ControllerSet for &mut S {
    fn count(&self) -> usize {
        (**self).count()
    }
    fn get_mut(&mut self, index: usize) -> Option<&mut dyn Controller> {
        (**self).get_mut(index)
    }
}

#[cfg(feature = "std")]
impl ControllerSet for std::vec::Vec<std::boxed::Box<dyn Controller + Send>> {
    fn count(&self) -> usize {
        self.len()
    }
    fn get_mut(&mut self, index: usize) -> Option<&mut dyn Controller> {
        match self.as_mut_slice().get_mut(index) {
            Some(c) => Some(&mut **c),
            None => None,
        }
    }
}

macro_rules! tuple_set {
    ($n:expr; $($t:ident $i:tt),+) => {
        impl<$($t: Controller),+> ControllerSet for ($($t,)+) {
            fn count(&self) -> usize {
                $n
            }
            fn get_mut(&mut self, index: usize) -> Option<&mut dyn Controller> {
                match index {
                    $($i => Some(&mut self.$i),)+
                    _ => None,
                }
            }
        }
    };
}

tuple_set!(1; A 0);
tuple_set!(2; A 0, B 1);
tuple_set!(3; A 0, B 1, C 2);
tuple_set!(4; A 0, B 1, C 2, D 3);
