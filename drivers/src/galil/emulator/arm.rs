//! A robot arm behind the emulated axes: axis `j` drives joint `j` of a rigid-body plant
//! ([`RigidBodyPlant`], gravity and friction included) instead of a bare motor.
//!
//! Each axis is wired as a DMC installer wires one for position servo: a positive output volt
//! drives the encoder count up. So the joint torque is `volts × newton_metres_per_volt ×
//! sign(counts per radian)` (the sign is the gear's and the encoder's direction), and the
//! encoder reads `(q - zero) × counts per radian` — the model's own scaling.
//!
//! With [`ArmConfig::brakes`], a joint whose amplifier is off is held by its brake, as a PUMA's
//! arm-power brakes hold it: the arm does not fall while the board is configured or after a
//! watchdog trip.

use std::time::Duration;

use penelope_hal::robot::Kinematics as _;
use penelope_hal::{JointVector, MAX_JOINTS, Timestamp};

use crate::model::SerialRobotModel;
use crate::sim::FreeSpace;
use crate::sim::plant::{PlantConfig, RigidBodyPlant};

use super::super::command::MAX_GALIL_AXES;

/// The arm an emulated DMC drives.
#[derive(Clone, Debug, PartialEq)]
pub struct ArmConfig {
    /// The robot (its dynamics, gravity, friction and encoder scaling are used).
    pub model: SerialRobotModel,
    /// Joint positions where the encoders read zero (the arm is there at power-up), rad.
    pub zero: JointVector,
    /// Joint torque per output volt, N·m/V (amplifier gain × motor constant × |gear ratio|);
    /// positive, the direction comes from the model.
    pub newton_metres_per_volt: [f64; MAX_GALIL_AXES],
    /// Include the model's joint friction.
    pub friction: bool,
    /// A joint whose amplifier is off is held still by a brake.
    pub brakes: bool,
}

impl ArmConfig {
    /// `model` at rest in `zero`, with the same torque per volt on every axis.
    pub fn new(model: SerialRobotModel, zero: JointVector, newton_metres_per_volt: f64) -> Self {
        ArmConfig {
            model,
            zero,
            newton_metres_per_volt: [newton_metres_per_volt; MAX_GALIL_AXES],
            friction: true,
            brakes: true,
        }
    }
}

/// The arm being simulated.
#[derive(Clone, Debug)]
pub(super) struct Arm {
    config: ArmConfig,
    plant: RigidBodyPlant<SerialRobotModel>,
    joints: usize,
    /// Where each braked joint is held.
    braked: [Option<f64>; MAX_JOINTS],
}

impl Arm {
    pub(super) fn new(config: ArmConfig, period: f64) -> Arm {
        let plant_config = PlantConfig {
            substep: Duration::from_secs_f64(period.max(1e-5)),
            friction: config.friction,
            ..PlantConfig::default()
        };
        let plant = RigidBodyPlant::new(
            config.model.clone(),
            plant_config,
            config.zero,
            Timestamp::ZERO,
        );
        let joints = config.model.joint_count().min(MAX_JOINTS);
        Arm {
            config,
            plant,
            joints,
            braked: [None; MAX_JOINTS],
        }
    }

    /// Joints driven (the first axes).
    pub(super) fn joints(&self) -> usize {
        self.joints
    }

    /// Applies `volts` on the axes up to simulated time `now` (seconds); `on[j]`: joint `j`'s
    /// amplifier is on (off and braked: held still).
    pub(super) fn advance(&mut self, now: f64, volts: &[f64], on: &[bool]) {
        let mut tau = JointVector::zeros();
        let position = self.plant.snapshot().joints.position;
        for j in 0..self.joints {
            let powered = on.get(j).copied().unwrap_or(false);
            if self.config.brakes && !powered {
                self.braked[j].get_or_insert(position[j]);
                continue;
            }
            self.braked[j] = None;
            let v = volts.get(j).copied().unwrap_or(0.0);
            let direction = self.config.model.counts_per_radian(j).signum();
            tau[j] = v * self.config.newton_metres_per_volt[j] * direction;
        }
        let t = Timestamp::from_nanos((now.max(0.0) * 1e9) as u64);
        self.plant.advance_to(t, &tau, &mut FreeSpace);
        for (j, held) in self.braked.iter().enumerate() {
            if let Some(q) = held {
                self.plant.hold_joint(j, *q);
            }
        }
    }

    /// Encoder position (counts) and velocity (counts/s) of joint `j`.
    pub(super) fn encoder(&self, j: usize) -> (f64, f64) {
        let s = &self.plant.snapshot().joints;
        let cpr = self.config.model.counts_per_radian(j);
        (
            (s.position[j] - self.config.zero[j]) * cpr,
            s.velocity[j] * cpr,
        )
    }

    /// The arm's joint positions, rad.
    pub(super) fn joint_positions(&self) -> JointVector {
        self.plant.snapshot().joints.position
    }
}
