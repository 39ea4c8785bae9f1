//! The pinhole camera model: intrinsics ([`PinholeIntrinsics`]: focal lengths and principal
//! point, pixels) and the camera's pose in the world, with the optical convention (z forward, x right, y down) that
//! ROS's and Foxglove's `CameraCalibration` use, so a frame's calibration describes it exactly.

use nalgebra::{Matrix3, Point3, Rotation3, Unit, Vector3};
use penelope_hal::Pose;

use crate::pinhole::PinholeIntrinsics;

/// Why a camera cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CameraError {
    /// A width or height of zero, or over [`MAX_SIDE`] pixels.
    #[error("a camera image is 1 to {MAX_SIDE} pixels a side, not {0}x{1}")]
    Size(u32, u32),
    /// A field of view outside (0, 170) degrees.
    #[error("a horizontal field of view is between 0 and 170 degrees, not {0}")]
    FieldOfView(f64),
    /// The eye and the target coincide, or the up vector is along the line of sight.
    #[error("the camera's eye, target and up vector do not define a view")]
    Degenerate,
    /// A number is not finite.
    #[error("a camera setting is not finite")]
    NotFinite,
}

/// The largest image side, pixels.
pub const MAX_SIDE: u32 = 4096;

/// A pinhole camera: its intrinsics and its pose.
#[derive(Clone, Debug, PartialEq)]
pub struct PinholeCamera {
    /// Image size, focal lengths and principal point, pixels.
    pub intrinsics: PinholeIntrinsics,
    /// The camera's optical frame in the world (z forward, x right, y down).
    pub pose: Pose,
}

impl PinholeCamera {
    /// A camera at `eye` looking at `target`, `up` roughly up in the image, square pixels, the
    /// principal point at the image's centre, `hfov_deg` across the width.
    ///
    /// # Errors
    /// [`CameraError`] for a size, a field of view or a geometry that makes no camera.
    pub fn look_at(
        eye: [f64; 3],
        target: [f64; 3],
        up: [f64; 3],
        width: u32,
        height: u32,
        hfov_deg: f64,
    ) -> Result<PinholeCamera, CameraError> {
        if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
            return Err(CameraError::Size(width, height));
        }
        let numbers = eye.iter().chain(&target).chain(&up).chain([&hfov_deg]);
        if numbers.into_iter().any(|v| !v.is_finite()) {
            return Err(CameraError::NotFinite);
        }
        if !(hfov_deg > 0.0 && hfov_deg < 170.0) {
            return Err(CameraError::FieldOfView(hfov_deg));
        }
        let (eye, target, up) = (Vector3::from(eye), Vector3::from(target), Vector3::from(up));
        let forward = Unit::try_new(target - eye, 1e-9).ok_or(CameraError::Degenerate)?;
        let right = Unit::try_new(forward.cross(&up), 1e-9).ok_or(CameraError::Degenerate)?;
        // Optical frame: x right, y down, z forward.
        let down = forward.cross(&right);
        let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[
            right.into_inner(),
            down,
            forward.into_inner(),
        ]));
        let intrinsics = PinholeIntrinsics::from_horizontal_fov(width, height, hfov_deg)
            .ok_or(CameraError::FieldOfView(hfov_deg))?;
        Ok(PinholeCamera {
            intrinsics,
            pose: Pose::from_parts(eye.into(), rotation.into()),
        })
    }

    /// A world point in the camera's frame.
    pub fn to_camera(&self, world: &Vector3<f64>) -> Vector3<f64> {
        self.pose
            .inverse_transform_point(&Point3::from(*world))
            .coords
    }

    /// Where a point in the camera's frame falls on the image
    /// ([`PinholeIntrinsics::project`]).
    pub fn project_camera(&self, p: &Vector3<f64>) -> Option<[f64; 3]> {
        self.intrinsics.project(p)
    }

    /// [`project_camera`](Self::project_camera) of a world point.
    pub fn project(&self, world: &Vector3<f64>) -> Option<[f64; 3]> {
        self.project_camera(&self.to_camera(world))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_camera_looking_down_x_projects_the_target_to_the_centre() {
        let c = PinholeCamera::look_at(
            [-1.0, 0.0, 0.5],
            [1.0, 0.0, 0.5],
            [0.0, 0.0, 1.0],
            640,
            480,
            60.0,
        )
        .unwrap();
        let [u, v, d] = c.project(&Vector3::new(1.0, 0.0, 0.5)).unwrap();
        assert!((u - 320.0).abs() < 1e-9 && (v - 240.0).abs() < 1e-9 && (d - 2.0).abs() < 1e-12);
        // +y in the world is to the camera's left (smaller u); +z is up (smaller v).
        let [u, v, _] = c.project(&Vector3::new(1.0, 0.1, 0.6)).unwrap();
        assert!(u < 320.0 && v < 240.0, "{u} {v}");
        // The field of view: a point at the edge of the 60 degree cone lands on the image's edge.
        let half = (30f64).to_radians().tan() * 2.0;
        let [u, _, _] = c.project(&Vector3::new(1.0, -half, 0.5)).unwrap();
        assert!((u - 640.0).abs() < 1e-6, "{u}");
        assert!(
            c.project(&Vector3::new(-2.0, 0.0, 0.5)).is_none(),
            "behind the camera"
        );
    }

    #[test]
    fn bad_cameras_are_refused() {
        let up = [0.0, 0.0, 1.0];
        assert_eq!(
            PinholeCamera::look_at([0.0; 3], [1.0, 0.0, 0.0], up, 0, 480, 60.0),
            Err(CameraError::Size(0, 480))
        );
        assert_eq!(
            PinholeCamera::look_at([0.0; 3], [1.0, 0.0, 0.0], up, 640, 480, 180.0),
            Err(CameraError::FieldOfView(180.0))
        );
        assert_eq!(
            PinholeCamera::look_at([0.0; 3], [0.0; 3], up, 640, 480, 60.0),
            Err(CameraError::Degenerate)
        );
        assert_eq!(
            PinholeCamera::look_at([0.0; 3], [0.0, 0.0, 1.0], up, 640, 480, 60.0),
            Err(CameraError::Degenerate)
        );
        assert_eq!(
            PinholeCamera::look_at([f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], up, 640, 480, 60.0),
            Err(CameraError::NotFinite)
        );
    }
}
