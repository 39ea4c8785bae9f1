//! The cost of security per frame: sealing and opening one frame (ChaCha20-Poly1305 through
//! `snow`'s stateless transport) of a session after a real handshake, for a 64-byte body (a
//! typical call) and a 1 KiB one; and the handshake itself. `cargo bench -p
//! penelope-protocol --bench seal`; BENCHMARKS.md has the figures.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use penelope_protocol::net::auth::{ClientHandshake, Opener, Sealer, answer, member_psk, prologue};

fn session() -> (Sealer, Opener) {
    let psk = member_psk(b"penelope-bench-seal-shared-secret");
    let pro = prologue(b"client hello", b"server hello");
    let (client, first) = ClientHandshake::start(&psk, &pro).unwrap();
    let (reply, node_keys) = answer(&psk, &pro, &first).unwrap();
    let client_keys = client.finish(&reply).unwrap();
    let (sealer, _) = client_keys.split();
    let (_, opener) = node_keys.split();
    (sealer, opener)
}

fn seal_open(c: &mut Criterion) {
    for size in [64usize, 1024] {
        let (mut sealer, mut opener) = session();
        let body: Vec<u8> = (0..size).map(|i| (i % 251) as u8).collect();
        let mut out = Vec::with_capacity(size + 64);
        c.bench_function(&format!("seal+open {size} B frame"), |b| {
            b.iter(|| {
                out.clear();
                sealer.seal_body(black_box(&body), &mut out).unwrap();
                // The sealed frame's body follows its 4-byte length.
                let plain = opener.open(&out[4..]).unwrap();
                black_box(plain.len())
            })
        });
        let (mut sealer, _) = session();
        c.bench_function(&format!("seal {size} B frame"), |b| {
            b.iter(|| {
                out.clear();
                sealer.seal_body(black_box(&body), &mut out).unwrap();
                black_box(out.len())
            })
        });
    }
    c.bench_function("handshake (both sides)", |b| {
        b.iter(|| black_box(session()))
    });
}

/// Thread CPU time per seal+open of a `size`-byte frame over `n` frames: what the work costs
/// on a shared machine, where wall time also counts the time other processes ran.
fn cpu_time_per_frame(size: usize, n: u32) -> f64 {
    use nix::time::{ClockId, clock_gettime};
    let (mut sealer, mut opener) = session();
    let body: Vec<u8> = (0..size).map(|i| (i % 251) as u8).collect();
    let mut out = Vec::with_capacity(size + 64);
    let now = || {
        let t = clock_gettime(ClockId::CLOCK_THREAD_CPUTIME_ID).unwrap();
        t.tv_sec() as f64 * 1e9 + t.tv_nsec() as f64
    };
    let t0 = now();
    for _ in 0..n {
        out.clear();
        sealer.seal_body(black_box(&body), &mut out).unwrap();
        black_box(opener.open(&out[4..]).unwrap().len());
    }
    (now() - t0) / f64::from(n)
}

fn cpu_time(_c: &mut Criterion) {
    for size in [64usize, 1024] {
        let ns = cpu_time_per_frame(size, 200_000);
        println!(
            "seal+open {size} B frame: {ns:.0} ns of thread CPU time per frame (200000 frames)"
        );
    }
}

criterion_group!(benches, seal_open, cpu_time);
criterion_main!(benches);
