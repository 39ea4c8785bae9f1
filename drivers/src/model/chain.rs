//! A serial chain of joints between a base transform and a tool transform: forward kinematics
//! and the geometric Jacobian.
//!
//! A joint is either a standard-DH row ([`DhLink`]) or an axis joint ([`AxisJoint`], what a URDF
//! joint becomes); one chain may mix them. Every joint transform is computed once per call (one
//! `sin_cos` per revolute joint) and composed in place on the stack; nothing allocates.

use nalgebra::{Matrix3, Vector3};
use penelope_hal::{Jacobian, JacobianFrame, JointVector, MAX_JOINTS, Pose};

use super::axis_joint::{AxisGeometry, AxisJoint};
use super::dh::{DhLink, JointKind, LinkGeometry, Rt};

/// Why a chain could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ChainError {
    /// No links, or more than [`MAX_JOINTS`].
    #[error("a chain needs 1 to {max} links, got {0}", max = MAX_JOINTS)]
    LinkCount(usize),
    /// A DH parameter, an axis joint's origin, the base or the tool is NaN or infinite (`joint`
    /// is 0-based; `None` for the base or tool transform).
    #[error("non-finite DH parameter or transform (joint {0:?})")]
    NonFinite(Option<usize>),
    /// An axis joint's axis has zero length (`joint` is 0-based).
    #[error("joint {0}: the axis has zero length")]
    ZeroAxis(usize),
}

/// One joint of a [`SerialChain`]: how the frame of the link it moves follows from the frame
/// before it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChainJoint {
    /// A standard-DH row: `A = Rz(theta) Tz(d) Tx(a) Rx(alpha)`; the joint moves about (along)
    /// the previous frame's z axis.
    Dh(DhLink),
    /// A fixed origin, then motion about (along) a unit axis: a URDF joint.
    Axis(AxisJoint),
}

impl ChainJoint {
    /// Revolute or prismatic.
    pub fn kind(&self) -> JointKind {
        match self {
            ChainJoint::Dh(l) => l.kind,
            ChainJoint::Axis(a) => a.kind,
        }
    }
}

impl From<DhLink> for ChainJoint {
    fn from(link: DhLink) -> Self {
        ChainJoint::Dh(link)
    }
}

impl From<AxisJoint> for ChainJoint {
    fn from(joint: AxisJoint) -> Self {
        ChainJoint::Axis(joint)
    }
}

/// A joint prepared for evaluation.
// The joints live in a fixed array inside the (Copy) chain; boxing the larger variant would put
// them on the heap for no gain (a chain is at most MAX_JOINTS of them, ~2 KiB).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum JointGeometry {
    Dh(LinkGeometry),
    Axis(AxisGeometry),
}

impl JointGeometry {
    fn new(joint: ChainJoint) -> Self {
        match joint {
            ChainJoint::Dh(l) => JointGeometry::Dh(LinkGeometry::new(l)),
            ChainJoint::Axis(a) => JointGeometry::Axis(AxisGeometry::new(a)),
        }
    }

    /// The joint as given (an axis joint's axis normalised).
    pub fn joint(&self) -> ChainJoint {
        match self {
            JointGeometry::Dh(g) => ChainJoint::Dh(g.link),
            JointGeometry::Axis(g) => ChainJoint::Axis(g.joint),
        }
    }

    /// Revolute or prismatic.
    #[inline(always)]
    pub fn kind(&self) -> JointKind {
        match self {
            JointGeometry::Dh(g) => g.link.kind,
            JointGeometry::Axis(g) => g.joint.kind,
        }
    }

    /// The frame of the link this joint moves, from the frame `(r, p)` before it, at `q`.
    #[inline(always)]
    pub fn compose(
        &self,
        r: &Matrix3<f64>,
        p: &Vector3<f64>,
        q: f64,
    ) -> (Matrix3<f64>, Vector3<f64>) {
        match self {
            JointGeometry::Dh(g) => g.compose(r, p, q),
            JointGeometry::Axis(g) => g.compose(r, p, q),
        }
    }

    /// True when the joint's axis passes through the origin of the frame before it (a DH row's
    /// does: it is that frame's z axis).
    #[inline(always)]
    pub fn axis_through_origin(&self) -> bool {
        matches!(self, JointGeometry::Dh(_))
    }

    /// The frame of the link this joint moves, and the joint's unit axis and a point on it, from
    /// the frame `(r, p)` before it, at `q`.
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    pub fn step(
        &self,
        r: &Matrix3<f64>,
        p: &Vector3<f64>,
        q: f64,
    ) -> ((Matrix3<f64>, Vector3<f64>), (Vector3<f64>, Vector3<f64>)) {
        match self {
            JointGeometry::Dh(g) => (g.compose(r, p, q), (r.column(2).into(), *p)),
            JointGeometry::Axis(g) => g.step(r, p, q),
        }
    }

    /// The joint's unit axis and a point on it, from the frame `(r, p)` before it.
    #[inline(always)]
    pub fn axis_in(&self, r: &Matrix3<f64>, p: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        match self {
            JointGeometry::Dh(_) => (r.column(2).into(), *p),
            JointGeometry::Axis(g) => g.axis_in(r, p),
        }
    }
}

/// Every link frame of one configuration, in the world frame: index 0 is the base frame, index
/// `j` the frame after link `j` (1-based, standard DH numbering).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frames {
    pub r: [Matrix3<f64>; MAX_JOINTS + 1],
    pub p: [Vector3<f64>; MAX_JOINTS + 1],
}

/// A serial chain: up to [`MAX_JOINTS`] joints (standard-DH rows or axis joints), a base
/// transform (world to frame 0) and a tool transform (last link frame to the tool frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SerialChain {
    n: usize,
    links: [JointGeometry; MAX_JOINTS],
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
        let mut joints = [ChainJoint::Dh(DhLink::revolute(0.0, 0.0, 0.0, 0.0)); MAX_JOINTS];
        if links.is_empty() || links.len() > MAX_JOINTS {
            return Err(ChainError::LinkCount(links.len()));
        }
        for (j, l) in joints.iter_mut().zip(links) {
            *j = ChainJoint::Dh(*l);
        }
        Self::from_joints(&joints[..links.len()], base, tool)
    }

    /// A chain from its joints (1 to [`MAX_JOINTS`], DH rows or axis joints, mixed as needed),
    /// base and tool transforms.
    ///
    /// # Errors
    /// [`ChainError`] for a wrong joint count, a non-finite number or a zero axis.
    pub fn from_joints(links: &[ChainJoint], base: &Pose, tool: &Pose) -> Result<Self, ChainError> {
        if links.is_empty() || links.len() > MAX_JOINTS {
            return Err(ChainError::LinkCount(links.len()));
        }
        for (j, l) in links.iter().enumerate() {
            match l {
                ChainJoint::Dh(l) if !l.is_finite() => return Err(ChainError::NonFinite(Some(j))),
                ChainJoint::Axis(a) if !a.is_valid() => {
                    return Err(if a.axis.iter().all(|x| x.is_finite()) {
                        ChainError::ZeroAxis(j)
                    } else {
                        ChainError::NonFinite(Some(j))
                    });
                }
                _ => {}
            }
        }
        let finite = |p: &Pose| {
            p.translation.vector.iter().all(|x| x.is_finite())
                && p.rotation.coords.iter().all(|x| x.is_finite())
        };
        if !finite(base) || !finite(tool) {
            return Err(ChainError::NonFinite(None));
        }
        let mut geo =
            [JointGeometry::new(ChainJoint::Dh(DhLink::revolute(0.0, 0.0, 0.0, 0.0))); MAX_JOINTS];
        for (g, l) in geo.iter_mut().zip(links) {
            *g = JointGeometry::new(*l);
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

    /// The DH row of joint `j` (0-based), or `None` past the joint count or for an axis joint.
    pub fn link(&self, j: usize) -> Option<DhLink> {
        match self.joint(j)? {
            ChainJoint::Dh(l) => Some(l),
            ChainJoint::Axis(_) => None,
        }
    }

    /// Joint `j` (0-based) as given (an axis joint's axis normalised), or `None` past the joint
    /// count.
    pub fn joint(&self, j: usize) -> Option<ChainJoint> {
        (j < self.n).then(|| self.links[j].joint())
    }

    /// The base transform: pose of frame 0 in the world frame.
    pub fn base(&self) -> Pose {
        self.base.to_pose()
    }

    /// The tool transform: pose of the tool frame in the last link's frame.
    pub fn tool(&self) -> Pose {
        self.tool.to_pose()
    }

    pub(crate) fn geometry(&self, j: usize) -> &JointGeometry {
        &self.links[j]
    }

    /// Joint `j`'s (0-based) unit axis and a point on it in the world frame, from the frames of
    /// one configuration.
    #[inline(always)]
    pub(crate) fn joint_axis(&self, f: &Frames, j: usize) -> (Vector3<f64>, Vector3<f64>) {
        self.links[j].axis_in(&f.r[j], &f.p[j])
    }

    /// The DH geometry of joint `j`, `None` for an axis joint.
    pub(crate) fn dh_geometry(&self, j: usize) -> Option<&LinkGeometry> {
        match &self.links[j] {
            JointGeometry::Dh(g) => Some(g),
            JointGeometry::Axis(_) => None,
        }
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

    /// One sweep storing only each joint's axis and a point on it (not whole frames), then one
    /// column per joint.
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
            ((r, p), (axis[j], origin[j])) = self.links[j].step(&r, &p, q[j]);
        }
        let e = self.tool_of(&Rt { r, p });
        let mut jac = Jacobian::zeros();
        for j in 0..self.n {
            let z = axis[j];
            let (v, w) = match self.links[j].kind() {
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
