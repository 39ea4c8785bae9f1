//! A serial chain of joints between a base transform and a tool transform: forward kinematics
//! and the geometric Jacobian.
//!
//! A joint is either a standard-DH row ([`DhLink`]) or an axis joint ([`AxisJoint`], what a URDF
//! joint becomes); one chain may mix them. Every joint transform is computed once per call (one
//! `sin_cos` per revolute joint) and composed in place on the stack; nothing allocates. A chain
//! of six revolute DH rows (both PUMAs, the FRHC) takes a faster path with the same arithmetic,
//! equal bit for bit (`dh6.rs`).

use nalgebra::{Matrix3, Vector3};
use penelope_hal::{Jacobian, JacobianFrame, JointVector, MAX_JOINTS, Pose};

use super::axis_joint::{AxisGeometry, AxisJoint};
use super::dh::{DhLink, JointKind, LinkGeometry, Rt};
use super::dh6::Dh6;

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
    /// The fast path when the chain is six revolute DH rows (bit for bit the general one).
    dh6: Option<Dh6>,
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
        let dh: [Option<&LinkGeometry>; MAX_JOINTS] = core::array::from_fn(|j| match &geo[j] {
            JointGeometry::Dh(g) => Some(g),
            JointGeometry::Axis(_) => None,
        });
        let dh6 = Dh6::new(&dh[..links.len()]);
        Ok(SerialChain {
            n: links.len(),
            links: geo,
            base,
            tool,
            tool_identity: tool.is_identity(),
            dh6,
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
        match &self.dh6 {
            Some(fast) => fast.flange(&self.base, q),
            None => self.flange_general(q),
        }
    }

    /// [`flange`](Self::flange) for any chain.
    #[inline]
    fn flange_general(&self, q: &JointVector) -> Rt {
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
        let mut jac = Jacobian::zeros();
        self.forward_and_jacobian_into(q, frame, &mut jac);
        jac
    }

    /// Forward kinematics and the Jacobian from one pass over the links (cheaper than calling
    /// both).
    ///
    /// # Real-time
    /// No allocation, bounded time.
    pub fn forward_and_jacobian(&self, q: &JointVector, frame: JacobianFrame) -> (Pose, Jacobian) {
        // Built in place: moving a 288-byte Jacobian costs a `memcpy` call per move.
        let mut out = (Pose::identity(), Jacobian::zeros());
        let t = self.forward_and_jacobian_into(q, frame, &mut out.1);
        out.0 = t.to_pose();
        out
    }

    /// One sweep storing only each joint's axis and a point on it (not whole frames), then one
    /// column per joint.
    #[inline]
    pub(crate) fn forward_and_jacobian_rt(
        &self,
        q: &JointVector,
        frame: JacobianFrame,
    ) -> (Rt, Jacobian) {
        let mut jac = Jacobian::zeros();
        let t = self.forward_and_jacobian_into(q, frame, &mut jac);
        (t, jac)
    }

    /// [`forward_and_jacobian_rt`](Self::forward_and_jacobian_rt) writing the Jacobian into
    /// `jac`, which must be zero (the columns past the joint count are left as they are).
    #[inline(always)]
    fn forward_and_jacobian_into(
        &self,
        q: &JointVector,
        frame: JacobianFrame,
        jac: &mut Jacobian,
    ) -> Rt {
        match &self.dh6 {
            Some(fast) => {
                let sweep = fast.sweep(&self.base, q);
                let e = self.tool_of(&sweep.flange);
                for j in 0..6 {
                    let z = sweep.axis[j];
                    let v = z.cross(&(e.p - sweep.origin[j]));
                    let (v, w) = match frame {
                        JacobianFrame::Base => (v, z),
                        JacobianFrame::Tool => (e.r.tr_mul(&v), e.r.tr_mul(&z)),
                    };
                    jac.fixed_view_mut::<3, 1>(0, j).copy_from(&v);
                    jac.fixed_view_mut::<3, 1>(3, j).copy_from(&w);
                }
                e
            }
            None => self.forward_and_jacobian_general(q, frame, jac),
        }
    }

    /// [`forward_and_jacobian_into`](Self::forward_and_jacobian_into) for any chain.
    #[inline]
    fn forward_and_jacobian_general(
        &self,
        q: &JointVector,
        frame: JacobianFrame,
        jac: &mut Jacobian,
    ) -> Rt {
        let mut axis = [Vector3::zeros(); MAX_JOINTS];
        let mut origin = [Vector3::zeros(); MAX_JOINTS];
        let mut r = self.base.r;
        let mut p = self.base.p;
        for j in 0..self.n {
            ((r, p), (axis[j], origin[j])) = self.links[j].step(&r, &p, q[j]);
        }
        let e = self.tool_of(&Rt { r, p });
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
        e
    }
}

#[cfg(test)]
mod tests {
    use core::f64::consts::{FRAC_PI_2, PI};

    use nalgebra::{Translation3, UnitQuaternion};
    use proptest::prelude::*;

    use super::*;

    impl SerialChain {
        /// The same chain, always on the general path.
        fn general(&self) -> SerialChain {
            SerialChain { dh6: None, ..*self }
        }
    }

    fn pose_bits(p: &Pose) -> [u64; 7] {
        let t = p.translation.vector;
        let r = p.rotation.coords;
        [t.x, t.y, t.z, r.x, r.y, r.z, r.w].map(f64::to_bits)
    }

    fn matrix_bits<const R: usize, const C: usize>(m: &nalgebra::SMatrix<f64, R, C>) -> Vec<u64> {
        m.iter().map(|x| x.to_bits()).collect()
    }

    /// Every kinematics result of `chain` at `q` equals the general path's, bit for bit.
    fn assert_fast_equals_general(chain: &SerialChain, q: &JointVector) {
        assert!(chain.dh6.is_some(), "the chain should take the fast path");
        let general = chain.general();
        assert_eq!(
            pose_bits(&chain.forward(q)),
            pose_bits(&general.forward(q)),
            "fk at {q:?}"
        );
        assert_eq!(
            matrix_bits(&chain.forward_matrix(q)),
            matrix_bits(&general.forward_matrix(q))
        );
        for frame in [JacobianFrame::Base, JacobianFrame::Tool] {
            let (pose, jac) = chain.forward_and_jacobian(q, frame);
            let (pose_g, jac_g) = general.forward_and_jacobian(q, frame);
            assert_eq!(pose_bits(&pose), pose_bits(&pose_g), "{frame:?} at {q:?}");
            assert_eq!(matrix_bits(&jac), matrix_bits(&jac_g), "{frame:?} at {q:?}");
            assert_eq!(
                matrix_bits(&chain.jacobian(q, frame)),
                matrix_bits(&jac_g),
                "{frame:?} at {q:?}"
            );
            let (t, j) = chain.forward_and_jacobian_rt(q, frame);
            let (t_g, j_g) = general.forward_and_jacobian_rt(q, frame);
            assert_eq!(matrix_bits(&t.r), matrix_bits(&t_g.r));
            assert_eq!(matrix_bits(&t.p), matrix_bits(&t_g.p));
            assert_eq!(matrix_bits(&j), matrix_bits(&j_g));
        }
    }

    fn built_in_chains() -> Vec<SerialChain> {
        crate::model::BUILT_IN
            .iter()
            .map(|name| *crate::model::by_name(name).unwrap().chain())
            .collect()
    }

    /// A twist: the exact ones of the built-in tables (as degrees converted, like a DH file
    /// does), or any.
    fn alpha() -> impl Strategy<Value = f64> {
        prop_oneof![
            Just(0.0),
            Just(90.0_f64.to_radians()),
            Just((-90.0_f64).to_radians()),
            Just(FRAC_PI_2),
            Just(PI),
            -PI..PI,
        ]
    }

    /// A length: often exactly zero, as in the built-in tables.
    fn length() -> impl Strategy<Value = f64> {
        prop_oneof![Just(0.0), -1.0..1.0]
    }

    fn dh_row() -> impl Strategy<Value = DhLink> {
        (length(), length(), alpha(), prop_oneof![Just(0.0), -PI..PI])
            .prop_map(|(d, a, alpha, offset)| DhLink::revolute(d, a, alpha, offset))
    }

    /// The identity (the built-in robots' base and tool) or any pose.
    fn pose() -> impl Strategy<Value = Pose> {
        prop_oneof![
            Just(Pose::identity()),
            (
                prop::array::uniform3(-1.0..1.0),
                prop::array::uniform3(-PI..PI)
            )
                .prop_map(|(t, [r, p, y])| Pose::from_parts(
                    Translation3::new(t[0], t[1], t[2]),
                    UnitQuaternion::from_euler_angles(r, p, y)
                )),
        ]
    }

    /// Joint values: within a turn, far outside it (the other argument reductions of `sin_cos`),
    /// and exact zeros.
    fn joints() -> impl Strategy<Value = JointVector> {
        prop::array::uniform6(prop_oneof![
            Just(0.0),
            -PI..PI,
            -1.0e3..1.0e3,
            -1.0e9..1.0e9
        ])
        .prop_map(|q| JointVector::from_column_slice(&q))
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 2000,
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

        #[test]
        fn the_built_in_robots_fast_path_equals_the_general_one_bit_for_bit(q in joints()) {
            for chain in built_in_chains() {
                assert_fast_equals_general(&chain, &q);
            }
        }

        #[test]
        fn any_six_revolute_dh_chains_fast_path_equals_the_general_one_bit_for_bit(
            rows in prop::array::uniform6(dh_row()),
            base in pose(),
            tool in pose(),
            q in joints(),
        ) {
            let chain = SerialChain::new(&rows, &base, &tool).unwrap();
            assert_fast_equals_general(&chain, &q);
        }
    }

    #[test]
    fn only_six_revolute_dh_rows_take_the_fast_path() {
        let row = DhLink::revolute(0.1, 0.2, FRAC_PI_2, 0.0);
        let id = Pose::identity();
        assert!(SerialChain::new(&[row; 6], &id, &id).unwrap().dh6.is_some());
        assert!(SerialChain::new(&[row; 5], &id, &id).unwrap().dh6.is_none());
        let mut rows = [row; 6];
        rows[2] = DhLink::prismatic(0.0, 0.1, 0.0, 0.0);
        assert!(SerialChain::new(&rows, &id, &id).unwrap().dh6.is_none());
        let mut joints = [ChainJoint::Dh(row); 6];
        joints[4] = ChainJoint::Axis(crate::model::AxisJoint::revolute(id, Vector3::z()));
        let mixed = SerialChain::from_joints(&joints, &id, &id).unwrap();
        assert!(mixed.dh6.is_none());
        // Every built-in robot is six revolute DH rows.
        assert!(built_in_chains().iter().all(|c| c.dh6.is_some()));
    }

    #[test]
    fn a_non_finite_joint_value_gives_non_finite_results_on_both_paths() {
        for chain in built_in_chains() {
            for bad in [f64::NAN, f64::INFINITY] {
                let mut q = JointVector::repeat(0.3);
                q[3] = bad;
                let (pose, jac) = chain.forward_and_jacobian(&q, JacobianFrame::Base);
                let (pose_g, jac_g) = chain
                    .general()
                    .forward_and_jacobian(&q, JacobianFrame::Base);
                assert!(pose.rotation.coords.iter().any(|x| x.is_nan()));
                assert!(pose_g.rotation.coords.iter().any(|x| x.is_nan()));
                // Joints before the bad one keep finite columns on both paths alike.
                for c in 0..6 {
                    for r in 0..6 {
                        assert_eq!(jac[(r, c)].is_nan(), jac_g[(r, c)].is_nan(), "({r}, {c})");
                    }
                }
            }
        }
    }
}
