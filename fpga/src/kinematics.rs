//! [`FpgaKinematics`]: the bit-exact model behind the one kinematics trait of `penelope-hal`.

use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use penelope_hal::joint::{JointVector, MAX_JOINTS};
use penelope_hal::robot::{JacobianFrame, Kinematics, KinematicsError};
use penelope_hal::spatial::{Frame, Jacobian, Pose, Wrench};

use crate::cycles::{FK_CYCLES, FORCE_CYCLES};
use crate::dh::{DhTable, JOINTS};
use crate::fixed::{Fx, Overflow, Rounding};
use crate::pipeline::{self, FkWords, ForceWords, POS, ROT, TORQUE, WRENCH};
use crate::sincos::angle_from_radians;

const _: () = assert!(JOINTS == MAX_JOINTS);

/// Forward kinematics, Jacobian and force transformation computed by the bit-exact model of the
/// FPGA pipelines, over a DH table held as data (the FRHC working model by default).
///
/// Float inputs are quantized on the host exactly as the FPGA's host interface would:
/// joint angles to the nearest binary angle (`<+-,24,1>` pi-rad, half-even, wrapped into
/// `[-pi, pi)`), wrench components to the nearest [`WRENCH`] word (half-even, saturated at
/// +-128 N or N m). Outputs are the exact values of the result words.
///
/// The Jacobian is assembled on the host in f64 from the pipeline's bit-exact frame words
/// (`z_j`, `o_j`, `p`); the FPGA itself never forms it, it only computes `J^T F`
/// ([`joint_torques`](FpgaKinematics::joint_torques)).
///
/// ```
/// use penelope_fpga::FpgaKinematics;
/// use penelope_hal::joint::JointVector;
/// use penelope_hal::robot::Kinematics;
///
/// let kin = FpgaKinematics::frhc();
/// let pi = std::f64::consts::PI;
/// let home = JointVector::from([0.0, pi / 3.0, 5.0 * pi / 6.0, 0.0, 0.0, 0.0]);
/// let pose = kin.forward(&home);
/// assert!((pose.translation.vector.norm() - 0.25).abs() < 1e-6);
/// let words = kin.fk_words(&home).unwrap();
/// assert_eq!(words.cycles, penelope_fpga::cycles::FK_CYCLES);
/// ```
///
/// # Real-time
/// Every method is allocation-free, lock-free and constant-time; none panics.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FpgaKinematics {
    table: DhTable,
}

/// One forward-kinematics run: the binary joint angles that went in, every result word, and the
/// modelled hardware cycle count.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FkRun {
    /// The quantized joint angles, raw `<+-,24,1>` pi-rad words.
    pub q: [i32; JOINTS],
    /// The result words.
    pub words: FkWords,
    /// Clock cycles at 40 MHz ([`FK_CYCLES`]).
    pub cycles: u32,
}

/// One force-transformation run (forward kinematics included).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ForceRun {
    /// The forward kinematics it ran first.
    pub fk: FkRun,
    /// The quantized input wrench `[f; m]`, raw [`WRENCH`] words.
    pub wrench: [i32; 6],
    /// True when the wrench was given in a tool-side frame (rotated to the base by the FPGA).
    pub flange_frame: bool,
    /// The result words.
    pub words: ForceWords,
    /// Clock cycles at 40 MHz ([`FORCE_CYCLES`]).
    pub cycles: u32,
}

impl FpgaKinematics {
    /// The model over `table`.
    pub const fn new(table: DhTable) -> FpgaKinematics {
        FpgaKinematics { table }
    }

    /// The FRHC working model ([`DhTable::frhc`]).
    pub const fn frhc() -> FpgaKinematics {
        FpgaKinematics::new(DhTable::frhc())
    }

    /// The DH table in hardware words.
    pub const fn table(&self) -> &DhTable {
        &self.table
    }

    /// The binary joint angles for `q` (rad); joints past the table's count are 0.
    ///
    /// # Errors
    /// [`KinematicsError::NonFinite`] if a used joint is NaN or infinite.
    pub fn quantize_joints(&self, q: &JointVector) -> Result<[i32; JOINTS], KinematicsError> {
        let mut out = [0i32; JOINTS];
        for (j, o) in out.iter_mut().enumerate().take(self.table.joints()) {
            *o = angle_from_radians(q[j]).map_err(|_| KinematicsError::NonFinite)?;
        }
        Ok(out)
    }

    /// Forward kinematics at `q` (rad) with every raw word and the cycle count.
    ///
    /// # Errors
    /// [`KinematicsError::NonFinite`] for a NaN or infinite joint.
    pub fn fk_words(&self, q: &JointVector) -> Result<FkRun, KinematicsError> {
        Ok(self.fk_words_raw(&self.quantize_joints(q)?))
    }

    /// Forward kinematics at binary joint angles (raw `<+-,24,1>` pi-rad words).
    pub fn fk_words_raw(&self, q: &[i32; JOINTS]) -> FkRun {
        FkRun {
            q: *q,
            words: pipeline::forward(&self.table, q),
            cycles: FK_CYCLES,
        }
    }

    /// The tool pose the words stand for (rotation re-orthonormalized through a quaternion; its
    /// entries differ from the words by about one LSB, `2^-23`).
    pub fn pose_of(words: &FkWords) -> Pose {
        let lsb = ROT.lsb();
        let m = Matrix3::from_fn(|i, k| words.r[i][k] as f64 * lsb);
        let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
        let plsb = POS.lsb();
        let t = Translation3::new(
            words.p[0] as f64 * plsb,
            words.p[1] as f64 * plsb,
            words.p[2] as f64 * plsb,
        );
        Pose::from_parts(t, rotation)
    }

    /// The geometric Jacobian of a result, rows `[v; omega]`, in the base frame.
    pub fn jacobian_of(&self, words: &FkWords) -> Jacobian {
        let (rl, pl) = (ROT.lsb(), POS.lsb());
        let p = Vector3::from(words.p.map(|x| x as f64 * pl));
        let mut jac = Jacobian::zeros();
        for j in 0..self.table.joints() {
            let z = Vector3::from(words.z[j].map(|x| x as f64 * rl));
            let o = Vector3::from(words.o[j].map(|x| x as f64 * pl));
            let v = z.cross(&(p - o));
            for i in 0..3 {
                jac[(i, j)] = v[i];
                jac[(3 + i, j)] = z[i];
            }
        }
        jac
    }

    /// Joint torques (N m) balancing `wrench` at the tool, `tau = J^T F`, computed by the force
    /// pipeline. A wrench in [`Frame::Tool`], [`Frame::Flange`] or [`Frame::Sensor`] is taken
    /// as expressed in the flange frame about the flange origin (the FRHC model has no tool
    /// offset; a sensor mounted elsewhere must be moved to the flange by the caller) and is
    /// rotated to the base on the FPGA; [`Frame::Base`] or [`Frame::Master`] are taken as base
    /// frame, about the tool origin. Joints past the table's count get 0.
    ///
    /// # Errors
    /// [`KinematicsError::NonFinite`] for a NaN or infinite joint or wrench component.
    pub fn joint_torques(
        &self,
        q: &JointVector,
        wrench: &Wrench,
    ) -> Result<JointVector, KinematicsError> {
        let run = self.torque_words(q, wrench)?;
        let lsb = TORQUE.lsb();
        let mut tau = JointVector::zeros();
        for j in 0..self.table.joints() {
            tau[j] = run.words.tau[j] as f64 * lsb;
        }
        Ok(tau)
    }

    /// As [`joint_torques`](FpgaKinematics::joint_torques), with every raw word and the cycle
    /// count.
    ///
    /// # Errors
    /// [`KinematicsError::NonFinite`] for a NaN or infinite joint or wrench component.
    pub fn torque_words(
        &self,
        q: &JointVector,
        wrench: &Wrench,
    ) -> Result<ForceRun, KinematicsError> {
        let q = self.quantize_joints(q)?;
        let w = wrench.to_vector();
        let mut raw = [0i32; 6];
        for (r, x) in raw.iter_mut().zip(w.iter()) {
            *r = Fx::from_f64(*x, WRENCH, Rounding::HalfEven, Overflow::Saturate)
                .map_err(|_| KinematicsError::NonFinite)?
                .raw() as i32;
        }
        let flange = matches!(wrench.frame, Frame::Tool | Frame::Flange | Frame::Sensor);
        Ok(self.torque_words_raw(&q, &raw, flange))
    }

    /// The force pipeline on raw words: binary joint angles, wrench words `[f; m]`, and whether
    /// the wrench is in the flange frame.
    pub fn torque_words_raw(&self, q: &[i32; JOINTS], wrench: &[i32; 6], flange: bool) -> ForceRun {
        let fk = self.fk_words_raw(q);
        ForceRun {
            fk,
            wrench: *wrench,
            flange_frame: flange,
            words: pipeline::joint_torques(&fk.words, wrench, flange),
            cycles: FORCE_CYCLES,
        }
    }
}

impl Default for FpgaKinematics {
    fn default() -> Self {
        FpgaKinematics::frhc()
    }
}

fn nan_pose() -> Pose {
    Pose::from_parts(
        Translation3::new(f64::NAN, f64::NAN, f64::NAN),
        UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
            f64::NAN,
            f64::NAN,
            f64::NAN,
            f64::NAN,
        )),
    )
}

impl Kinematics for FpgaKinematics {
    fn joint_count(&self) -> usize {
        self.table.joints()
    }

    fn forward(&self, q: &JointVector) -> Pose {
        match self.fk_words(q) {
            Ok(run) => FpgaKinematics::pose_of(&run.words),
            Err(_) => nan_pose(),
        }
    }

    fn jacobian(&self, q: &JointVector, frame: JacobianFrame) -> Jacobian {
        let Ok(run) = self.fk_words(q) else {
            return Jacobian::from_element(f64::NAN);
        };
        let jac = self.jacobian_of(&run.words);
        match frame {
            JacobianFrame::Base => jac,
            JacobianFrame::Tool => {
                let lsb = ROT.lsb();
                let rt = Matrix3::from_fn(|i, k| run.words.r[k][i] as f64 * lsb);
                let mut out = jac;
                for j in 0..MAX_JOINTS {
                    let v = rt * jac.fixed_view::<3, 1>(0, j);
                    let w = rt * jac.fixed_view::<3, 1>(3, j);
                    out.fixed_view_mut::<3, 1>(0, j).copy_from(&v);
                    out.fixed_view_mut::<3, 1>(3, j).copy_from(&w);
                }
                out
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::FloatChain;

    #[test]
    fn trait_methods_agree_with_the_float_chain() {
        let kin = FpgaKinematics::frhc();
        let chain = FloatChain::new(&DhTable::frhc_params());
        let q = JointVector::from([0.3, 0.9, 2.1, -0.4, 0.7, 1.2]);
        let pose = kin.forward(&q);
        let fl = chain.forward_frames(&q.into(), libm::sincos);
        let p = Vector3::from(fl.p);
        assert!((pose.translation.vector - p).norm() < 2e-6);
        let j = kin.jacobian(&q, JacobianFrame::Base);
        // Column 1 by finite difference of the float model.
        let h = 1e-6;
        let mut q2 = q;
        q2[1] += h;
        let (_, p2) = chain.forward(&q2.into(), libm::sincos);
        let col = (Vector3::from(p2) - p) / h;
        assert!((j.fixed_view::<3, 1>(0, 1) - col).norm() < 1e-4);
        let jt = kin.jacobian(&q, JacobianFrame::Tool);
        assert!((jt.column(3).norm() - j.column(3).norm()).abs() < 1e-6);
    }

    #[test]
    fn torques_are_j_transpose_f() {
        let kin = FpgaKinematics::frhc();
        let q = JointVector::from([0.3, 0.9, 2.1, -0.4, 0.7, 1.2]);
        let w = Wrench {
            force: Vector3::new(3.0, -2.0, 5.0),
            torque: Vector3::new(0.1, 0.2, -0.3),
            frame: Frame::Base,
        };
        let tau = kin.joint_torques(&q, &w).unwrap();
        let expect = kin.jacobian(&q, JacobianFrame::Base).transpose() * w.to_vector();
        assert!((tau - expect).norm() < 1e-4, "{tau} vs {expect}");
        // The same wrench expressed in the tool frame gives the same torques.
        let pose = kin.forward(&q);
        let r = pose.rotation.inverse();
        let wt = Wrench {
            force: r * w.force,
            torque: r * w.torque,
            frame: Frame::Tool,
        };
        let tau_t = kin.joint_torques(&q, &wt).unwrap();
        assert!((tau - tau_t).norm() < 1e-4);
        let bad = Wrench {
            force: Vector3::new(f64::NAN, 0.0, 0.0),
            ..w
        };
        assert_eq!(kin.joint_torques(&q, &bad), Err(KinematicsError::NonFinite));
        let mut qn = q;
        qn[2] = f64::INFINITY;
        assert!(kin.forward(&qn).translation.vector.x.is_nan());
        assert_eq!(kin.fk_words(&qn), Err(KinematicsError::NonFinite));
    }
}
