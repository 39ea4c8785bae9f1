//! The simulated camera: a pinhole camera watching the slave's world (its links, its
//! environment's walls and spheres, a red marker on the tool), rendered in software from the
//! plant's truth, with a sensor's timing (a frame rate, an exposure whose middle is the capture
//! instant, a readout delay before the frame exists) and seeded pixel noise: the same seed, the
//! same frame number and the same truth give the same bytes.
//!
//! Nothing here runs in a control loop: rendering allocates and takes milliseconds.

pub mod pinhole;
pub mod raster;

use nalgebra::Vector3;
use penelope_hal::Pose;
use rand::RngExt;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

pub use pinhole::{CameraError, PinholeCamera};
pub use raster::{Image, PlanePatch, Rgb};

use super::environment::Shape;

/// The sky behind everything.
pub const BACKGROUND: Rgb = [176, 196, 214];
/// The links.
pub const LINK_COLOUR: Rgb = [230, 140, 40];
/// The tool's marker (pure red: nothing else in the scene is).
pub const TOOL_COLOUR: Rgb = [255, 0, 0];
/// A link's radius as drawn, m.
pub const LINK_RADIUS: f64 = 0.025;
/// The tool marker's radius, m: wider than a link, so the link that ends at its centre hides
/// none of it from the side.
pub const TOOL_RADIUS: f64 = 0.035;
/// Half the side of a drawn wall (a plane is drawn as this square around its point), m.
pub const WALL_HALF_SIDE: f64 = 0.6;

/// When a camera's frames are taken and ready.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraTiming {
    /// Frames per second.
    pub rate_hz: f64,
    /// Exposure, µs: a frame's capture instant is its middle.
    pub exposure_us: u32,
    /// Readout after the exposure, µs: the frame exists this long after the exposure ends.
    pub readout_us: u32,
}

impl CameraTiming {
    /// The start of frame `k`'s exposure, ns after `start_ns`.
    fn exposure_start_ns(&self, start_ns: u64, k: u64) -> u64 {
        start_ns + (k as f64 * 1e9 / self.rate_hz).round() as u64
    }

    /// Frame `k`'s capture instant: the middle of its exposure.
    pub fn capture_ns(&self, start_ns: u64, k: u64) -> u64 {
        self.exposure_start_ns(start_ns, k) + u64::from(self.exposure_us) * 500
    }

    /// When frame `k` is read out and may be used.
    pub fn ready_ns(&self, start_ns: u64, k: u64) -> u64 {
        self.exposure_start_ns(start_ns, k)
            + (u64::from(self.exposure_us) + u64::from(self.readout_us)) * 1000
    }
}

/// What the camera sees at one instant, in the world frame it is placed in.
#[derive(Clone, Debug)]
pub struct WorldView<'a> {
    /// The robot's link frames, root first, the tool last (a model's `link_frames`, placed).
    pub link_frames: &'a [Pose],
    /// The environment's shapes.
    pub contacts: &'a [Shape],
}

/// A simulated camera: see the [module](self).
#[derive(Clone, Debug, PartialEq)]
pub struct SimCamera {
    /// Its optics and placement.
    pub camera: PinholeCamera,
    /// Uniform pixel noise, ± levels per channel (0: none).
    pub noise: u8,
    /// The noise's seed.
    pub seed: u64,
}

impl SimCamera {
    /// Renders frame `frame` of `view`: the sky, the walls (checkered squares) and spheres, the
    /// links as capsules between consecutive frame origins, the tool's marker, then the noise.
    pub fn render(&self, view: &WorldView<'_>, frame: u64) -> Image {
        let c = &self.camera;
        let mut image = Image::new(c.intrinsics.width, c.intrinsics.height, BACKGROUND);
        for shape in view.contacts {
            match *shape {
                Shape::Plane { point, normal } => raster::plane(
                    &mut image,
                    c,
                    &PlanePatch {
                        point,
                        normal: normal.into_inner(),
                        half_side: WALL_HALF_SIDE,
                        tile: 0.1,
                        colours: [[210, 210, 200], [150, 150, 140]],
                    },
                ),
                Shape::Sphere { center, radius } => {
                    raster::sphere(&mut image, c, &center, radius, [120, 160, 120]);
                }
            }
        }
        let origins: Vec<Vector3<f64>> = view
            .link_frames
            .iter()
            .map(|f| f.translation.vector)
            .collect();
        for pair in origins.windows(2) {
            raster::capsule(&mut image, c, &pair[0], &pair[1], LINK_RADIUS, LINK_COLOUR);
        }
        if let Some(tool) = origins.last() {
            raster::sphere(&mut image, c, tool, TOOL_RADIUS, TOOL_COLOUR);
        }
        if self.noise > 0 {
            let mut rng =
                ChaCha8Rng::seed_from_u64(self.seed ^ frame.wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let n = i16::from(self.noise);
            for v in &mut image.rgb {
                let noisy = i16::from(*v) + rng.random_range(-n..=n);
                *v = noisy.clamp(0, 255) as u8;
            }
        }
        image
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::puma560;
    use nalgebra::Unit;
    use penelope_hal::JointVector;

    fn world(q: &[f64]) -> (Vec<Pose>, Vec<Shape>) {
        let model = puma560();
        let q = JointVector::from_column_slice(q);
        let wall = Shape::Plane {
            point: Vector3::new(0.0, 0.0, -0.2),
            normal: Unit::new_normalize(Vector3::z()),
        };
        (model.link_frames(&q), vec![wall])
    }

    fn camera(noise: u8, seed: u64) -> SimCamera {
        SimCamera {
            camera: PinholeCamera::look_at(
                [2.4, -1.9, 1.4],
                [0.2, 0.0, 0.2],
                [0.0, 0.0, 1.0],
                640,
                480,
                60.0,
            )
            .unwrap(),
            noise,
            seed,
        }
    }

    /// The centroid of the marker's pixels (red, nothing else is).
    fn red_centroid(image: &Image) -> Option<(f64, f64)> {
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
        for y in 0..image.height {
            for x in 0..image.width {
                let [r, g, b] = image.pixel(x, y);
                if r > 90 && g < 40 && b < 40 {
                    sx += f64::from(x) + 0.5;
                    sy += f64::from(y) + 0.5;
                    n += 1.0;
                }
            }
        }
        (n > 0.0).then(|| (sx / n, sy / n))
    }

    #[test]
    fn the_tool_is_drawn_where_the_truth_projects_it() {
        for q in [
            [0.0, -0.6, 0.4, 0.0, 0.3, 0.0],
            [0.5, -0.3, 0.2, 0.2, -0.4, 0.1],
            [-0.4, -0.8, 0.6, 0.0, 0.6, 0.0],
        ] {
            let (frames, contacts) = world(&q);
            let sim = camera(0, 0);
            let image = sim.render(
                &WorldView {
                    link_frames: &frames,
                    contacts: &contacts,
                },
                0,
            );
            let tool = frames.last().unwrap().translation.vector;
            let [u, v, _] = sim
                .camera
                .project(&tool)
                .expect("the tool in front of the camera");
            let (x, y) = red_centroid(&image).expect("the marker is visible");
            let off = ((x - u).powi(2) + (y - v).powi(2)).sqrt();
            println!("q {q:?}: the marker's centroid {off:.2} px from the projected truth");
            assert!(
                off < 2.0,
                "q {q:?}: marker at ({x:.1}, {y:.1}), truth at ({u:.1}, {v:.1})"
            );
        }
    }

    #[test]
    fn frames_are_deterministic_per_seed_and_frame() {
        let (frames, contacts) = world(&[0.0, -0.6, 0.4, 0.0, 0.3, 0.0]);
        let view = WorldView {
            link_frames: &frames,
            contacts: &contacts,
        };
        let a = camera(6, 42).render(&view, 7);
        assert_eq!(a, camera(6, 42).render(&view, 7));
        assert_ne!(a, camera(6, 43).render(&view, 7));
        assert_ne!(a, camera(6, 42).render(&view, 8));
        // The scene is drawn: the links, the wall and the sky all show.
        let clean = camera(0, 0).render(&view, 0);
        let colours: std::collections::BTreeSet<Rgb> = (0..480)
            .step_by(8)
            .flat_map(|y| (0..640).step_by(8).map(move |x| (x, y)))
            .map(|(x, y)| clean.pixel(x, y))
            .collect();
        assert!(colours.contains(&BACKGROUND));
        assert!(colours.len() > 20, "{} colours", colours.len());
    }

    #[test]
    fn timing_puts_the_capture_mid_exposure_and_the_frame_after_readout() {
        let t = CameraTiming {
            rate_hz: 30.0,
            exposure_us: 8000,
            readout_us: 12000,
        };
        assert_eq!(t.capture_ns(1_000, 0), 1_000 + 4_000_000);
        assert_eq!(t.ready_ns(1_000, 0), 1_000 + 20_000_000);
        assert_eq!(t.capture_ns(0, 3), 100_000_000 + 4_000_000);
    }
}
