//! What runs while a controller is active: the control task (period `T_ctrl`, SCHED_FIFO), the
//! communication task (period `T_com`: the trajectory's reference into a latest-value cell), the
//! sensor feed (a non-real-time thread: a local sensor, or a sensor stream on the data plane)
//! and the telemetry pump (non-real-time: drains the telemetry ring, keeps the newest sample,
//! fans batches out).
//!
//! ```text
//!  GoTo ──ring──> comm task ──LatestCell<reference>──> control task ──ring<telemetry>──> pump ──> outboxes
//!                    ^ LatestCell<sample>                  │  ^ LatestCell<wrench>
//!                    └─────────────────────────────────────┤  └── sensor feed <── sensor stream (UDP)
//!                                  LatestCell<sample> ─────┘
//! ```
//!
//! [`ControlTask::tick`] is the whole per-tick body of the control thread; it is public so a test
//! can run it on a simulated clock under a counting allocator.
//!
//! Why the reference is produced in the communication task and not in the loop: DESIGN.md's two
//! threads per controller, and a GoTo or a new trajectory is then swapped without touching the
//! control thread; the control loop's watchdog holds the robot if that task ever stalls.

use std::sync::Arc;

use penelope_drivers::model::SerialRobotModel;
use penelope_drivers::sim::ToolContact;
use penelope_drivers::sim::board::SimBoard;
use penelope_rt_core::ring::ArcConsumer;

use super::kinematics::RobotKinematics;

/// Telemetry samples buffered between a control thread and its pump (4 s at 1 kHz).
pub const TELEMETRY_CAPACITY: usize = 4096;
/// Commands buffered towards a control thread.
pub const COMMAND_CAPACITY: usize = 16;
/// GoTo requests buffered towards a communication thread.
pub const GOTO_CAPACITY: usize = 4;
/// Gain changes buffered towards a control thread (a queue, not a latest value: changes to two
/// members of a joint group must both arrive).
pub const GAINS_CAPACITY: usize = 8;
/// Waypoints of a configured spline.
pub const SPLINE_CAPACITY: usize = crate::objects::kinds::MAX_WAYPOINTS;

/// A robot's simulated body: the rigid-body plant of its whole chain behind a simulated board
/// whose axes are the robot's joints in order (joints are dynamically coupled, so a robot whose
/// joints are spread over several simulated boards is still one plant).
pub type SimBody = SimBoard<SerialRobotModel, ToolContact>;

/// The command ring behind the loop's stop latch (an e-stop needs no room in the ring).
pub(crate) type Commands = penelope_rt_core::stop::StopAwareCommands<
    ArcConsumer<penelope_rt_core::control::ControlCommand, COMMAND_CAPACITY>,
    Arc<penelope_rt_core::stop::StopLatch>,
>;

mod board;
mod comm;
mod control;
mod frame_telemetry;
mod link_telemetry;
mod sensors;
mod telemetry;
mod threads;

pub use board::{GalilSet, JointBoard, JointBoardError, MAX_PLANT_STEP_NS, SimDrive, SimObserver};
pub use comm::{
    CommTask, GoToCommand, MAX_SERVO_STEP_RAD, MOVE_SETTLE_TIMEOUT, MOVE_SETTLED_RAD,
    MotionControl, MotionPort, MotionStatus, ServoTarget, TrajectoryFeed, TrajectoryGenerator,
    motion_port,
};
pub(crate) use control::Loop;
pub use control::{
    CellSensor, CellSensorError, ControlLaw, ControlTask, GainsUpdate, RobotLoop, RoutedGains,
    TelemetryPort,
};
pub use frame_telemetry::{
    FrameSink, FrameSubscriberStats, FrameSubscriptionSpec, FrameSubscriptions,
};
pub use link_telemetry::{LINK_PERIOD, LinkPump, LinkSubscriptions};
pub use sensors::{
    FeedStats, LoopSensorRead, LoopSensorReader, SensorFeed, SensorSource, VirtualSensor,
    run_sensor_feed,
};
pub use telemetry::{
    LoopShared, MAX_BATCH_RECORDS, Newest, Pump, Subscriptions, TickSink, record, run_pump,
};
pub use threads::{
    LoopFault, LoopThread, Running, StopMode, StoppedLoop, comm_body, control_body, guarded,
};
