//! The cost of security per frame: sealing and opening one frame (ChaCha20-Poly1305 through
//! `snow`'s stateless transport) of a session after a real handshake, for a 64-byte body (a
//! typical call) and a 1 KiB one; and the handshake itself. `cargo bench -p
//! penelope-supervisor --bench seal`; BENCHMARKS.md has the figures.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use penelope_supervisor::net::auth::{
    ClientHandshake, Opener, Sealer, answer, member_psk, prologue,
};

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
    c.bench_function("handshake (both sides)", |b| b.iter(|| black_box(session())));
}

criterion_group!(benches, seal_open);
criterion_main!(benches);
