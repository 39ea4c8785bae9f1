//! Values between the wire and Python: joint vectors and matrices as flat `f64` lists (the
//! Python layer shapes them into NumPy arrays), records and descriptions as dicts.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use penelope_hal::{JointVector, MAX_JOINTS, Pose, Wrench};
use penelope_protocol::proto::{
    CameraFrame, CameraModelMsg, KindInfo, LinkRecord, ObjectInfo, ObjectRef, PoseMsg,
    TelemetryRecord,
};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use crate::errors::{Result, bad_argument};

/// The joint vector of `q` (at most [`MAX_JOINTS`] values; the rest zero).
pub fn joints(q: &[f64]) -> Result<JointVector> {
    if q.len() > MAX_JOINTS {
        return Err(bad_argument(format!(
            "{} joint values, at most {MAX_JOINTS}",
            q.len()
        )));
    }
    let mut v = JointVector::zeros();
    for (slot, x) in v.iter_mut().zip(q) {
        *slot = *x;
    }
    Ok(v)
}

/// The first `n` values of `v`.
pub fn first(v: &JointVector, n: usize) -> Vec<f64> {
    v.iter().take(n).copied().collect()
}

/// The 4x4 homogeneous transform of `pose`, row by row.
pub fn pose_rows(pose: &Pose) -> Vec<f64> {
    let m = pose.to_homogeneous();
    (0..4)
        .flat_map(|i| (0..4).map(move |j| (i, j)))
        .map(|(i, j)| m[(i, j)])
        .collect()
}

/// The pose of a 4x4 homogeneous transform given row by row: its rotation must be
/// orthonormal (to 1e-6) and its last row `0 0 0 1`.
pub fn pose_of_rows(t: &[f64]) -> Result<Pose> {
    if t.len() != 16 {
        return Err(bad_argument(format!(
            "a pose is a 4x4 homogeneous transform, got {} values",
            t.len()
        )));
    }
    if !t.iter().all(|x| x.is_finite()) {
        return Err(bad_argument("the pose has a NaN or infinite value"));
    }
    if t[12..] != [0.0, 0.0, 0.0, 1.0] {
        return Err(bad_argument("the pose's last row must be 0 0 0 1"));
    }
    let r = Matrix3::new(t[0], t[1], t[2], t[4], t[5], t[6], t[8], t[9], t[10]);
    let off = (r.transpose() * r - Matrix3::identity()).abs().max();
    if off > 1e-6 || (r.determinant() - 1.0).abs() > 1e-6 {
        return Err(bad_argument(
            "the pose's rotation is not orthonormal and right-handed (to 1e-6)",
        ));
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(Isometry3::from_parts(
        Translation3::new(t[3], t[7], t[11]),
        rotation,
    ))
}

/// A wrench as `[fx, fy, fz, tx, ty, tz]`.
pub fn wrench_values(w: &Wrench) -> Vec<f64> {
    w.force.iter().chain(w.torque.iter()).copied().collect()
}

/// An object's description.
pub fn object_info<'py>(py: Python<'py>, info: &ObjectInfo) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("name", &info.name)?;
    d.set_item("kind", &info.kind)?;
    d.set_item("class", info.class.to_string())?;
    d.set_item("state", info.state.to_string())?;
    d.set_item("relations", info.relations.clone())?;
    Ok(d)
}

/// What a naming entry refers to.
pub fn object_ref<'py>(py: Python<'py>, r: &ObjectRef) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("node", &r.node)?;
    d.set_item("address", &r.address)?;
    d.set_item("name", &r.name)?;
    d.set_item("class", r.class.to_string())?;
    d.set_item("kind", &r.kind)?;
    Ok(d)
}

/// One kind a node can create.
pub fn kind_info<'py>(py: Python<'py>, k: &KindInfo) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("kind", &k.kind)?;
    d.set_item("class", k.class.to_string())?;
    d.set_item("summary", &k.summary)?;
    d.set_item("config", &k.config)?;
    Ok(d)
}

/// One control tick (vectors as lists, the Python layer makes them arrays).
pub fn record<'py>(py: Python<'py>, r: &TelemetryRecord) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("time_ns", r.time_ns)?;
    d.set_item("seq", r.seq)?;
    d.set_item("q", r.q.clone())?;
    d.set_item("qd", r.qd.clone())?;
    d.set_item("effort", r.effort.clone())?;
    d.set_item("tool_position", r.tool_position.to_vec())?;
    d.set_item("force", r.wrench.force.to_vec())?;
    d.set_item("torque", r.wrench.torque.to_vec())?;
    d.set_item("state", &r.state)?;
    d.set_item("fault", r.fault.clone())?;
    d.set_item("commanded_force", r.commanded_wrench.force.to_vec())?;
    d.set_item("commanded_torque", r.commanded_wrench.torque.to_vec())?;
    d.set_item("clutch", r.clutch)?;
    d.set_item("port_energy", r.port_energy)?;
    d.set_item("channel_energy", r.channel_energy)?;
    Ok(d)
}

/// One reading of a teleop channel's link statistics (times in ns, `None` when not yet
/// estimated).
pub fn link_record<'py>(py: Python<'py>, r: &LinkRecord) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("time_ns", r.time_ns)?;
    d.set_item("down", r.down)?;
    d.set_item("losses", r.losses)?;
    d.set_item("restorations", r.restorations)?;
    d.set_item("samples_taken", r.samples_taken)?;
    d.set_item("samples_dropped", r.samples_dropped)?;
    d.set_item("samples_missed", r.samples_missed)?;
    d.set_item("refused", r.refused)?;
    d.set_item("clock_offset_ns", r.clock_offset_ns)?;
    d.set_item("round_trip_ns", r.round_trip_ns)?;
    d.set_item("one_way_delay_ns", r.one_way_delay_ns)?;
    d.set_item("jitter_ns", r.jitter_ns)?;
    d.set_item("last_heard_ns", r.last_heard_ns)?;
    d.set_item("heartbeat_loss", r.heartbeat_loss)?;
    d.set_item("trips", r.trips)?;
    d.set_item("trip_p50_ns", r.trip_p50_ns)?;
    d.set_item("trip_p99_ns", r.trip_p99_ns)?;
    d.set_item("trip_max_ns", r.trip_max_ns)?;
    Ok(d)
}

/// A camera frame as a dict: `seq`, `capture_ns`, `ready_ns`, `sent_ns` (ns on the common
/// clock), `encoding` (`"jpeg"`), `data` (the encoded image, bytes) and `model` (see
/// [`camera_model`]).
pub fn camera_frame<'py>(py: Python<'py>, f: &CameraFrame) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("seq", f.seq)?;
    d.set_item("capture_ns", f.capture_ns)?;
    d.set_item("ready_ns", f.ready_ns)?;
    d.set_item("sent_ns", f.sent_ns)?;
    d.set_item("encoding", f.encoding.name())?;
    d.set_item("data", PyBytes::new(py, &f.data))?;
    d.set_item("model", camera_model(py, &f.model)?)?;
    Ok(d)
}

/// A camera's model as a dict: `frame_id`, `width`, `height` (px), the pinhole's `fx`, `fy`,
/// `cx`, `cy` (px), `pose_in_robot_base` (the optical frame in the watched robot's base, 4x4
/// row by row, or `None`) and `robot` (the robot it watches, or `None`).
pub fn camera_model<'py>(py: Python<'py>, m: &CameraModelMsg) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("frame_id", &m.frame_id)?;
    d.set_item("width", m.width)?;
    d.set_item("height", m.height)?;
    d.set_item("fx", m.fx)?;
    d.set_item("fy", m.fy)?;
    d.set_item("cx", m.cx)?;
    d.set_item("cy", m.cy)?;
    d.set_item(
        "pose_in_robot_base",
        m.pose_in_robot_base.as_ref().map(pose_msg_rows),
    )?;
    d.set_item("robot", m.robot.as_deref())?;
    Ok(d)
}

/// The 4x4 homogeneous transform of a pose message (its columns `n`, `o`, `a`, `position`),
/// row by row.
fn pose_msg_rows(p: &PoseMsg) -> Vec<f64> {
    let mut rows = Vec::with_capacity(16);
    for i in 0..3 {
        rows.extend([p.n[i], p.o[i], p.a[i], p.position[i]]);
    }
    rows.extend([0.0, 0.0, 0.0, 1.0]);
    rows
}
