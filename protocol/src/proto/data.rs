//! The plain data of the wire (joints, poses, wrenches, matrices, references) and its conversions
//! to and from the math types of `hal`.

use nalgebra::{Matrix3, SMatrix, Translation3, UnitQuaternion, Vector3};
use penelope_hal::{Frame, JointVector, MAX_JOINTS, Pose, Wrench};
use serde::{Deserialize, Serialize};

use super::{CallError, WireError};

/// Joint values, one per joint (rad, rad/s or N·m as the method says); at most 6.
pub type Joints = Vec<f64>;

/// A pose: position and orientation as the three versors of the tool frame (the columns of the
/// rotation matrix: normal `n`, sliding `o`, approach `a`), in the base frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseMsg {
    /// Position, m.
    pub position: [f64; 3],
    /// Normal versor `n` (the tool x axis).
    pub n: [f64; 3],
    /// Sliding versor `o` (the tool y axis).
    pub o: [f64; 3],
    /// Approach versor `a` (the tool z axis).
    pub a: [f64; 3],
}

/// A rigid contact shape of a simulated environment, in a robot's root frame (metres): the
/// wire form of the simulator's shapes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum ContactShapeMsg {
    /// An infinite plane (a wall or a table): free space is on the side `normal` points to.
    Plane {
        /// A point on the plane, m.
        point: [f64; 3],
        /// Unit normal pointing into free space.
        normal: [f64; 3],
    },
    /// A solid sphere.
    Sphere {
        /// Centre, m.
        center: [f64; 3],
        /// Radius, m.
        radius: f64,
    },
}

/// A wrench: force (N) and torque (N·m).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WrenchMsg {
    /// Force, N.
    pub force: [f64; 3],
    /// Torque, N·m.
    pub torque: [f64; 3],
}

/// Operational-space state: tool pose and twist.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OperationalMsg {
    /// The tool pose.
    pub pose: PoseMsg,
    /// Linear velocity, m/s.
    pub linear_velocity: [f64; 3],
    /// Angular velocity, rad/s.
    pub angular_velocity: [f64; 3],
}

/// A dense matrix, row-major.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MatrixMsg {
    /// Rows.
    pub rows: u16,
    /// Columns.
    pub cols: u16,
    /// `rows * cols` values, row after row.
    pub data: Vec<f64>,
}

/// A reference a controller follows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ReferenceMsg {
    /// Joint positions (rad) and velocities (rad/s).
    Joint {
        /// Positions, rad.
        q: Joints,
        /// Velocities, rad/s.
        qd: Joints,
    },
    /// A tool pose.
    Cartesian {
        /// The pose.
        pose: PoseMsg,
    },
    /// A wrench to display or exert.
    Wrench {
        /// The wrench.
        wrench: WrenchMsg,
    },
}

impl From<&Pose> for PoseMsg {
    fn from(pose: &Pose) -> Self {
        let r = pose.rotation.to_rotation_matrix();
        let col = |j: usize| [r[(0, j)], r[(1, j)], r[(2, j)]];
        let t = pose.translation.vector;
        PoseMsg {
            position: [t.x, t.y, t.z],
            n: col(0),
            o: col(1),
            a: col(2),
        }
    }
}

impl PoseMsg {
    /// The pose, after checking that every value is finite and that `n, o, a` are orthonormal
    /// and right-handed within 1e-6 (then re-orthonormalized).
    ///
    /// # Errors
    /// [`CallError::BadArgument`] saying what is wrong.
    pub fn to_pose(&self) -> Result<Pose, WireError> {
        let all = self
            .position
            .iter()
            .chain(&self.n)
            .chain(&self.o)
            .chain(&self.a);
        if !all.into_iter().all(|x| x.is_finite()) {
            return Err(WireError::Call(CallError::BadArgument(
                "pose has a NaN or infinite value".into(),
            )));
        }
        let m = Matrix3::from_columns(&[
            Vector3::from(self.n),
            Vector3::from(self.o),
            Vector3::from(self.a),
        ]);
        let off = (m.transpose() * m - Matrix3::identity()).abs().max();
        if off > 1e-6 || m.determinant() < 0.0 {
            return Err(WireError::Call(CallError::BadArgument(
                "pose versors n, o, a are not orthonormal and right-handed".into(),
            )));
        }
        let rotation = UnitQuaternion::from_matrix(&m);
        Ok(Pose::from_parts(
            Translation3::from(Vector3::from(self.position)),
            rotation,
        ))
    }
}

impl From<&Wrench> for WrenchMsg {
    fn from(w: &Wrench) -> Self {
        WrenchMsg {
            force: [w.force.x, w.force.y, w.force.z],
            torque: [w.torque.x, w.torque.y, w.torque.z],
        }
    }
}

impl WrenchMsg {
    /// The wrench in `frame`, after checking every value is finite.
    ///
    /// # Errors
    /// [`CallError::BadArgument`] for a NaN or infinite component.
    pub fn to_wrench(&self, frame: Frame) -> Result<Wrench, WireError> {
        if !self.force.iter().chain(&self.torque).all(|x| x.is_finite()) {
            return Err(WireError::Call(CallError::BadArgument(
                "wrench has a NaN or infinite value".into(),
            )));
        }
        Ok(Wrench {
            force: Vector3::from(self.force),
            torque: Vector3::from(self.torque),
            frame,
        })
    }
}

/// The first `n` joints of `q` on the wire.
pub fn joints_from_vector(q: &JointVector, n: usize) -> Joints {
    q.iter().take(n.min(MAX_JOINTS)).copied().collect()
}

/// A joint vector from exactly `n` finite wire values (the rest zero).
///
/// # Errors
/// [`CallError::BadArgument`] for a wrong count or a NaN or infinite value.
pub fn joints_to_vector(q: &[f64], n: usize) -> Result<JointVector, WireError> {
    if q.len() != n || n > MAX_JOINTS {
        return Err(WireError::Call(CallError::BadArgument(format!(
            "expected {n} joint values, got {}",
            q.len()
        ))));
    }
    if !q.iter().all(|x| x.is_finite()) {
        return Err(WireError::Call(CallError::BadArgument(
            "a joint value is NaN or infinite".into(),
        )));
    }
    let mut v = JointVector::zeros();
    v.as_mut_slice()[..n].copy_from_slice(q);
    Ok(v)
}

impl MatrixMsg {
    /// The top-left `rows` × `cols` block of `m`, row-major.
    pub fn from_block<const R: usize, const C: usize>(
        m: &SMatrix<f64, R, C>,
        rows: usize,
        cols: usize,
    ) -> Self {
        let (rows, cols) = (rows.min(R), cols.min(C));
        let mut data = Vec::with_capacity(rows * cols);
        for i in 0..rows {
            for j in 0..cols {
                data.push(m[(i, j)]);
            }
        }
        MatrixMsg {
            rows: rows as u16,
            cols: cols as u16,
            data,
        }
    }

    /// The value at row `i`, column `j` (`None` out of range).
    pub fn get(&self, i: usize, j: usize) -> Option<f64> {
        if i < usize::from(self.rows) && j < usize::from(self.cols) {
            self.data.get(i * usize::from(self.cols) + j).copied()
        } else {
            None
        }
    }
}
