//! A small software renderer: an RGB image with a depth buffer, and the few primitives the
//! simulated camera draws (capsules for links, spheres, bounded planes), each shaded simply
//! and depth-tested per pixel. Planes and spheres are ray-cast exactly; a capsule is its
//! projected segment widened by its projected radius.

use nalgebra::Vector3;

use super::pinhole::PinholeCamera;

/// An RGB colour.
pub type Rgb = [u8; 3];

/// An 8-bit RGB image, rows top to bottom, with a depth per pixel (m along the optical axis;
/// infinite where nothing was drawn).
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// `width * height * 3` bytes.
    pub rgb: Vec<u8>,
    depth: Vec<f32>,
}

impl Image {
    /// An image of `colour`, nothing drawn.
    pub fn new(width: u32, height: u32, colour: Rgb) -> Image {
        let n = width as usize * height as usize;
        Image {
            width,
            height,
            rgb: colour.repeat(n),
            depth: vec![f32::INFINITY; n],
        }
    }

    /// The pixel at column `x`, row `y`.
    pub fn pixel(&self, x: u32, y: u32) -> Rgb {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Writes `colour` at (`x`, `y`) if `depth` is nearer than what is there.
    fn plot(&mut self, x: u32, y: u32, depth: f64, colour: Rgb) {
        let i = y as usize * self.width as usize + x as usize;
        let d = depth as f32;
        if d < self.depth[i] {
            self.depth[i] = d;
            self.rgb[3 * i..3 * i + 3].copy_from_slice(&colour);
        }
    }
}

/// `colour` scaled by `light` (0..=1).
fn shade(colour: Rgb, light: f64) -> Rgb {
    colour.map(|c| (f64::from(c) * light.clamp(0.0, 1.0)).round() as u8)
}

/// The ray through the centre of pixel (`x`, `y`), in the camera's frame (not normalized:
/// z = 1).
fn ray(camera: &PinholeCamera, x: u32, y: u32) -> Vector3<f64> {
    Vector3::new(
        (f64::from(x) + 0.5 - camera.intrinsics.cx) / camera.intrinsics.fx,
        (f64::from(y) + 0.5 - camera.intrinsics.cy) / camera.intrinsics.fy,
        1.0,
    )
}

/// A bounded plane: the square of side `2 * half_side` around `point`, in the plane of normal
/// `normal`, checkered every `tile` m; world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanePatch {
    /// Its centre, m.
    pub point: Vector3<f64>,
    /// Its unit normal.
    pub normal: Vector3<f64>,
    /// Half its side, m.
    pub half_side: f64,
    /// The checker's tile, m.
    pub tile: f64,
    /// The two colours of the checker.
    pub colours: [Rgb; 2],
}

/// Draws `patch`, ray-cast per pixel; lit by how squarely the camera faces it.
pub fn plane(image: &mut Image, camera: &PinholeCamera, patch: &PlanePatch) {
    let rotation = camera.pose.rotation;
    let point = camera.to_camera(&patch.point);
    let normal = rotation.inverse() * patch.normal;
    // Two axes in the plane for its checker and its bounds.
    let helper = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let a = normal.cross(&helper).normalize();
    let b = normal.cross(&a);
    for y in 0..image.height {
        for x in 0..image.width {
            let r = ray(camera, x, y);
            let denominator = r.dot(&normal);
            if denominator.abs() < 1e-12 {
                continue;
            }
            let t = point.dot(&normal) / denominator;
            if t <= 1e-3 {
                continue;
            }
            let hit = r * t - point;
            let (s, u) = (hit.dot(&a), hit.dot(&b));
            if s.abs() > patch.half_side || u.abs() > patch.half_side {
                continue;
            }
            let tile = ((s / patch.tile).floor() + (u / patch.tile).floor()) as i64;
            let light = 0.55 + 0.45 * (denominator.abs() / r.norm());
            image.plot(
                x,
                y,
                t,
                shade(patch.colours[tile.rem_euclid(2) as usize], light),
            );
        }
    }
}

/// Draws a sphere of `radius` around world point `center`, ray-cast within its projected
/// bounding box, lit from the camera.
pub fn sphere(
    image: &mut Image,
    camera: &PinholeCamera,
    center: &Vector3<f64>,
    radius: f64,
    colour: Rgb,
) {
    let c = camera.to_camera(center);
    let Some([u, v, depth]) = camera.project_camera(&c) else {
        return;
    };
    let reach =
        radius * camera.intrinsics.fx.max(camera.intrinsics.fy) / (depth - radius).max(1e-3) + 2.0;
    for (x, y) in bounding_box(
        (image.width, image.height),
        u - reach,
        u + reach,
        v - reach,
        v + reach,
    ) {
        let r = ray(camera, x, y);
        // |t r - c|² = radius²: the nearer root.
        let (aa, bb, cc) = (r.dot(&r), -2.0 * r.dot(&c), c.dot(&c) - radius * radius);
        let disc = bb * bb - 4.0 * aa * cc;
        if disc < 0.0 {
            continue;
        }
        let t = (-bb - disc.sqrt()) / (2.0 * aa);
        if t <= 1e-3 {
            continue;
        }
        let normal = (r * t - c) / radius;
        let light = 0.35 + 0.65 * (-normal.dot(&r.normalize())).max(0.0);
        image.plot(x, y, t, shade(colour, light));
    }
}

/// Draws a capsule of `radius` from world point `a` to `b`: its projected segment widened by
/// the radius projected at each end (linear between), depth along the segment, shaded across
/// its width as a cylinder. A segment partly behind the camera is cut at 1 cm in front of it.
pub fn capsule(
    image: &mut Image,
    camera: &PinholeCamera,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    radius: f64,
    colour: Rgb,
) {
    let (mut p, mut q) = (camera.to_camera(a), camera.to_camera(b));
    let near = 0.01;
    if p.z < near && q.z < near {
        return;
    }
    if p.z < near {
        p = q + (p - q) * ((q.z - near) / (q.z - p.z));
    } else if q.z < near {
        q = p + (q - p) * ((p.z - near) / (p.z - q.z));
    }
    let (Some(pa), Some(pb)) = (camera.project_camera(&p), camera.project_camera(&q)) else {
        return;
    };
    let f = camera.intrinsics.fx.max(camera.intrinsics.fy);
    let (ra, rb) = (radius * f / pa[2], radius * f / pb[2]);
    let reach = ra.max(rb) + 1.0;
    let (du, dv) = (pb[0] - pa[0], pb[1] - pa[1]);
    let length2 = du * du + dv * dv;
    let xs = (pa[0].min(pb[0]) - reach, pa[0].max(pb[0]) + reach);
    let ys = (pa[1].min(pb[1]) - reach, pa[1].max(pb[1]) + reach);
    for (x, y) in bounding_box((image.width, image.height), xs.0, xs.1, ys.0, ys.1) {
        let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
        let t = if length2 > 1e-12 {
            (((px - pa[0]) * du + (py - pa[1]) * dv) / length2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (cx, cy) = (pa[0] + t * du, pa[1] + t * dv);
        let r = ra + t * (rb - ra);
        let d = ((px - cx).powi(2) + (py - cy).powi(2)).sqrt();
        if d > r {
            continue;
        }
        let across = d / r.max(1e-9);
        let depth = pa[2] + t * (pb[2] - pa[2]) - radius * (1.0 - across * across).sqrt();
        image.plot(
            x,
            y,
            depth,
            shade(colour, 0.35 + 0.65 * (1.0 - across * across).sqrt()),
        );
    }
}

/// The pixels whose centres may lie in `[u0, u1] x [v0, v1]`, clipped to the image.
fn bounding_box(
    size: (u32, u32),
    u0: f64,
    u1: f64,
    v0: f64,
    v1: f64,
) -> impl Iterator<Item = (u32, u32)> {
    let clip = |lo: f64, hi: f64, n: u32| {
        let lo = lo.floor().max(0.0).min(f64::from(n)) as u32;
        let hi = hi.ceil().max(0.0).min(f64::from(n)) as u32;
        lo..hi
    };
    let (xs, ys) = (clip(u0, u1, size.0), clip(v0, v1, size.1));
    ys.flat_map(move |y| xs.clone().map(move |x| (x, y)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> PinholeCamera {
        PinholeCamera::look_at(
            [-1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            160,
            120,
            60.0,
        )
        .unwrap()
    }

    #[test]
    fn a_nearer_shape_hides_a_farther_one_whatever_the_order() {
        let c = camera();
        let (red, blue) = ([255, 0, 0], [0, 0, 255]);
        let near = Vector3::new(0.0, 0.0, 0.0);
        let far = Vector3::new(0.5, 0.0, 0.0);
        let mut one = Image::new(160, 120, [0; 3]);
        sphere(&mut one, &c, &far, 0.2, blue);
        sphere(&mut one, &c, &near, 0.05, red);
        let mut other = Image::new(160, 120, [0; 3]);
        sphere(&mut other, &c, &near, 0.05, red);
        sphere(&mut other, &c, &far, 0.2, blue);
        assert_eq!(one, other);
        let centre = one.pixel(80, 60);
        assert!(centre[0] > 150 && centre[2] == 0, "{centre:?}");
        // The far sphere shows around the near one.
        let beside = one.pixel(80 + 12, 60);
        assert!(beside[2] > 0 && beside[0] == 0, "{beside:?}");
    }

    #[test]
    fn a_capsule_covers_its_projected_segment_and_a_plane_its_square() {
        let c = camera();
        let mut image = Image::new(160, 120, [0; 3]);
        capsule(
            &mut image,
            &c,
            &Vector3::new(0.0, 0.2, 0.0),
            &Vector3::new(0.0, -0.2, 0.0),
            0.02,
            [0, 255, 0],
        );
        // The segment crosses the image's middle row from left to right of centre.
        for x in [60, 80, 100] {
            assert!(image.pixel(x, 60)[1] > 0, "column {x}");
        }
        assert_eq!(image.pixel(80, 20), [0; 3]);
        let mut wall = Image::new(160, 120, [0; 3]);
        plane(
            &mut wall,
            &c,
            &PlanePatch {
                point: Vector3::new(0.5, 0.0, 0.0),
                normal: Vector3::new(-1.0, 0.0, 0.0),
                half_side: 0.2,
                tile: 0.1,
                colours: [[200, 200, 200], [100, 100, 100]],
            },
        );
        assert_ne!(wall.pixel(80, 60), [0; 3], "the wall's centre");
        assert_eq!(wall.pixel(2, 2), [0; 3], "past the wall's edge");
    }
}
