//! Co-simulation: the Verilog RTL (`rtl/`) against the Rust model, bit for bit.
//!
//! (The exhaustive sine/cosine sweep is in `cosim_sincos.rs`.)
//! - 100,000 seeded random forward-kinematics and force vectors, FRHC and random DH tables,
//!   plus the directed corners, in two simulator runs; the cycle count of each is checked against
//!   the cycle model;
//! - a mutation check: the RTL built with each planted bug must FAIL the same comparison;
//! - both simulators (Verilator and Icarus) give the model's words on the same vectors.
//!
//! Needs Verilator or Icarus Verilog (`cosim::Simulator::chosen`; the cross-check needs both).
//! With `PENELOPE_REQUIRE_COSIM=1` (set by `scripts/test`) a missing simulator fails these tests;
//! without it they print a loud SKIPPED line and pass.

use std::thread;

use penelope_fpga::cosim::{self, Bench, KinOutput, KinVector, Simulator};
use penelope_fpga::dh::{Alpha, DhRow, DhTable, JOINTS, LENGTH};
use penelope_fpga::pipeline;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const RANDOM_VECTORS: usize = 100_000;
const MUTANT_RANDOM_VECTORS: usize = 500;
const CROSS_RANDOM_VECTORS: usize = 1_000;

// --- vector generation ---------------------------------------------------------------------

const HALF_PI: i32 = 1 << 22;
const PI: i32 = 1 << 23;
const WMAX: i32 = (1 << 24) - 1;
const WMIN: i32 = -(1 << 24);

fn random_table(rng: &mut ChaCha8Rng) -> DhTable {
    let lmax = (1i32 << 24) - 1;
    let mut rows = [DhRow::IDENTITY; JOINTS];
    for r in rows.iter_mut() {
        let mut len = || match rng.random_range(0..8) {
            0 => 0,
            1 => -(1 << 24),
            2 => lmax,
            3..=5 => rng.random_range(-(1 << 23)..(1 << 23)), // +-0.5 m
            _ => rng.random_range(-(1 << 24)..=lmax),
        };
        let (a, d) = (len(), len());
        *r = DhRow {
            a,
            d,
            alpha: [Alpha::Zero, Alpha::Plus90, Alpha::Pi, Alpha::Minus90][rng.random_range(0..4)],
            offset: rng.random_range(-PI..PI),
        };
    }
    DhTable::from_rows(rows, JOINTS).expect("six rows")
}

fn random_wrench(rng: &mut ChaCha8Rng) -> [i32; 6] {
    let mut w = [0i32; 6];
    for x in w.iter_mut() {
        *x = match rng.random_range(0..10) {
            0 => rng.random_range(WMIN..=WMAX), // anywhere in +-128
            1 => [WMIN, WMAX, 0, -1][rng.random_range(0..4)],
            _ => rng.random_range(-(20 << 17)..(20 << 17)), // +-20 N or N m
        };
    }
    w
}

fn random_vector(rng: &mut ChaCha8Rng, table: DhTable) -> KinVector {
    KinVector {
        force: rng.random_bool(0.75),
        flange: rng.random_bool(0.5),
        q: std::array::from_fn(|_| rng.random_range(-PI..PI)),
        wrench: random_wrench(rng),
        table,
    }
}

/// Quadrant edges, most-negative codes, singular poses, saturation and wrap edges, and
/// rounding ties of the lever node.
fn directed_vectors(rng: &mut ChaCha8Rng) -> Vec<KinVector> {
    let mut out = Vec::new();
    let edges = [
        0,
        1,
        -1,
        HALF_PI - 1,
        HALF_PI,
        HALF_PI + 1,
        -HALF_PI - 1,
        -HALF_PI,
        -HALF_PI + 1,
        PI - 1,
        -PI,
        -PI + 1,
        HALF_PI / 2,
        -HALF_PI / 2,
    ];
    let wrenches = [
        [0; 6],
        [WMAX; 6],
        [WMIN; 6],
        [WMAX, WMIN, WMAX, WMIN, WMAX, WMIN],
        [10 << 17, 0, 0, 0, 0, 1 << 16],
        [1, -1, 1, -1, 1, -1],
    ];
    let frhc = DhTable::frhc();
    let stress = stress_table(&edges);
    let tables = [frhc, stress];
    for table in tables {
        for &e in &edges {
            for w in &wrenches {
                for flange in [false, true] {
                    out.push(KinVector {
                        force: true,
                        flange,
                        q: [e; JOINTS],
                        wrench: *w,
                        table,
                    });
                }
            }
            // One joint at the edge, the others random.
            for j in 0..JOINTS {
                let mut q: [i32; JOINTS] = std::array::from_fn(|_| rng.random_range(-PI..PI));
                q[j] = e;
                out.push(KinVector {
                    force: true,
                    flange: rng.random_bool(0.5),
                    q,
                    wrench: random_wrench(rng),
                    table,
                });
            }
        }
    }
    singular_poses(frhc, &mut out);
    // FK-only vectors.
    for &e in &edges {
        out.push(KinVector {
            force: false,
            flange: false,
            q: [e; JOINTS],
            wrench: [0; 6],
            table: frhc,
        });
    }
    rounding_ties(rng, frhc, &mut out);
    out
}

/// A table at the edges of the word formats: lengths at their most negative and largest
/// codes, every kind of twist, the joint offsets at angle edges.
fn stress_table(edges: &[i32]) -> DhTable {
    let mut stress = [DhRow::IDENTITY; JOINTS];
    for (j, r) in stress.iter_mut().enumerate() {
        *r = DhRow {
            a: if j % 2 == 0 {
                -(1 << 24)
            } else {
                (1 << 24) - 1
            },
            d: if j % 3 == 0 {
                (1 << 24) - 1
            } else {
                -(1 << 24)
            },
            alpha: [Alpha::Zero, Alpha::Plus90, Alpha::Pi, Alpha::Minus90][j % 4],
            offset: edges[j],
        };
    }
    DhTable::from_rows(stress, JOINTS).expect("six rows")
}

/// FRHC singular poses: elbow stretched or folded (q3 = -+90 deg), wrist aligned (theta5 = 0,
/// i.e. q5 = -90 deg with the +90 deg offset), shoulder on the base axis.
fn singular_poses(frhc: DhTable, out: &mut Vec<KinVector>) {
    for q2 in [0, HALF_PI / 3 * 2, HALF_PI, -HALF_PI] {
        for q3 in [HALF_PI, -HALF_PI, 0, PI - 1] {
            for q5 in [-HALF_PI, 0, HALF_PI] {
                for flange in [false, true] {
                    out.push(KinVector {
                        force: true,
                        flange,
                        q: [0, q2, q3, HALF_PI / 2, q5, -HALF_PI / 2],
                        wrench: [3 << 17, -(2 << 17), 5 << 17, 1 << 15, -(1 << 14), 3 << 15],
                        table: frhc,
                    });
                }
            }
        }
    }
}

/// 500 exact rounding ties in the lever node (p - o_j with low 7 bits 1000000b), found by
/// search.
fn rounding_ties(rng: &mut ChaCha8Rng, frhc: DhTable, out: &mut Vec<KinVector>) {
    let mut ties = 0;
    while ties < 500 {
        let table = if rng.random_bool(0.5) {
            frhc
        } else {
            random_table(rng)
        };
        let v = random_vector(rng, table);
        let fk = pipeline::forward(&v.table, &v.q);
        let tie = (0..JOINTS).any(|j| (0..3).any(|i| (fk.p[i] - fk.o[j][i]) & 0x7f == 0x40));
        if tie {
            out.push(KinVector { force: true, ..v });
            ties += 1;
        }
    }
}

fn vectors(random: usize, seed: u64) -> Vec<KinVector> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut v = directed_vectors(&mut rng);
    // Random vectors in runs of 16 sharing a table: half the runs the FRHC, half a random one.
    let mut table = DhTable::frhc();
    for n in 0..random {
        if n % 16 == 0 {
            table = if rng.random_bool(0.5) {
                DhTable::frhc()
            } else {
                random_table(&mut rng)
            };
        }
        v.push(random_vector(&mut rng, table));
    }
    v
}

// --- the tests -----------------------------------------------------------------------------

#[test]
fn kinematics_rtl_equals_model_bit_for_bit() {
    if !cosim::simulator_or_skip("kinematics_rtl_equals_model_bit_for_bit") {
        return;
    }
    let work = cosim::scratch_dir("kin");
    let bench = cosim::compile(Bench::Kin, &work, &[]).expect("simulator build");
    let v = vectors(RANDOM_VECTORS, 0x7e1e_0b05);
    assert!(v.len() > RANDOM_VECTORS);
    // Two simulator processes, one per half of the vectors.
    let (first, second) = v.split_at(v.len() / 2);
    let rtl: Vec<KinOutput> = thread::scope(|s| {
        let a = s.spawn(|| cosim::run_kin(&bench, "first", first));
        let b = s.spawn(|| cosim::run_kin(&bench, "second", second));
        let mut out = a.join().expect("thread").expect("simulator");
        out.extend(b.join().expect("thread").expect("simulator"));
        out
    });
    if let Err(e) = cosim::compare(&v, &rtl) {
        panic!("RTL and model differ: {e}");
    }
    // The cycle model is what the RTL does (compare() checked each count too).
    assert!(
        rtl.iter()
            .all(|o| o.cycles == penelope_fpga::cycles::FK_CYCLES
                || o.cycles == penelope_fpga::cycles::FORCE_CYCLES)
    );
    // The corners really were reached: saturated torques and wrapped positions occurred.
    let sat = rtl
        .iter()
        .filter(|o| o.tau.iter().any(|&t| t == WMAX || t == WMIN))
        .count();
    assert!(sat > 100, "only {sat} vectors saturated a torque");
    let _ = std::fs::remove_dir_all(&work);
}

#[test]
fn planted_bugs_fail_the_comparison() {
    if !cosim::simulator_or_skip("planted_bugs_fail_the_comparison") {
        return;
    }
    // Six builds of 500 vectors each: Icarus compiles in well under a second where Verilator
    // takes several, so this check prefers Icarus (`both_simulators_give_the_model_words`
    // shows that both simulators give the same words).
    let sim = if Simulator::Icarus.available() {
        Simulator::Icarus
    } else {
        Simulator::Verilator
    };
    let v = vectors(MUTANT_RANDOM_VECTORS, 0x0bad_c0de);
    // The unmutated RTL passes the same vectors (so a failure below is the mutant's doing).
    let clean = cosim::compile_with(sim, Bench::Kin, &cosim::scratch_dir("clean"), &[])
        .expect("simulator build");
    let rtl = cosim::run_kin(&clean, "clean", &v).expect("simulator");
    assert_eq!(cosim::compare(&v, &rtl), Ok(()));
    let _ = std::fs::remove_dir_all(cosim::scratch_dir("clean"));
    for mutant in [
        "MUTANT_LOGICAL_SHIFT",
        "MUTANT_HALF_UP",
        "MUTANT_DROP_LSB",
        "MUTANT_SINCOS_TRUNC",
    ] {
        let work = cosim::scratch_dir(mutant);
        let bench =
            cosim::compile_with(sim, Bench::Kin, &work, &[mutant]).expect("simulator build");
        let rtl = cosim::run_kin(&bench, "mutant", &v).expect("simulator");
        let verdict = cosim::compare(&v, &rtl);
        assert!(
            verdict.is_err(),
            "{mutant}: the harness did not notice the planted bug"
        );
        eprintln!(
            "{mutant}: caught: {}",
            verdict.unwrap_err().lines().next().unwrap_or("")
        );
        let _ = std::fs::remove_dir_all(&work);
    }
    // The sine/cosine sweep catches its own planted bug too.
    let work = cosim::scratch_dir("sincos-mutant");
    let bench = cosim::compile_with(sim, Bench::SinCos, &work, &["MUTANT_SINCOS_TRUNC"])
        .expect("simulator build");
    let rtl = cosim::sincos_rtl_hashes(&bench, "m", 0, 1).expect("simulator");
    assert_ne!(
        rtl,
        cosim::sincos_model_hashes(0, 1),
        "MUTANT_SINCOS_TRUNC not caught"
    );
    assert!(
        cosim::sincos_dump(&bench, "m", 0)
            .expect("simulator")
            .is_some()
    );
    let _ = std::fs::remove_dir_all(&work);
}

#[test]
fn both_simulators_give_the_model_words() {
    let test = "both_simulators_give_the_model_words";
    let both = Simulator::Icarus.available() && Simulator::Verilator.available();
    if !cosim::tool_or_skip(test, "verilator and iverilog", both, "verilator iverilog") {
        return;
    }
    let v = vectors(CROSS_RANDOM_VECTORS, 0x5eed_c055);
    for sim in [Simulator::Icarus, Simulator::Verilator] {
        let work = cosim::scratch_dir(&format!("cross-{sim:?}"));
        let bench = cosim::compile_with(sim, Bench::Kin, &work, &[]).expect("simulator build");
        let rtl = cosim::run_kin(&bench, "cross", &v).expect("simulator");
        assert_eq!(cosim::compare(&v, &rtl), Ok(()), "{sim:?}");
        let bench = cosim::compile_with(sim, Bench::SinCos, &work, &[]).expect("simulator build");
        let start = 0x40_0000 - 0x8000; // across the quadrant edge at pi/2
        let rtl = cosim::sincos_rtl_hashes(&bench, "cross", start, 1).expect("simulator");
        assert_eq!(rtl, cosim::sincos_model_hashes(start, 1), "{sim:?}");
        let _ = std::fs::remove_dir_all(&work);
    }
}

#[test]
fn length_format_is_what_the_bench_assumes() {
    // The random tables above use the full LENGTH range; keep them in step with the format.
    assert_eq!(LENGTH.word_length(), 25);
    assert_eq!(LENGTH.min_raw(), -(1 << 24));
}
