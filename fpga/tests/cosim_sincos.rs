//! Co-simulation of the sine/cosine unit: the RTL (`rtl/kin_sincos.v`) against the Rust model
//! on every one of the 2^24 binary angles, bit for bit (hashed per block of 65,536 angles; a
//! differing block is re-run word by word to name the first differing angle). Two simulator
//! processes share the sweep.
//!
//! Needs Verilator or Icarus Verilog. With `PENELOPE_REQUIRE_COSIM=1` (set by `scripts/test`) a missing
//! simulator fails this test; without it, it prints a loud SKIPPED line and passes.

use std::thread;

use penelope_fpga::cosim::{self, Bench, SINCOS_BLOCK};

#[test]
fn sincos_rtl_equals_model_on_every_input() {
    if !cosim::simulator_or_skip("sincos_rtl_equals_model_on_every_input") {
        return;
    }
    let work = cosim::scratch_dir("sincos");
    let bench = cosim::compile(Bench::SinCos, &work, &[]).expect("simulator build");
    let blocks_total = (1u32 << 24) / SINCOS_BLOCK;
    let half = blocks_total / 2;
    // Two simulator processes, one per half of the angle circle; the model runs meanwhile.
    let handles: Vec<_> = (0..2u32)
        .map(|part| {
            let bench = bench.clone();
            thread::spawn(move || {
                cosim::sincos_rtl_hashes(
                    &bench,
                    &format!("part{part}"),
                    part * half * SINCOS_BLOCK,
                    half,
                )
            })
        })
        .collect();
    let model = cosim::sincos_model_hashes(0, blocks_total);
    let mut rtl = Vec::new();
    for h in handles {
        rtl.extend(h.join().expect("thread").expect("simulator"));
    }
    assert_eq!(rtl.len(), model.len());
    for (b, (got, want)) in rtl.iter().zip(&model).enumerate() {
        if got != want {
            let start = b as u32 * SINCOS_BLOCK;
            let first = cosim::sincos_dump(&bench, "diff", start).expect("simulator");
            panic!("sin/cos block at angle {start:#x} differs: first difference {first:?}");
        }
    }
    let _ = std::fs::remove_dir_all(&work);
}
