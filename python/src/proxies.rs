//! The typed proxies of remote objects, as Python classes: a robot, a sensor, a controller,
//! and an object of any class (its lifecycle only).

use penelope_protocol::client::{
    BoardProxy, ControllerProxy, Lifecycle, ObjectProxy, RobotProxy, SensorProxy, TrajectoryProxy,
};
use penelope_protocol::net::conn::RpcError;
use penelope_protocol::proto::{Method, ReferenceMsg, Reply, TrajectoryMethod, parse_transition};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{Error, Result, bad_argument};
use crate::values;

/// Runs the lifecycle transition `word` (`configure`, `activate`, ...) on `p`.
pub fn transition<'py, P: Lifecycle + Sync>(
    py: Python<'py>,
    p: &P,
    word: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let t = parse_transition(word).ok_or_else(|| {
        bad_argument(format!(
            "unknown transition `{word}` (configure, activate, deactivate, cleanup, shutdown, reset)"
        ))
    })?;
    let info = py.detach(|| p.transition(t)).map_err(Error)?;
    values::object_info(py, &info)
}

/// `p`'s description.
pub fn describe<'py, P: Lifecycle + Sync>(py: Python<'py>, p: &P) -> PyResult<Bound<'py, PyDict>> {
    let info = py.detach(|| p.describe()).map_err(Error)?;
    values::object_info(py, &info)
}

/// The lifecycle methods every proxy class has.
macro_rules! methods_with_lifecycle {
    ($class:ident { $($body:tt)* }) => {
        #[pymethods]
        impl $class {
            $($body)*

            /// The object's naming path.
            #[getter]
            fn path(&self) -> String {
                self.p.path()
            }

            /// Runs the lifecycle transition `word`; returns the new description.
            fn transition<'py>(
                &self,
                py: Python<'py>,
                word: &str,
            ) -> PyResult<Bound<'py, PyDict>> {
                transition(py, &self.p, word)
            }

            /// The object's description.
            fn describe<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
                describe(py, &self.p)
            }
        }
    };
}

/// A remote robot.
#[pyclass(module = "penelope._native", frozen)]
pub struct Robot {
    /// The Rust proxy.
    pub p: RobotProxy,
}

/// A remote sensor.
#[pyclass(module = "penelope._native", frozen)]
pub struct Sensor {
    /// The Rust proxy.
    pub p: SensorProxy,
}

/// A remote controller.
#[pyclass(module = "penelope._native", frozen)]
pub struct Controller {
    /// The Rust proxy.
    pub p: ControllerProxy,
}

/// A remote board (encoders and amplifiers).
#[pyclass(module = "penelope._native", frozen)]
pub struct Board {
    /// The Rust proxy.
    pub p: BoardProxy,
}

/// A remote trajectory.
#[pyclass(module = "penelope._native", frozen)]
pub struct Trajectory {
    /// The Rust proxy.
    pub p: TrajectoryProxy,
}

/// A remote object of any class.
#[pyclass(module = "penelope._native", frozen)]
pub struct Object {
    /// The Rust proxy.
    pub p: ObjectProxy,
}
methods_with_lifecycle!(Object {});

impl Robot {
    /// The joint vector of a target `q`: exactly one value per joint (a short vector is not
    /// padded with zeros: that would be a motion nobody asked for).
    fn target(&self, py: Python<'_>, q: &[f64]) -> Result<penelope_hal::JointVector> {
        let n = py.detach(|| self.p.joint_count())?;
        if q.len() != n {
            return Err(bad_argument(format!(
                "{} joint values for a robot of {n} joints",
                q.len()
            )));
        }
        values::joints(q)
    }

    /// The joint vector of `q`, `None` for the measured one.
    fn q(q: Option<Vec<f64>>) -> Result<Option<penelope_hal::JointVector>> {
        q.as_deref().map(values::joints).transpose()
    }
}

methods_with_lifecycle!(Robot {
    /// Number of joints.
    fn joint_count(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(py.detach(|| self.p.joint_count()).map_err(Error)?)
    }

    /// Forward kinematics at `q` (`None`: measured): the 4x4 transform, row by row.
    #[pyo3(signature = (q=None))]
    fn fk(&self, py: Python<'_>, q: Option<Vec<f64>>) -> PyResult<Vec<f64>> {
        let q = Self::q(q)?;
        let pose = py
            .detach(|| self.p.forward_kinematics(q.as_ref()))
            .map_err(Error)?;
        Ok(values::pose_rows(&pose))
    }

    /// The base-frame Jacobian at `q`: its 6xN values row by row, and N.
    #[pyo3(signature = (q=None))]
    fn jacobian(&self, py: Python<'_>, q: Option<Vec<f64>>) -> PyResult<(Vec<f64>, usize)> {
        let q = Self::q(q)?;
        let (j, n) = py
            .detach(|| Ok::<_, Error>((self.p.jacobian(q.as_ref())?, self.p.joint_count()?)))?;
        let flat = (0..6)
            .flat_map(|i| (0..n).map(move |k| (i, k)))
            .map(|(i, k)| j[(i, k)])
            .collect();
        Ok((flat, n))
    }

    /// Inverse kinematics of the 4x4 transform `t` (row by row): every branch.
    fn ik(&self, py: Python<'_>, t: Vec<f64>) -> PyResult<Vec<Vec<f64>>> {
        let pose = values::pose_of_rows(&t)?;
        let (branches, n) = py.detach(|| {
            Ok::<_, Error>((
                self.p.inverse_kinematics(&pose)?,
                self.p.joint_count()?,
            ))
        })?;
        Ok(branches.iter().map(|q| values::first(q, n)).collect())
    }

    /// Measured joint positions.
    fn joint_positions(&self, py: Python<'_>) -> PyResult<Vec<f64>> {
        let (q, n) = py.detach(|| {
            Ok::<_, Error>((self.p.joint_positions()?, self.p.joint_count()?))
        })?;
        Ok(values::first(&q, n))
    }

    /// Measured joint velocities.
    fn joint_velocities(&self, py: Python<'_>) -> PyResult<Vec<f64>> {
        let (q, n) = py.detach(|| {
            Ok::<_, Error>((self.p.joint_velocities()?, self.p.joint_count()?))
        })?;
        Ok(values::first(&q, n))
    }

    /// Gravity torques at `q` (`None`: measured).
    #[pyo3(signature = (q=None))]
    fn gravity(&self, py: Python<'_>, q: Option<Vec<f64>>) -> PyResult<Vec<f64>> {
        let q = Self::q(q)?;
        let (g, n) = py.detach(|| {
            Ok::<_, Error>((self.p.gravity(q.as_ref())?, self.p.joint_count()?))
        })?;
        Ok(values::first(&g, n))
    }

    /// The wrench at the tool from the bound force sensor, `[fx, fy, fz, tx, ty, tz]`, base
    /// frame.
    fn tool_wrench(&self, py: Python<'_>) -> PyResult<Vec<f64>> {
        let w = py.detach(|| self.p.tool_wrench()).map_err(Error)?;
        Ok(values::wrench_values(&w))
    }

    /// CRTK `move_jp`: a smooth joint motion to `q` in `duration` s; returns once started.
    fn move_jp(&self, py: Python<'_>, q: Vec<f64>, duration: f64) -> PyResult<()> {
        let q = self.target(py, &q)?;
        Ok(py.detach(|| self.p.move_joints(&q, duration)).map_err(Error)?)
    }

    /// CRTK `move_cp`: a smooth motion to the 4x4 tool pose `t` (row by row) in `duration` s.
    fn move_cp(&self, py: Python<'_>, t: Vec<f64>, duration: f64) -> PyResult<()> {
        let pose = values::pose_of_rows(&t)?;
        Ok(py.detach(|| self.p.move_tool(&pose, duration)).map_err(Error)?)
    }

    /// CRTK `servo_jp`: the newest joint target of a stream.
    fn servo_jp(&self, py: Python<'_>, q: Vec<f64>) -> PyResult<()> {
        let q = self.target(py, &q)?;
        Ok(py.detach(|| self.p.servo_joints(&q)).map_err(Error)?)
    }

    /// CRTK `servo_cp`: the newest tool-pose target of a stream (4x4, row by row).
    fn servo_cp(&self, py: Python<'_>, t: Vec<f64>) -> PyResult<()> {
        let pose = values::pose_of_rows(&t)?;
        Ok(py.detach(|| self.p.servo_tool(&pose)).map_err(Error)?)
    }

    /// CRTK `setpoint_js` / `setpoint_cp`: `(time_ns, joints or None, 4x4 pose row by row or
    /// None)`.
    #[allow(clippy::type_complexity)]
    fn setpoints(
        &self,
        py: Python<'_>,
    ) -> PyResult<(u64, Option<Vec<f64>>, Option<Vec<f64>>)> {
        let (s, n) = py.detach(|| {
            Ok::<_, Error>((self.p.setpoints()?, self.p.joint_count()?))
        })?;
        Ok((
            s.time_ns,
            s.joints.as_ref().map(|q| values::first(q, n)),
            s.pose.as_ref().map(values::pose_rows),
        ))
    }

    /// For the benchmark (`scripts/bench-python`): `calls` `servo_cp` calls of the pose `t`
    /// made by the Rust client alone (no Python between them), each timed, ns.
    fn bench_servo_cp(&self, py: Python<'_>, t: Vec<f64>, calls: usize) -> PyResult<Vec<u64>> {
        let pose = values::pose_of_rows(&t)?;
        let times = py.detach(|| {
            let mut times = Vec::with_capacity(calls);
            for _ in 0..calls {
                let start = std::time::Instant::now();
                self.p.servo_tool(&pose)?;
                times.push(u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX));
            }
            Ok::<_, Error>(times)
        })?;
        Ok(times)
    }

    /// CRTK `operating_state`: `(state, is_homed, is_busy)`.
    fn operating_state(&self, py: Python<'_>) -> PyResult<(String, bool, bool)> {
        let s = py.detach(|| self.p.operating_state()).map_err(Error)?;
        Ok((s.state, s.is_homed, s.is_busy))
    }

    /// Maps joint `j` to axis `a` of `board` for each `(j, a)`.
    fn map_joints(&self, py: Python<'_>, board: &str, joints: Vec<(usize, usize)>) -> PyResult<()> {
        Ok(py.detach(|| self.p.map_joints(board, &joints)).map_err(Error)?)
    }
});

methods_with_lifecycle!(Sensor {
    /// The newest reading, `[fx, fy, fz, tx, ty, tz]` in the sensor frame.
    fn read(&self, py: Python<'_>) -> PyResult<Vec<f64>> {
        let w = py.detach(|| self.p.read()).map_err(Error)?;
        Ok(values::wrench_values(&w))
    }

    /// Takes the current reading as the zero.
    fn bias(&self, py: Python<'_>) -> PyResult<()> {
        Ok(py.detach(|| self.p.bias()).map_err(Error)?)
    }
});

methods_with_lifecycle!(Controller {
    /// Replaces gains: TOML text with the kind's keys.
    fn set_gains(&self, py: Python<'_>, gains: &str) -> PyResult<()> {
        Ok(py.detach(|| self.p.set_gains(gains)).map_err(Error)?)
    }

    /// Relates the controller to the robot at `robot` (a name on its node).
    fn set_robot(&self, py: Python<'_>, robot: &str) -> PyResult<()> {
        Ok(py.detach(|| self.p.set_robot(robot)).map_err(Error)?)
    }

    /// Relates the controller to the trajectory `trajectory`.
    fn set_trajectory(&self, py: Python<'_>, trajectory: &str) -> PyResult<()> {
        Ok(py.detach(|| self.p.set_trajectory(trajectory)).map_err(Error)?)
    }

    /// Relates the controller to the force sensor `sensor` (a name on its node, or the
    /// naming path of a sensor on another node).
    fn set_sensor(&self, py: Python<'_>, sensor: &str) -> PyResult<()> {
        Ok(py.detach(|| self.p.set_sensor(sensor)).map_err(Error)?)
    }

    /// Latches the emergency stop.
    fn estop(&self, py: Python<'_>) -> PyResult<()> {
        Ok(py.detach(|| self.p.estop()).map_err(Error)?)
    }

    /// Re-arms the loop from the measured state.
    fn rearm(&self, py: Python<'_>) -> PyResult<()> {
        Ok(py.detach(|| self.p.rearm()).map_err(Error)?)
    }

    /// The loop's state, counters and newest sample.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = py.detach(|| self.p.status()).map_err(Error)?;
        let d = PyDict::new(py);
        d.set_item("state", s.state.to_string())?;
        d.set_item("running", s.running)?;
        d.set_item("ticks", s.ticks)?;
        d.set_item("overruns", s.overruns)?;
        d.set_item("telemetry_dropped", s.telemetry_dropped)?;
        match &s.last {
            Some(r) => d.set_item("last", values::record(py, r)?)?,
            None => d.set_item("last", py.None())?,
        }
        Ok(d)
    }
});

methods_with_lifecycle!(Board {
    /// Number of axes.
    fn axis_count(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(py.detach(|| self.p.axis_count()).map_err(Error)?)
    }

    /// Encoder positions of every axis, counts.
    fn read_encoders(&self, py: Python<'_>) -> PyResult<Vec<i64>> {
        Ok(py.detach(|| self.p.read_encoders()).map_err(Error)?)
    }

    /// Whether the amplifiers are enabled (the board's word).
    fn amplifiers_enabled(&self, py: Python<'_>) -> PyResult<bool> {
        Ok(py.detach(|| self.p.amplifiers_enabled()).map_err(Error)?)
    }

    /// Asks the board to leave a fault it latched itself.
    fn rearm(&self, py: Python<'_>) -> PyResult<()> {
        Ok(py.detach(|| self.p.rearm()).map_err(Error)?)
    }
});

methods_with_lifecycle!(Trajectory {
    /// The reference at `t` seconds after the start, as the wire carries it (so a joint
    /// reference keeps its joint count): a dict with `type` (`joint`, `cartesian`, `wrench`)
    /// and `q`, `qd` / `pose` (16 values row by row) / `force`, `torque`.
    fn reference<'py>(&self, py: Python<'py>, t: f64) -> PyResult<Bound<'py, PyDict>> {
        if !t.is_finite() {
            return Err(bad_argument(format!("time must be finite, got {t}")).into());
        }
        let r = py
            .detach(|| {
                match self
                    .p
                    .handle()
                    .call(Method::Trajectory(TrajectoryMethod::Reference { t_s: t }))?
                {
                    Reply::Reference(r) => Ok(r),
                    other => Err(RpcError::Protocol(format!(
                        "expected a reference, got {other:?}"
                    ))),
                }
            })
            .map_err(Error)?;
        let d = PyDict::new(py);
        match r {
            ReferenceMsg::Joint { q, qd } => {
                d.set_item("type", "joint")?;
                d.set_item("q", q)?;
                d.set_item("qd", qd)?;
            }
            ReferenceMsg::Cartesian { pose } => {
                let pose = pose
                    .to_pose()
                    .map_err(|e| Error(RpcError::Protocol(format!("a bad pose: {e}"))))?;
                d.set_item("type", "cartesian")?;
                d.set_item("pose", values::pose_rows(&pose))?;
            }
            ReferenceMsg::Wrench { wrench } => {
                d.set_item("type", "wrench")?;
                d.set_item("force", wrench.force.to_vec())?;
                d.set_item("torque", wrench.torque.to_vec())?;
            }
        }
        Ok(d)
    }

    /// The total duration, s (`None` for an endless trajectory).
    fn duration(&self, py: Python<'_>) -> PyResult<Option<f64>> {
        Ok(py.detach(|| self.p.duration()).map_err(Error)?)
    }
});
