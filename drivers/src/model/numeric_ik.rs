//! Numerical inverse kinematics for any chain: damped least squares (Levenberg-Marquardt) on the
//! geometric Jacobian, with a bounded number of iterations.

use nalgebra::{Matrix3, Matrix6, Rotation3, Vector3, Vector6};
use penelope_hal::{JacobianFrame, JointVector, KinematicsError};

use super::chain::SerialChain;
use super::dh::Rt;

/// Settings of the damped-least-squares solver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DlsOptions {
    /// Largest number of iterations (each one forward kinematics, a Jacobian and a 6x6
    /// Cholesky solve).
    pub max_iterations: usize,
    /// Converged when the pose error `|[dp; dtheta]|` falls below this (m and rad together).
    pub tolerance: f64,
    /// Initial damping `lambda` (the step solves `(J J^T + lambda² I) y = e`, `dq = J^T y`).
    pub initial_damping: f64,
    /// Largest joint step per iteration, rad (the step is scaled down to this norm).
    pub max_step: f64,
}

impl Default for DlsOptions {
    fn default() -> Self {
        DlsOptions {
            max_iterations: 200,
            tolerance: 1e-10,
            initial_damping: 1e-2,
            max_step: 0.5,
        }
    }
}

/// The pose error `[p_t - p; log(R_t R^T)]` in the world frame.
#[inline]
pub(crate) fn pose_error(target: &Rt, current: &Rt) -> Vector6<f64> {
    let dp = target.p - current.p;
    let dr = log_rotation(&(target.r * current.r.transpose()));
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

/// The rotation vector (axis times angle, rad) of `r`, accurate near the identity (where
/// `acos` of the trace loses half the digits).
#[inline]
pub(crate) fn log_rotation(r: &Matrix3<f64>) -> Vector3<f64> {
    // v = sin(theta) * axis, c = cos(theta).
    let v = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    ) * 0.5;
    let c = 0.5 * (r.trace() - 1.0);
    let s = v.norm();
    if s < 1e-9 {
        if c > 0.0 {
            return v; // theta ~ sin(theta)
        }
        // Near a half turn the skew part vanishes: take the axis from the symmetric part.
        return Rotation3::from_matrix_unchecked(*r).scaled_axis();
    }
    v * (s.atan2(c) / s)
}

/// Solves for the tool frame `target` (world frame) from `seed`. Returns the solution and the
/// number of iterations used.
///
/// # Errors
/// [`KinematicsError::NoConvergence`] when the error stays above tolerance after
/// `max_iterations`, or the damping grows without progress (an unreachable target).
pub(crate) fn solve(
    chain: &SerialChain,
    target: &Rt,
    seed: &JointVector,
    opts: &DlsOptions,
) -> Result<(JointVector, usize), KinematicsError> {
    let mut q = *seed;
    let (t, mut jac) = chain.forward_and_jacobian_rt(&q, JacobianFrame::Base);
    let mut e = pose_error(target, &t);
    let mut cost = e.norm_squared();
    let mut lambda = opts.initial_damping;
    let tol2 = opts.tolerance * opts.tolerance;
    for it in 0..opts.max_iterations {
        if cost <= tol2 {
            return Ok((q, it));
        }
        let a = jac * jac.transpose() + Matrix6::identity() * (lambda * lambda);
        let Some(ch) = a.cholesky() else {
            lambda *= 4.0;
            continue;
        };
        let mut dq = jac.transpose() * ch.solve(&e);
        let norm = dq.norm();
        if norm > opts.max_step {
            dq *= opts.max_step / norm;
        }
        let q_new = q + dq;
        let (t_new, jac_new) = chain.forward_and_jacobian_rt(&q_new, JacobianFrame::Base);
        let e_new = pose_error(target, &t_new);
        let cost_new = e_new.norm_squared();
        if cost_new < cost {
            q = q_new;
            jac = jac_new;
            e = e_new;
            cost = cost_new;
            lambda = (lambda * 0.3).max(1e-9);
        } else {
            lambda *= 4.0;
            if lambda > 1e6 {
                break;
            }
        }
    }
    if cost <= tol2 {
        Ok((q, opts.max_iterations))
    } else {
        Err(KinematicsError::NoConvergence)
    }
}
