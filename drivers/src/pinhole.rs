//! A camera's pinhole intrinsics (focal lengths and principal point, pixels), shared by the
//! simulated camera ([`crate::sim::camera::PinholeCamera`], which adds its pose) and the V4L2
//! one (which has no calibration: the intrinsics come from the image size and a configured
//! horizontal field of view, square pixels, the principal point at the image's centre).

use nalgebra::Vector3;

/// Pinhole intrinsics of an (undistorted) image, in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PinholeIntrinsics {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
}

impl PinholeIntrinsics {
    /// From the horizontal field of view (degrees, in (0, 180)); `None` for a field of view out
    /// of range or an empty image.
    pub fn from_horizontal_fov(width: u32, height: u32, hfov_deg: f64) -> Option<Self> {
        if width == 0 || height == 0 || !(hfov_deg > 0.0 && hfov_deg < 180.0) {
            return None;
        }
        let f = f64::from(width) / 2.0 / (hfov_deg.to_radians() / 2.0).tan();
        Some(PinholeIntrinsics {
            width,
            height,
            fx: f,
            fy: f,
            cx: f64::from(width) / 2.0,
            cy: f64::from(height) / 2.0,
        })
    }

    /// Where a point in the camera's optical frame (z forward, x right, y down) falls on the
    /// image: `(u, v, depth)`, `u` and `v` in pixels (the centre of the top-left pixel is (0.5,
    /// 0.5)), `depth` along the optical axis (m); `None` behind or too close to the camera
    /// (1 mm).
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 3]> {
        (p.z > 1e-3).then(|| {
            [
                self.fx * p.x / p.z + self.cx,
                self.fy * p.y / p.z + self.cy,
                p.z,
            ]
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ninety_degree_field_of_view_puts_the_focal_length_at_half_the_width() {
        let k = PinholeIntrinsics::from_horizontal_fov(640, 480, 90.0).unwrap();
        assert!((k.fx - 320.0).abs() < 1e-9 && (k.fy - 320.0).abs() < 1e-9);
        assert_eq!((k.cx, k.cy), (320.0, 240.0));
        // a point at the edge of the field of view projects onto the image's edge
        let x = k.fx * (45f64.to_radians()).tan() + k.cx;
        assert!((x - 640.0).abs() < 1e-9);
    }

    #[test]
    fn field_of_view_out_of_range_gives_none() {
        assert!(PinholeIntrinsics::from_horizontal_fov(640, 480, 0.0).is_none());
        assert!(PinholeIntrinsics::from_horizontal_fov(640, 480, 180.0).is_none());
        assert!(PinholeIntrinsics::from_horizontal_fov(640, 480, f64::NAN).is_none());
        assert!(PinholeIntrinsics::from_horizontal_fov(0, 480, 60.0).is_none());
    }
}
