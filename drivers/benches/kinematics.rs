//! Per-call cost of the PUMA 560 model: forward kinematics, Jacobian, both from one pass,
//! inverse kinematics (all 8 branches), gravity, inertia and Newton-Euler; and the FRHC's
//! forward kinematics and Jacobian (the master's model, called every control tick).
//!
//! `scripts/bench-kinematics` runs this beside the same calls of the Python Robotics Toolbox and
//! prints the ratio table that BENCHMARKS.md quotes.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use penelope_drivers::model;
use penelope_hal::{
    Dynamics, IkSolutions, InverseKinematics, JacobianFrame, JointVector, Kinematics,
};

fn puma560(c: &mut Criterion) {
    let m = model::puma560();
    // A generic, non-singular configuration (the same one the toolbox run uses).
    let q = JointVector::from_column_slice(&[0.3, -0.4, 0.7, -1.1, 0.9, 0.5]);
    let qd = JointVector::from_column_slice(&[0.2, -0.5, 0.3, 1.0, -0.7, 0.4]);
    let qdd = JointVector::from_column_slice(&[1.0, 0.5, -0.8, 0.3, 0.2, -1.5]);
    let target = m.forward(&q);
    let mut g = c.benchmark_group("puma560");
    g.bench_function("fk", |b| b.iter(|| m.forward(black_box(&q))));
    g.bench_function("jacobian", |b| {
        b.iter(|| m.jacobian(black_box(&q), JacobianFrame::Base))
    });
    g.bench_function("fk+jacobian", |b| {
        b.iter(|| {
            let t = m.forward(black_box(&q));
            let j = m.jacobian(black_box(&q), JacobianFrame::Base);
            (t, j)
        })
    });
    g.bench_function("fk+jacobian one pass", |b| {
        b.iter(|| m.forward_and_jacobian(black_box(&q), JacobianFrame::Base))
    });
    let mut sols = IkSolutions::new();
    g.bench_function("ik all 8 branches", |b| {
        b.iter(|| {
            m.inverse_all(black_box(&target), &mut sols)
                .map(|n| n + sols.len())
        })
    });
    g.bench_function("ik near seed", |b| {
        b.iter(|| m.inverse_near(black_box(&target), black_box(&q)))
    });
    g.bench_function("ik numerical (DLS)", |b| {
        let seed = q + JointVector::repeat(0.05);
        b.iter(|| m.inverse_numerical(black_box(&target), black_box(&seed)))
    });
    g.bench_function("gravity", |b| b.iter(|| m.gravity(black_box(&q))));
    g.bench_function("inertia", |b| b.iter(|| m.inertia(black_box(&q))));
    g.bench_function("rne", |b| {
        b.iter(|| m.inverse_dynamics(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
    g.finish();
}

fn frhc(c: &mut Criterion) {
    let m = model::frhc();
    // A generic configuration near the FRHC's home [0, 60, 150, 0, 0, 0] deg.
    let q = JointVector::from_column_slice(&[0.3, 0.9, 2.4, -0.6, 0.5, 0.4]);
    let mut g = c.benchmark_group("frhc");
    g.bench_function("fk", |b| b.iter(|| m.forward(black_box(&q))));
    g.bench_function("jacobian", |b| {
        b.iter(|| m.jacobian(black_box(&q), JacobianFrame::Base))
    });
    g.bench_function("fk+jacobian one pass", |b| {
        b.iter(|| m.forward_and_jacobian(black_box(&q), JacobianFrame::Base))
    });
    g.bench_function("fk+jacobian one pass, tool frame", |b| {
        b.iter(|| m.forward_and_jacobian(black_box(&q), JacobianFrame::Tool))
    });
    g.finish();
}

criterion_group!(benches, puma560, frhc);
criterion_main!(benches);
