//! Accuracy of the bit-exact model against the f64 model (the second oracle, kept apart from
//! the RTL co-simulation): each test states its bound and prints max and RMS errors.
//!
//! Both models get the **same quantized inputs** (binary joint angles, wrench words), so these
//! bounds measure the fixed-point arithmetic alone; input quantization is reported separately.
//!
//! `cargo test -p penelope-fpga --release --test accuracy -- --nocapture` prints the table in
//! BENCHMARKS.md.

use penelope_fpga::dh::{DhTable, JOINTS};
use penelope_fpga::pipeline::{self, POS, ROT, TORQUE, WRENCH};
use penelope_fpga::reference::FloatChain;
use penelope_fpga::sincos::{self, SIN_COS, angle_to_radians};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Max and RMS of a stream of absolute errors.
#[derive(Default)]
struct Stats {
    max: f64,
    sum_sq: f64,
    n: u64,
}

impl Stats {
    fn add(&mut self, e: f64) {
        self.max = self.max.max(e.abs());
        self.sum_sq += e * e;
        self.n += 1;
    }
    fn rms(&self) -> f64 {
        (self.sum_sq / self.n.max(1) as f64).sqrt()
    }
    fn row(&self, quantity: &str, unit: &str, scale: f64) {
        eprintln!(
            "| {quantity} | {} | {:.4} {unit} | {:.4} {unit} |",
            self.n,
            self.max * scale,
            self.rms() * scale
        );
    }
}

#[test]
fn sin_cos_within_one_lsb_on_every_angle() {
    // Every angle in release; every 5th in a debug build (the sweep is 2^24 angles).
    let stride = if cfg!(debug_assertions) { 5 } else { 1 };
    let lsb = SIN_COS.lsb();
    let mut s = Stats::default();
    let mut c = Stats::default();
    for a in (-(1i32 << 23)..(1 << 23)).step_by(stride) {
        let (sw, cw) = sincos::sin_cos(a);
        let (st, ct) = angle_to_radians(a).sin_cos();
        s.add((sw as f64 * lsb - st) / lsb);
        c.add((cw as f64 * lsb - ct) / lsb);
    }
    s.row("sin (LSB = 2^-23)", "LSB", 1.0);
    c.row("cos (LSB = 2^-23)", "LSB", 1.0);
    assert!(
        s.max <= 0.75 && c.max <= 0.75,
        "sin {} cos {} LSB",
        s.max,
        c.max
    );
}

fn random_q(rng: &mut ChaCha8Rng) -> [i32; JOINTS] {
    std::array::from_fn(|_| rng.random_range(-(1 << 23)..(1 << 23)))
}

fn radians(q: &[i32; JOINTS]) -> [f64; JOINTS] {
    q.map(angle_to_radians)
}

#[test]
fn frhc_position_error_is_far_below_a_micrometre() {
    let table = DhTable::frhc();
    let chain = FloatChain::new(&DhTable::frhc_params());
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (mut pos, mut rot, mut input) = (Stats::default(), Stats::default(), Stats::default());
    let n = if cfg!(debug_assertions) {
        20_000
    } else {
        200_000
    };
    for _ in 0..n {
        // Every joint over its whole circle: a superset of the FRHC's 0.30 m workspace.
        let q = random_q(&mut rng);
        let fk = pipeline::forward(&table, &q);
        let (r, p) = chain.forward(&radians(&q), f64::sin_cos);
        let mut e2 = 0.0;
        for i in 0..3 {
            e2 += (fk.p[i] as f64 * POS.lsb() - p[i]).powi(2);
            for (word, exact) in fk.r[i].iter().zip(&r[i]) {
                rot.add((*word as f64 * ROT.lsb() - exact) / ROT.lsb());
            }
        }
        pos.add(e2.sqrt());
        // Input quantization alone: f64 at the exact angles vs f64 at the binary angles.
        let exact: [f64; JOINTS] = std::array::from_fn(|j| {
            angle_to_radians(q[j]) + rng.random_range(-0.5..0.5) * angle_to_radians(1)
        });
        let (_, pe) = chain.forward(&exact, f64::sin_cos);
        input.add(((0..3).map(|i| (pe[i] - p[i]).powi(2)).sum::<f64>()).sqrt());
    }
    pos.row("FK position (norm)", "um", 1e6);
    rot.row("FK rotation entries (LSB = 2^-23)", "LSB", 1.0);
    input.row("input quantization alone (f64, norm)", "um", 1e6);
    // Regression bounds far inside the 10 um requirement (and the 1 um goal). Rotation
    // entries collect one truncation (-0.5 LSB mean) per product sum per joint.
    assert!(pos.max < 0.3e-6, "position error {} m", pos.max);
    assert!(rot.max < 8.0, "rotation error {} LSB", rot.max);
    assert!(input.max < 0.5e-6, "input quantization {} m", input.max);
}

fn wrench_words(rng: &mut ChaCha8Rng, force: f64, moment: f64) -> [i32; 6] {
    let lsb = WRENCH.lsb();
    std::array::from_fn(|k| {
        let limit = if k < 3 { force } else { moment };
        (rng.random_range(-limit..limit) / lsb).round() as i32
    })
}

fn torque_error(force: f64, moment: f64, seed: u64) -> Stats {
    let table = DhTable::frhc();
    let chain = FloatChain::new(&DhTable::frhc_params());
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut err = Stats::default();
    let n = if cfg!(debug_assertions) {
        20_000
    } else {
        200_000
    };
    for _ in 0..n {
        let q = random_q(&mut rng);
        let w = wrench_words(&mut rng, force, moment);
        let flange = rng.random_bool(0.5);
        let fk = pipeline::forward(&table, &q);
        let out = pipeline::joint_torques(&fk, &w, flange);
        let fl = chain.forward_frames(&radians(&q), f64::sin_cos);
        let wf = w.map(|x| x as f64 * WRENCH.lsb());
        let wb = if flange { fl.rotate_to_base(&wf) } else { wf };
        let tau = fl.joint_torques(&wb, JOINTS);
        for (word, exact) in out.tau.iter().zip(&tau) {
            err.add(*word as f64 * TORQUE.lsb() - exact);
        }
    }
    err
}

#[test]
fn force_path_error_is_bounded() {
    // The FRHC's display range (10 N, 0.5 N m) and a range near the wrench format's limit.
    let device = torque_error(10.0, 0.5, 2);
    device.row("tau, |f| <= 10 N, |m| <= 0.5 N m", "uN m", 1e6);
    let large = torque_error(40.0, 20.0, 3);
    large.row("tau, |f| <= 40 N, |m| <= 20 N m", "uN m", 1e6);
    // Bounds from the node formats (SPEC.md): the moment truncation (1 LSB = 2^-17 N m per
    // component, times |z| summed over three), the torque rounding (half an LSB), the base
    // wrench truncation times the lever (<= 0.5 m), lever and axis quantization times the
    // wrench: about 30 uN m at the device range; the bounds leave a margin.
    assert!(device.max < 40e-6, "{} N m", device.max);
    assert!(large.max < 60e-6, "{} N m", large.max);
}
