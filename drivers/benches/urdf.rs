//! Per-call cost of the PUMA 560 built from its URDF (`drivers/robots/puma560.urdf`: axis
//! joints, one Rodrigues rotation per joint) beside the same robot from its DH table (one
//! `Rz Tz Tx Rx` per joint), in one group so the two are measured back to back: forward
//! kinematics, the Jacobian, both in one pass, gravity and Newton-Euler.
//!
//! `cargo bench -p penelope-drivers --bench urdf`; the ratios are what to quote (the machine's
//! load moves both sides together).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use penelope_drivers::model::{self, SerialRobotModel, UrdfChain};
use penelope_hal::{Dynamics, JacobianFrame, JointVector, Kinematics};

fn calls(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    side: &str,
    m: &SerialRobotModel,
) {
    // The generic configuration of the kinematics bench.
    let q = JointVector::from_column_slice(&[0.3, -0.4, 0.7, -1.1, 0.9, 0.5]);
    let qd = JointVector::from_column_slice(&[0.2, -0.5, 0.3, 1.0, -0.7, 0.4]);
    let qdd = JointVector::from_column_slice(&[1.0, 0.5, -0.8, 0.3, 0.2, -1.5]);
    g.bench_function(format!("{side} fk"), |b| {
        b.iter(|| m.forward(black_box(&q)))
    });
    g.bench_function(format!("{side} jacobian"), |b| {
        b.iter(|| m.jacobian(black_box(&q), JacobianFrame::Base))
    });
    g.bench_function(format!("{side} fk+jacobian one pass"), |b| {
        b.iter(|| m.forward_and_jacobian(black_box(&q), JacobianFrame::Base))
    });
    g.bench_function(format!("{side} gravity"), |b| {
        b.iter(|| m.gravity(black_box(&q)))
    });
    g.bench_function(format!("{side} rne"), |b| {
        b.iter(|| m.inverse_dynamics(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
}

fn urdf_vs_dh(c: &mut Criterion) {
    let dh = model::puma560();
    let urdf =
        model::urdf::model_from_str(include_str!("../robots/puma560.urdf"), &UrdfChain::whole())
            .expect("the committed PUMA URDF loads");
    let mut g = c.benchmark_group("puma560 urdf vs dh");
    calls(&mut g, "dh", &dh);
    calls(&mut g, "urdf", &urdf);
    g.finish();
}

criterion_group!(benches, urdf_vs_dh);
criterion_main!(benches);
