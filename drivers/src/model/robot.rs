//! [`SerialRobotModel`]: a DH chain with dynamics, limits, inverse kinematics and named poses,
//! implementing the hal model traits; [`DhRobot`]: the model with a measured state, the hal
//! [`Robot`].

use nalgebra::Vector3;
use penelope_hal::{
    Dynamics, IkSolution, IkSolutions, InverseKinematics, Jacobian, JacobianFrame, JointLimits,
    JointSpaceMatrix, JointState, JointVector, Kinematics, KinematicsError, MAX_JOINTS, NamedPose,
    Pose, Robot, RobotModel,
};

use super::chain::{ChainError, ChainJoint, SerialChain};
use super::dh::{JointKind, Rt};
use super::dynamics::{self, LinkDynamics};
use super::links::LinkTree;
use super::numeric_ik::{self, DlsOptions};
use super::puma::{self, PumaIk};

/// How inverse kinematics is solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum IkMethod {
    /// The closed form when the chain has the PUMA structure (see [`super::puma`]), else
    /// numerical.
    #[default]
    Auto,
    /// Always damped least squares.
    Numerical,
}

/// Everything that defines a model, in SI units (m, rad, kg). Build one by hand or from a DH
/// file ([`super::file`]), then [`SerialRobotModel::new`].
#[derive(Clone, Debug, PartialEq)]
pub struct ModelSpec {
    /// Short name, for example `"puma560"`.
    pub name: String,
    /// One line about the model and where its numbers come from.
    pub description: String,
    /// Values that are assumptions rather than measurements, one sentence each.
    pub assumptions: Vec<String>,
    /// Joint names, one per link.
    pub joint_names: Vec<String>,
    /// The joints, base to tip, 1 to [`MAX_JOINTS`]: DH rows (a DH file) or axis joints (a URDF).
    pub joints: Vec<ChainJoint>,
    /// Mass properties and drives, one per link.
    pub dynamics: Vec<LinkDynamics>,
    /// Pose of the robot's frame 0 in the world frame.
    pub base: Pose,
    /// Pose of the tool frame in the last link's frame.
    pub tool: Pose,
    /// Gravitational acceleration in the world frame, m/s².
    pub gravity: Vector3<f64>,
    /// Joint envelope (entries past the joint count are ignored).
    pub limits: JointLimits,
    /// Encoder counts per joint radian (per metre for a prismatic joint), one per link; the sign
    /// gives the counting direction.
    pub counts_per_radian: Vec<f64>,
    /// Named joint configurations; `nest`, `start` and `work` are required.
    pub poses: Vec<(String, JointVector)>,
    /// Inverse-kinematics method.
    pub ik: IkMethod,
    /// The robot's links and its own URDF, for a robot read from a URDF (`None`: derived from
    /// the chain: `base_link`, `link1`..`linkN`, `tool`; see [`super::links`]).
    pub links: Option<LinkTree>,
}

/// Why a [`ModelSpec`] is not a valid model.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// The DH table itself is malformed.
    #[error(transparent)]
    Chain(#[from] ChainError),
    /// A per-joint list has the wrong length.
    #[error("{what}: expected {expected} entries (one per joint), got {got}")]
    Length {
        /// Which list.
        what: &'static str,
        /// The joint count.
        expected: usize,
        /// What was given.
        got: usize,
    },
    /// A number is NaN or infinite, or out of its domain (negative mass, lo > hi, zero counts).
    #[error("invalid value: {0}")]
    Invalid(String),
    /// One of `nest`, `start`, `work` is missing.
    #[error("named pose `{0}` is missing (nest, start and work are required)")]
    MissingPose(&'static str),
}

/// A robot model from a standard DH table: forward kinematics, the geometric Jacobian, inverse
/// kinematics (closed form for the PUMA structure, damped least squares otherwise), gravity,
/// inertia, recursive Newton-Euler and friction.
///
/// Dynamics follow the Robotics Toolbox conventions: [`Dynamics::gravity`] is the *holding*
/// torque, [`Dynamics::inertia`] has `Jm G²` on its diagonal.
///
/// # Real-time
/// Every trait method (and [`forward_and_jacobian`](SerialRobotModel::forward_and_jacobian),
/// [`inverse_numerical`](SerialRobotModel::inverse_numerical)) works on the stack: no allocation, no
/// locks, bounded time. Numerical inverse kinematics is bounded by
/// [`DlsOptions::max_iterations`] per seed.
#[derive(Clone, Debug, PartialEq)]
pub struct SerialRobotModel {
    kind: &'static str,
    name: String,
    description: String,
    assumptions: Vec<String>,
    joint_names: Vec<String>,
    chain: SerialChain,
    dynamics: [LinkDynamics; MAX_JOINTS],
    gravity: Vector3<f64>,
    limits: JointLimits,
    counts_per_radian: [f64; MAX_JOINTS],
    named: [JointVector; 3],
    poses: Vec<(String, JointVector)>,
    closed_form: Option<PumaIk>,
    seeds: [JointVector; NUM_SEEDS],
    dls: DlsOptions,
    base_inv: Rt,
    tool_inv: Rt,
    links: LinkTree,
}

/// Number of seeds [`InverseKinematics::inverse_all`] tries on a numerical model.
const NUM_SEEDS: usize = 8;
/// Two numerical solutions closer than this (rad, after wrapping) are the same one.
const SAME_SOLUTION: f64 = 1e-6;

impl SerialRobotModel {
    /// Builds and checks a model. `kind` is what [`Robot::kind`] reports (`"dh"` for a lab's
    /// file).
    ///
    /// # Errors
    /// [`ModelError`] for a malformed table, mismatched lengths, non-finite or out-of-domain
    /// values, or a missing named pose.
    pub fn new(kind: &'static str, spec: ModelSpec) -> Result<Self, ModelError> {
        let chain = SerialChain::from_joints(&spec.joints, &spec.base, &spec.tool)?;
        let n = chain.joint_count();
        let check_len = |what, got| {
            if got == n {
                Ok(())
            } else {
                Err(ModelError::Length {
                    what,
                    expected: n,
                    got,
                })
            }
        };
        check_len("dynamics", spec.dynamics.len())?;
        check_len("counts_per_radian", spec.counts_per_radian.len())?;
        if !spec.joint_names.is_empty() {
            check_len("joint_names", spec.joint_names.len())?;
        }
        let dynamics = checked_dynamics(&spec.dynamics)?;
        if !spec.gravity.iter().all(|g| g.is_finite()) {
            return Err(ModelError::Invalid("gravity must be finite".into()));
        }
        let counts = checked_counts(&spec.counts_per_radian)?;
        let limits = checked_limits(&spec.limits, n)?;
        let named = named_poses(&spec.poses)?;
        let closed_form = match spec.ik {
            IkMethod::Auto => PumaIk::detect(&chain),
            IkMethod::Numerical => None,
        };
        let seeds = ik_seeds(&named, &limits, n);
        let base_inv = Rt::from_pose(&spec.base).inverse();
        let tool_inv = Rt::from_pose(&spec.tool).inverse();
        let links = match spec.links {
            Some(links) if links.fits(n) => links,
            _ => LinkTree::from_chain(&chain),
        };
        Ok(SerialRobotModel {
            kind,
            name: spec.name,
            description: spec.description,
            assumptions: spec.assumptions,
            joint_names: if spec.joint_names.is_empty() {
                (1..=n).map(|j| format!("q{j}")).collect()
            } else {
                spec.joint_names
            },
            chain,
            dynamics,
            gravity: spec.gravity,
            limits,
            counts_per_radian: counts,
            named,
            poses: spec.poses,
            closed_form,
            seeds,
            dls: DlsOptions::default(),
            base_inv,
            tool_inv,
            links,
        })
    }

    /// The model's short name (from its file).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// What [`Robot::kind`] reports: `"puma560"`, `"puma200"`, `"frhc"`, or `"dh"` for a model
    /// loaded from a lab's file.
    pub fn kind(&self) -> &'static str {
        self.kind
    }

    /// One line about the model and its sources.
    pub fn description(&self) -> &str {
        &self.description
    }

    /// Values that are assumptions rather than measurements.
    pub fn assumptions(&self) -> &[String] {
        &self.assumptions
    }

    /// Joint names.
    pub fn joint_names(&self) -> &[String] {
        &self.joint_names
    }

    /// The robot's frames, root first, the tool frame last: `base_link`, `link1`..`linkN`,
    /// `tool` for a DH robot; a URDF robot's own link names (its chain's base link first, its
    /// tip link last). See [`super::links`] for where each frame is.
    pub fn link_names(&self) -> Vec<String> {
        self.links.names()
    }

    /// The pose of each frame of [`link_names`](Self::link_names) in the root frame at `q`: the
    /// root's is the identity, the last equals [`Kinematics::forward`].
    ///
    /// # Real-time
    /// Allocates its answer: for recordings, viewers and clients, not a control loop.
    pub fn link_frames(&self, q: &JointVector) -> Vec<Pose> {
        self.links.frames(q)
    }

    /// A URDF whose link names are [`link_names`](Self::link_names): a URDF robot's own text;
    /// for a DH robot one generated from the chain (fixed joints for the base and tool
    /// transforms, revolute, continuous or prismatic joints with the limits, cylinders and boxes
    /// as visual geometry), such that a URDF viewer's forward kinematics at `q` puts every link
    /// at [`link_frames(q)`](Self::link_frames).
    pub fn urdf(&self) -> String {
        self.links.urdf(&self.name, &self.joint_names, &self.limits)
    }

    /// The kinematic chain (DH table, base and tool).
    pub fn chain(&self) -> &SerialChain {
        &self.chain
    }

    /// Mass properties and drive of joint `j` (0-based), or `None` past the joint count.
    pub fn link_dynamics(&self, j: usize) -> Option<&LinkDynamics> {
        (j < self.chain.joint_count()).then(|| &self.dynamics[j])
    }

    /// Gravitational acceleration in the world frame, m/s².
    pub fn gravity_vector(&self) -> Vector3<f64> {
        self.gravity
    }

    /// True when inverse kinematics uses the closed form (8 named branches).
    pub fn has_closed_form(&self) -> bool {
        self.closed_form.is_some()
    }

    /// Encoder counts per joint radian of joint `j` (0-based); 1 past the joint count.
    pub fn counts_per_radian(&self, j: usize) -> f64 {
        self.counts_per_radian.get(j).copied().unwrap_or(1.0)
    }

    /// A named configuration (`nest`, `start`, `work`, or any other name in the file).
    pub fn pose(&self, name: &str) -> Option<JointVector> {
        self.poses.iter().find(|(n, _)| n == name).map(|(_, q)| *q)
    }

    /// Every named configuration, in file order.
    pub fn poses(&self) -> &[(String, JointVector)] {
        &self.poses
    }

    /// The joint positions of one of the three standard named poses.
    pub fn named_pose(&self, pose: NamedPose) -> JointVector {
        match pose {
            NamedPose::Nest => self.named[0],
            NamedPose::Start => self.named[1],
            NamedPose::Work => self.named[2],
        }
    }

    /// The settings of the numerical solver.
    pub fn dls_options(&self) -> &DlsOptions {
        &self.dls
    }

    /// Replaces the settings of the numerical solver.
    pub fn set_dls_options(&mut self, options: DlsOptions) {
        self.dls = options;
    }

    /// Forward kinematics and the Jacobian from one pass over the links.
    ///
    /// # Real-time
    /// No allocation, bounded time.
    pub fn forward_and_jacobian(&self, q: &JointVector, frame: JacobianFrame) -> (Pose, Jacobian) {
        self.chain.forward_and_jacobian(q, frame)
    }

    /// The tool pose as a 4x4 homogeneous matrix.
    ///
    /// # Real-time
    /// No allocation, bounded time.
    pub fn forward_matrix(&self, q: &JointVector) -> nalgebra::Matrix4<f64> {
        self.chain.forward_matrix(q)
    }

    /// Damped least squares from `seed` to the tool pose `target`, whatever the chain. The result
    /// is not wrapped into the joint limits.
    ///
    /// # Errors
    /// [`KinematicsError::NonFinite`] for NaN input, [`KinematicsError::NoConvergence`] when the
    /// solver does not reach tolerance (unreachable target, or a bad seed).
    ///
    /// # Real-time
    /// No allocation; at most [`DlsOptions::max_iterations`] iterations.
    pub fn inverse_numerical(
        &self,
        target: &Pose,
        seed: &JointVector,
    ) -> Result<JointVector, KinematicsError> {
        check_pose(target)?;
        penelope_hal::robot::check_finite(seed)?;
        let t = Rt::from_pose(target);
        numeric_ik::solve(&self.chain, &t, seed, &self.dls).map(|(q, _)| q)
    }

    /// Holding torque (N·m) at `q` for a different gravity vector (m/s², world frame).
    ///
    /// # Real-time
    /// No allocation, bounded time.
    pub fn gravity_with(&self, q: &JointVector, gravity: &Vector3<f64>) -> JointVector {
        dynamics::gravity(&self.chain, &self.dynamics, gravity, q)
    }

    /// Recursive Newton-Euler with a different gravity vector (zero for pure inertial torques).
    ///
    /// # Real-time
    /// No allocation, bounded time.
    pub fn inverse_dynamics_with(
        &self,
        q: &JointVector,
        qd: &JointVector,
        qdd: &JointVector,
        gravity: &Vector3<f64>,
    ) -> JointVector {
        dynamics::rne(&self.chain, &self.dynamics, gravity, q, qd, qdd)
    }

    fn kind_of(&self, j: usize) -> JointKind {
        self.chain.geometry(j).kind()
    }

    /// The flange frame (in frame 0) for a tool pose in the world frame.
    fn flange_target(&self, target: &Pose) -> Rt {
        self.base_inv
            .mul(&Rt::from_pose(target))
            .mul(&self.tool_inv)
    }

    fn closed_form_all(
        &self,
        ik: &PumaIk,
        target: &Pose,
        wrist_hint: f64,
    ) -> Result<[JointVector; 8], KinematicsError> {
        let mut sols = [JointVector::zeros(); 8];
        ik.solve(
            &self.chain,
            &self.flange_target(target),
            wrist_hint,
            &mut sols,
        )?;
        Ok(sols)
    }

    fn fit(&self, q: &mut JointVector, target: &JointVector) -> bool {
        puma::fit_limits(
            q,
            self.chain.joint_count(),
            |j| self.kind_of(j),
            &self.limits.position_min,
            &self.limits.position_max,
            target,
        )
    }
}

fn check_pose(p: &Pose) -> Result<(), KinematicsError> {
    if p.translation.vector.iter().all(|x| x.is_finite())
        && p.rotation.coords.iter().all(|x| x.is_finite())
    {
        Ok(())
    } else {
        Err(KinematicsError::NonFinite)
    }
}

/// Largest difference between two configurations, revolute joints compared modulo 2π.
fn wrapped_distance(
    a: &JointVector,
    b: &JointVector,
    n: usize,
    kinds: impl Fn(usize) -> JointKind,
) -> f64 {
    (0..n)
        .map(|j| match kinds(j) {
            JointKind::Revolute => puma::principal(a[j] - b[j]).abs(),
            JointKind::Prismatic => (a[j] - b[j]).abs(),
        })
        .fold(0.0, f64::max)
}

impl Kinematics for SerialRobotModel {
    fn joint_count(&self) -> usize {
        self.chain.joint_count()
    }

    fn forward(&self, q: &JointVector) -> Pose {
        self.chain.forward(q)
    }

    fn jacobian(&self, q: &JointVector, frame: JacobianFrame) -> Jacobian {
        self.chain.jacobian(q, frame)
    }
}

impl InverseKinematics for SerialRobotModel {
    /// Closed form: all 8 branches in [`super::puma::BRANCHES`] order, each joint the
    /// 2π-equivalent inside its limits nearest zero. Numerical: the distinct solutions reached
    /// from up to 8 seeds (the named poses first), branch `"numerical"`.
    fn inverse_all(&self, target: &Pose, out: &mut IkSolutions) -> Result<usize, KinematicsError> {
        out.clear();
        check_pose(target)?;
        let zero = JointVector::zeros();
        if let Some(ik) = &self.closed_form {
            let sols = self.closed_form_all(ik, target, 0.0)?;
            for (k, mut q) in sols.into_iter().enumerate() {
                let within_limits = self.fit(&mut q, &zero);
                // Capacity is 8, exactly the branch count.
                let _ = out.push(IkSolution {
                    branch: puma::BRANCHES[k],
                    q,
                    within_limits,
                });
            }
            return Ok(out.len());
        }
        let t = Rt::from_pose(target);
        let n = self.chain.joint_count();
        for seed in &self.seeds {
            let Ok((mut q, _)) = numeric_ik::solve(&self.chain, &t, seed, &self.dls) else {
                continue;
            };
            let within_limits = self.fit(&mut q, &zero);
            if out
                .iter()
                .any(|s| wrapped_distance(&s.q, &q, n, |j| self.kind_of(j)) < SAME_SOLUTION)
            {
                continue;
            }
            if out
                .push(IkSolution {
                    branch: "numerical",
                    q,
                    within_limits,
                })
                .is_err()
            {
                break;
            }
        }
        if out.is_empty() {
            Err(KinematicsError::NoConvergence)
        } else {
            Ok(out.len())
        }
    }

    /// Closed form: the branch nearest `seed` (largest joint difference, after picking each
    /// joint's 2π-equivalent nearest the seed within limits); at a wrist singularity `q4` stays
    /// at the seed's. Numerical: damped least squares from `seed`.
    fn inverse_near(
        &self,
        target: &Pose,
        seed: &JointVector,
    ) -> Result<JointVector, KinematicsError> {
        check_pose(target)?;
        penelope_hal::robot::check_finite(seed)?;
        let n = self.chain.joint_count();
        if let Some(ik) = &self.closed_form {
            let sols = self.closed_form_all(ik, target, seed[3])?;
            let mut best: Option<(f64, JointVector)> = None;
            for mut q in sols {
                if !self.fit(&mut q, seed) {
                    continue;
                }
                let d = (0..n).map(|j| (q[j] - seed[j]).abs()).fold(0.0, f64::max);
                if best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((d, q));
                }
            }
            return best.map(|(_, q)| q).ok_or(KinematicsError::OutOfLimits);
        }
        let t = Rt::from_pose(target);
        let (mut q, _) = numeric_ik::solve(&self.chain, &t, seed, &self.dls)?;
        if self.fit(&mut q, seed) {
            Ok(q)
        } else {
            Err(KinematicsError::OutOfLimits)
        }
    }
}

impl Dynamics for SerialRobotModel {
    fn gravity(&self, q: &JointVector) -> JointVector {
        dynamics::gravity(&self.chain, &self.dynamics, &self.gravity, q)
    }

    fn inertia(&self, q: &JointVector) -> JointSpaceMatrix {
        dynamics::inertia(&self.chain, &self.dynamics, q)
    }

    fn inverse_dynamics(
        &self,
        q: &JointVector,
        qd: &JointVector,
        qdd: &JointVector,
    ) -> JointVector {
        dynamics::rne(&self.chain, &self.dynamics, &self.gravity, q, qd, qdd)
    }

    fn friction(&self, qd: &JointVector) -> JointVector {
        dynamics::friction(self.chain.joint_count(), &self.dynamics, qd)
    }
}

impl RobotModel for SerialRobotModel {
    fn limits(&self) -> &JointLimits {
        &self.limits
    }
}

/// A robot built on a [`SerialRobotModel`]: the model, its latest measured joint state and its
/// encoder scaling. Implements [`Robot`] (and, through the model, every model trait).
#[derive(Clone, Debug, PartialEq)]
pub struct DhRobot {
    model: SerialRobotModel,
    state: JointState,
}

impl DhRobot {
    /// A robot at rest at its `start` pose.
    pub fn new(model: SerialRobotModel) -> Self {
        let state = JointState::at_rest(model.named_pose(NamedPose::Start));
        DhRobot { model, state }
    }

    /// The model.
    pub fn model(&self) -> &SerialRobotModel {
        &self.model
    }

    /// The model, mutably (for example to tune the numerical solver).
    pub fn model_mut(&mut self) -> &mut SerialRobotModel {
        &mut self.model
    }
}

impl Kinematics for DhRobot {
    fn joint_count(&self) -> usize {
        self.model.joint_count()
    }
    fn forward(&self, q: &JointVector) -> Pose {
        self.model.forward(q)
    }
    fn jacobian(&self, q: &JointVector, frame: JacobianFrame) -> Jacobian {
        self.model.jacobian(q, frame)
    }
}

impl InverseKinematics for DhRobot {
    fn inverse_all(&self, target: &Pose, out: &mut IkSolutions) -> Result<usize, KinematicsError> {
        self.model.inverse_all(target, out)
    }
    fn inverse_near(
        &self,
        target: &Pose,
        seed: &JointVector,
    ) -> Result<JointVector, KinematicsError> {
        self.model.inverse_near(target, seed)
    }
}

impl Dynamics for DhRobot {
    fn gravity(&self, q: &JointVector) -> JointVector {
        Dynamics::gravity(&self.model, q)
    }
    fn inertia(&self, q: &JointVector) -> JointSpaceMatrix {
        self.model.inertia(q)
    }
    fn inverse_dynamics(
        &self,
        q: &JointVector,
        qd: &JointVector,
        qdd: &JointVector,
    ) -> JointVector {
        self.model.inverse_dynamics(q, qd, qdd)
    }
    fn friction(&self, qd: &JointVector) -> JointVector {
        self.model.friction(qd)
    }
}

impl RobotModel for DhRobot {
    fn limits(&self) -> &JointLimits {
        self.model.limits()
    }
}

impl Robot for DhRobot {
    fn kind(&self) -> &'static str {
        self.model.kind
    }

    fn joint_state(&self) -> &JointState {
        &self.state
    }

    fn set_joint_state(&mut self, state: JointState) {
        self.state = state;
    }

    fn counts_per_radian(&self, joint: usize) -> f64 {
        self.model.counts_per_radian(joint)
    }

    fn named_pose(&self, pose: NamedPose) -> JointVector {
        self.model.named_pose(pose)
    }
}

/// Each joint's dynamics, checked: finite, mass, motor inertia and viscous friction
/// non-negative, link inertia symmetric positive semi-definite (massless past the joints).
fn checked_dynamics(given: &[LinkDynamics]) -> Result<[LinkDynamics; MAX_JOINTS], ModelError> {
    let mut dynamics = [LinkDynamics::massless(); MAX_JOINTS];
    for (j, d) in given.iter().enumerate() {
        if !d.is_finite() || d.mass < 0.0 || d.motor_inertia < 0.0 || d.viscous < 0.0 {
            return Err(ModelError::Invalid(format!(
                "joint {}: dynamics must be finite, mass, motor inertia and viscous friction non-negative",
                j + 1
            )));
        }
        let sym = (d.inertia - d.inertia.transpose()).abs().max();
        let eig = d.inertia.symmetric_eigenvalues();
        if sym > 1e-12 || eig.iter().any(|&e| e < -1e-12) {
            return Err(ModelError::Invalid(format!(
                "joint {}: link inertia must be symmetric positive semi-definite",
                j + 1
            )));
        }
        dynamics[j] = *d;
    }
    Ok(dynamics)
}

/// Each joint's encoder counts per radian, checked finite and non-zero (1 past the joints).
fn checked_counts(given: &[f64]) -> Result<[f64; MAX_JOINTS], ModelError> {
    let mut counts = [1.0; MAX_JOINTS];
    for (j, c) in given.iter().enumerate() {
        if !c.is_finite() || *c == 0.0 {
            return Err(ModelError::Invalid(format!(
                "joint {}: counts per radian must be finite and non-zero",
                j + 1
            )));
        }
        counts[j] = *c;
    }
    Ok(counts)
}

/// The first `n` joints' limits, checked: min <= max, positive speed and effort limits
/// (unbounded past the joints).
fn checked_limits(lim: &JointLimits, n: usize) -> Result<JointLimits, ModelError> {
    for j in 0..n {
        if lim.position_min[j].is_nan()
            || lim.position_max[j].is_nan()
            || lim.position_min[j] > lim.position_max[j]
            || lim.velocity_max[j].is_nan()
            || lim.velocity_max[j] <= 0.0
            || lim.effort_max[j].is_nan()
            || lim.effort_max[j] <= 0.0
        {
            return Err(ModelError::Invalid(format!(
                "joint {}: limits need min <= max and positive speed and effort limits",
                j + 1
            )));
        }
    }
    let mut limits = JointLimits::unbounded();
    for j in 0..n {
        limits.position_min[j] = lim.position_min[j];
        limits.position_max[j] = lim.position_max[j];
        limits.velocity_max[j] = lim.velocity_max[j];
        limits.effort_max[j] = lim.effort_max[j];
    }
    Ok(limits)
}

/// The named poses nest, start and work, each required; every pose given checked finite.
fn named_poses(poses: &[(String, JointVector)]) -> Result<[JointVector; 3], ModelError> {
    for (name, q) in poses {
        if !q.iter().all(|x| x.is_finite()) {
            return Err(ModelError::Invalid(format!("pose `{name}` is not finite")));
        }
    }
    let find = |p: NamedPose| {
        poses
            .iter()
            .find(|(name, _)| name == p.as_str())
            .map(|(_, q)| *q)
            .ok_or(ModelError::MissingPose(p.as_str()))
    };
    Ok([
        find(NamedPose::Nest)?,
        find(NamedPose::Start)?,
        find(NamedPose::Work)?,
    ])
}

/// Seeds for the numerical solver: the named poses, zero, the middle of the envelope and a
/// few fixed spread-out configurations.
fn ik_seeds(named: &[JointVector; 3], limits: &JointLimits, n: usize) -> [JointVector; NUM_SEEDS] {
    let mut seeds = [JointVector::zeros(); NUM_SEEDS];
    seeds[0] = named[1];
    seeds[1] = named[2];
    seeds[2] = named[0];
    for (k, seed) in seeds.iter_mut().enumerate().skip(4) {
        for j in 0..n {
            let (lo, hi) = (limits.position_min[j], limits.position_max[j]);
            let (lo, hi) = if lo.is_finite() && hi.is_finite() {
                (lo, hi)
            } else {
                (-core::f64::consts::PI, core::f64::consts::PI)
            };
            // Seed 4: the middle of the envelope; then fixed, irregular fractions of it.
            let f = if k == 4 {
                0.5
            } else {
                0.1 + 0.8 * ((j as f64 + 1.0) * 0.618_033_988_749_895 * (k - 3) as f64).fract()
            };
            seed[j] = lo + f * (hi - lo);
        }
    }
    seeds
}
