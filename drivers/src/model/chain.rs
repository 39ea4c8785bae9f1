//! A serial chain of DH links between a base transform and a tool transform: forward
//! kinematics and the geometric Jacobian.
//!
//! Every link transform is computed once per call (one `sin_cos` per revolute joint) and composed
//! in place on the stack; nothing allocates.

use nalgebra::{Matrix3, Vector3};
use penelope_hal::{Jacobian, JacobianFrame, JointVector, MAX_JOINTS, Pose};

use super::dh::{DhLink, JointKind, LinkGeometry, Rt};

/// Why a chain could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ChainError {
    /// No links, or more than [`MAX_JOINTS`].
    #[error("a chain needs 1 to {max} links, got {0}", max = MAX_JOINTS)]
    LinkCount(usize),
    /// A DH parameter, the base or the tool is NaN or infinite (`joint` is 0-based; `None` for
    /// the base or tool transform).
    #[error("non-finite DH parameter or transform (joint {0:?})")]
    NonFinite(Option<usize>),
}

/// Every link frame of one configuration, in the world frame: index 0 is the base frame, index
/// `j` the frame after link `j` (1-based, standard DH numbering).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frames {
    pub r: [Matrix3<f64>; MAX_JOINTS + 1],
    pub p: [Vector3<f64>; MAX_JOINTS + 1],
}

/// A serial chain: up to [`MAX_JOINTS`] standard-DH links, a base transform (world to frame 0)
/// and a tool transform (last link frame to the tool frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SerialChain {
    n: usize,
    links: [LinkGeometry; MAX_JOINTS],
    base: Rt,
    tool: Rt,
    tool_identity: bool,
}

impl SerialChain {
    /// A chain from its DH rows (1 to [`MAX_JOINTS`]), base and tool transforms.
    ///
    /// # Errors
    /// [`ChainError`] for a wrong link count or a non-finite number.
    pub fn new(links: &[DhLink], base: &Pose, tool: &Pose) -> Result<Self, ChainError> {
        if links.is_empty() || links.len() > MAX_JOINTS {
            return Err(ChainError::LinkCount(links.len()));
        }
        if let Some(j) = links.iter().position(|l| !l.is_finite()) {
            return Err(ChainError::NonFinite(Some(j)));
        }
        let finite = |p: &Pose| {
            p.translation.vector.iter().all(|x| x.is_finite())
                && p.rotation.coords.iter().all(|x| x.is_finite())
        };
        if !finite(base) || !finite(tool) {
            return Err(ChainError::NonFinite(None));
        }
        let mut geo = [LinkGeometry::new(DhLink::revolute(0.0, 0.0, 0.0, 0.0)); MAX_JOINTS];
        for (g, l) in geo.iter_mut().zip(links) {
            *g = LinkGeometry::new(*l);
        }
        let base = Rt::from_pose(base);
        let tool = Rt::from_pose(tool);
        Ok(SerialChain {
            n: links.len(),
            links: geo,
            base,
            tool,
            tool_identity: tool.is_identity(),
        })
    }

    /// Number of joints.
    pub fn joint_count(&self) -> usize {
        self.n
    }

    /// The DH row of joint `j` (0-based), or `None` past the joint count.
    pub fn link(&self, j: usize) -> Option<DhLink> {
        (j < self.n).then(|| self.links[j].link)
    }

    /// The base transform: pose of frame 0 in the world frame.
    pub fn base(&self) -> Pose {
        self.base.to_pose()
    }

    /// The tool transform: pose of the tool frame in the last link's frame.
    pub fn tool(&self) -> Pose {
        self.tool.to_pose()
    }

    pub(crate) fn geometry(&self, j: usize) -> &LinkGeometry {
        &self.links[j]
    }

    /// The flange frame (after the last link) in the world frame, without storing the others.
    #[inline]
    pub(crate) fn flange(&self, q: &JointVector) -> Rt {
        let mut r = self.base.r;
        let mut p = self.base.p;
        for j in 0..self.n {
            (r, p) = self.links[j].compose(&r, &p, q[j]);
        }
        Rt { r, p }
    }

    /// Every link frame in the world frame.
    #[inline]
    pub(crate) fn frames(&self, q: &JointVector) -> Frames {
        let mut f = Frames {
            r: [self.base.r; MAX_JOINTS + 1],
            p: [self.base.p; MAX_JOINTS + 1],
        };
        for j in 0..self.n {
            let (r, p) = self.links[j].compose(&f.r[j], &f.p[j], q[j]);
            f.r[j + 1] = r;
            f.p[j + 1] = p;
        }
        f
    }

    /// The tool frame from the flange frame.
    #[inline]
    pub(crate) fn tool_of(&self, flange: &Rt) -> Rt {
        if self.tool_identity {
            *flange
        } else {
            flange.mul(&self.tool)
        }
    }

    /// The tool frame in the world frame as a rotation matrix and position.
    #[inline]
    pub(crate) fn forward_rt(&self, q: &JointVector) -> Rt {
        self.tool_of(&self.flange(q))
    }

    /// The tool pose in the world frame at `q` (rad, or m for prismatic joints).
    ///
    /// # Real-time
    /// No allocation, bounded time (one `sin_cos` per joint).
    pub fn forward(&self, q: &JointVector) -> Pose {
        self.forward_rt(q).to_pose()
    }

    /// The tool pose as a 4x4 homogeneous matrix (row-major access with `m[(row, col)]`).
    ///
    /// # Real-time
    /// No allocation, bounded time.
    pub fn forward_matrix(&self, q: &JointVector) -> nalgebra::Matrix4<f64> {
        let t = self.forward_rt(q);
        let mut m = nalgebra::Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&t.r);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&t.p);
        m
    }

    /// The geometric Jacobian at `q` for the tool origin, rows `[v; omega]`, expressed in the
    /// world (base) frame or the tool frame.
    ///
    /// # Real-time
    /// No allocation, bounded time.
    pub fn jacobian(&self, q: &JointVector, frame: JacobianFrame) -> Jacobian {
        self.forward_and_jacobian_rt(q, frame).1
    }

    /// Forward kinematics and the Jacobian from one pass over the links (cheaper than calling
    /// both).
    ///
    /// # Real-time
    /// No allocation, bounded time.
    pub fn forward_and_jacobian(&self, q: &JointVector, frame: JacobianFrame) -> (Pose, Jacobian) {
        let (t, j) = self.forward_and_jacobian_rt(q, frame);
        (t.to_pose(), j)
    }

    /// One sweep storing only each joint's axis and origin (not whole frames), then one column
    /// per joint.
    #[inline]
    pub(crate) fn forward_and_jacobian_rt(
        &self,
        q: &JointVector,
        frame: JacobianFrame,
    ) -> (Rt, Jacobian) {
        let mut axis = [Vector3::zeros(); MAX_JOINTS];
        let mut origin = [Vector3::zeros(); MAX_JOINTS];
        let mut r = self.base.r;
        let mut p = self.base.p;
        for j in 0..self.n {
            axis[j] = r.column(2).into();
            origin[j] = p;
            (r, p) = self.links[j].compose(&r, &p, q[j]);
        }
        let e = self.tool_of(&Rt { r, p });
        let mut jac = Jacobian::zeros();
        for j in 0..self.n {
            let z = axis[j];
            let (v, w) = match self.links[j].link.kind {
                JointKind::Revolute => (z.cross(&(e.p - origin[j])), z),
                JointKind::Prismatic => (z, Vector3::zeros()),
            };
            let (v, w) = match frame {
                JacobianFrame::Base => (v, w),
                JacobianFrame::Tool => (e.r.tr_mul(&v), e.r.tr_mul(&w)),
            };
            jac.fixed_view_mut::<3, 1>(0, j).copy_from(&v);
            jac.fixed_view_mut::<3, 1>(3, j).copy_from(&w);
        }
        (e, jac)
    }
}
