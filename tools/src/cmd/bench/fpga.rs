//! `penelope bench fpga`: throughput of the bit-exact FPGA kinematics model beside the float
//! (f64) forward kinematics of the same DH table, single-threaded, and the modelled hardware
//! latency at 40 MHz, alone and as `board/fpga` hands results to the host (with its DMA FIFO
//! transfers, `penelope_runtime::objects::fpga_board`).
//!
//! Every implementation runs over the same batch of seeded random FRHC configurations (the
//! float one at the exact values of the binary angles), one call after another on one thread;
//! `std::hint::black_box` keeps the compiler from skipping work. `--json` prints one object.

use std::hint::black_box;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use penelope_fpga::cycles::{self, FK_CYCLES, FORCE_CYCLES};
use penelope_fpga::dh::{DhTable, JOINTS};
use penelope_fpga::pipeline;
use penelope_fpga::reference::FloatChain;
use penelope_fpga::sincos::angle_to_radians;
use penelope_fpga::{FkWords, FpgaKinematics};
use penelope_hal::joint::JointVector;
use penelope_hal::robot::Kinematics;
use penelope_runtime::objects::fpga_board::{self, FK, FK_FORCE};
use serde_json::json;

/// Options of `penelope bench fpga`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Seconds to run each implementation (ignored with --iterations).
    #[arg(long, default_value_t = 2.0)]
    pub duration: f64,
    /// Run each implementation exactly this many calls instead of for --duration.
    #[arg(long)]
    pub iterations: Option<u64>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Configurations in the batch each implementation cycles through.
const BATCH: usize = 4096;

/// One measured implementation.
struct Measure {
    name: &'static str,
    calls: u64,
    elapsed: Duration,
}

impl Measure {
    fn ns_per_call(&self) -> f64 {
        self.elapsed.as_secs_f64() * 1e9 / self.calls.max(1) as f64
    }
    fn per_second(&self) -> f64 {
        self.calls as f64 / self.elapsed.as_secs_f64().max(1e-12)
    }
}

/// Calls `f(i)` for `i` cycling over the batch, for the duration or the iteration count.
fn measure(name: &'static str, args: &Args, mut f: impl FnMut(usize)) -> Measure {
    // Warm-up: one pass over the batch (caches, branch predictors, CPU frequency).
    for i in 0..BATCH {
        f(i);
    }
    let start = Instant::now();
    let mut calls = 0u64;
    match args.iterations {
        Some(n) => {
            for k in 0..n {
                f(k as usize % BATCH);
            }
            calls = n;
        }
        None => {
            let budget = Duration::from_secs_f64(args.duration);
            while start.elapsed() < budget {
                for i in 0..BATCH {
                    f(i);
                }
                calls += BATCH as u64;
            }
        }
    }
    Measure {
        name,
        calls,
        elapsed: start.elapsed(),
    }
}

/// A small deterministic generator (SplitMix64) for the batch of configurations.
fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Runs the benchmark.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 3600.0) {
        return Err(crate::cmd::usage("--duration must be in (0, 3600] seconds"));
    }
    if args.iterations == Some(0) {
        return Err(crate::cmd::usage("--iterations must be at least 1"));
    }
    let measures = measure_models(&args);
    if args.json {
        print_json(&measures);
    } else {
        print_text(&measures);
    }
    Ok(ExitCode::SUCCESS)
}

/// The five model measurements: FK and FK + force, float against bit-exact.
struct Measures {
    /// Float FK.
    float_fk: Measure,
    /// Bit-exact FK on words.
    fixed_fk: Measure,
    /// Bit-exact FK through the kinematics trait.
    trait_fk: Measure,
    /// Float FK and J^T F.
    float_force: Measure,
    /// Bit-exact FK and J^T F on words.
    fixed_force: Measure,
}

/// Measures each model on the same seeded configurations and wrenches.
fn measure_models(args: &Args) -> Measures {
    let table = DhTable::frhc();
    let kin = FpgaKinematics::new(table);
    let chain = FloatChain::new(&DhTable::frhc_params());

    let mut seed = 0x5eed_f96a_u64;
    let q_raw: Vec<[i32; JOINTS]> = (0..BATCH)
        .map(|_| std::array::from_fn(|_| ((splitmix(&mut seed) >> 40) as i32) - (1 << 23)))
        .collect();
    let q_rad: Vec<[f64; JOINTS]> = q_raw.iter().map(|q| q.map(angle_to_radians)).collect();
    let q_vec: Vec<JointVector> = q_rad.iter().map(|q| JointVector::from(*q)).collect();
    let wrench: Vec<[i32; 6]> = (0..BATCH)
        .map(|_| std::array::from_fn(|_| ((splitmix(&mut seed) >> 42) as i32) - (1 << 21)))
        .collect();
    let wrench_f: Vec<[f64; 6]> = wrench
        .iter()
        .map(|w| w.map(|x| x as f64 * pipeline::WRENCH.lsb()))
        .collect();

    let float_fk = measure("float FK (f64, R and p)", args, |i| {
        black_box(chain.forward(black_box(&q_rad[i]), f64::sin_cos));
    });
    let fixed_fk = measure("bit-exact FK (words in, words out)", args, |i| {
        black_box(pipeline::forward(&table, black_box(&q_raw[i])));
    });
    let trait_fk = measure("FpgaKinematics::forward (rad in, Pose out)", args, |i| {
        black_box(kin.forward(black_box(&q_vec[i])));
    });
    let float_force = measure("float FK + J^T F (f64)", args, |i| {
        let fl = chain.forward_frames(black_box(&q_rad[i]), f64::sin_cos);
        black_box(fl.joint_torques(black_box(&wrench_f[i]), JOINTS));
    });
    let fixed_force = measure("bit-exact FK + J^T F (words)", args, |i| {
        let fk: FkWords = pipeline::forward(&table, black_box(&q_raw[i]));
        black_box(pipeline::joint_torques(&fk, black_box(&wrench[i]), false));
    });

    Measures {
        float_fk,
        fixed_fk,
        trait_fk,
        float_force,
        fixed_force,
    }
}

/// The figures as one JSON object.
fn print_json(ms: &Measures) {
    let Measures {
        float_fk,
        fixed_fk,
        trait_fk,
        float_force,
        fixed_force,
    } = ms;
    let hw_fk_s = cycles::seconds(FK_CYCLES);
    let hw_force_s = cycles::seconds(FORCE_CYCLES);
    let fk_ratio = fixed_fk.ns_per_call() / float_fk.ns_per_call();
    let force_ratio = fixed_force.ns_per_call() / float_force.ns_per_call();

    let m = |m: &Measure| {
        json!({
            "name": m.name,
            "calls": m.calls,
            "ns_per_call": m.ns_per_call(),
            "per_second": m.per_second(),
        })
    };
    let out = json!({
        "model": [m(float_fk), m(fixed_fk), m(trait_fk), m(float_force), m(fixed_force)],
        "fk_time_ratio_bit_exact_over_float": fk_ratio,
        "force_time_ratio_bit_exact_over_float": force_ratio,
        "hardware": {
            "clock_hz": cycles::CLOCK_HZ,
            "fk_cycles": FK_CYCLES,
            "fk_latency_s": hw_fk_s,
            "fk_per_second": cycles::per_second(FK_CYCLES),
            "force_cycles": FORCE_CYCLES,
            "force_latency_s": hw_force_s,
            "force_per_second": cycles::per_second(FORCE_CYCLES),
            "fk_to_host_s": FK.latency_ns() as f64 * 1e-9,
            "force_to_host_s": FK_FORCE.latency_ns() as f64 * 1e-9,
            "command_delay_s": fpga_board::command_delay_ns() as f64 * 1e-9,
        },
    });
    println!("{out}");
}

/// The figures as Markdown tables.
fn print_text(ms: &Measures) {
    let Measures {
        float_fk,
        fixed_fk,
        trait_fk,
        float_force,
        fixed_force,
    } = ms;
    let hw_fk_s = cycles::seconds(FK_CYCLES);
    let hw_force_s = cycles::seconds(FORCE_CYCLES);
    let fk_ratio = fixed_fk.ns_per_call() / float_fk.ns_per_call();
    let force_ratio = fixed_force.ns_per_call() / float_force.ns_per_call();

    println!("FPGA kinematics model, FRHC DH table, one thread ({BATCH} seeded configurations)\n");
    println!("| implementation | calls | ns per call | calls per second | time vs float |");
    println!("|---|---|---|---|---|");
    for (m, base) in [
        (&float_fk, &float_fk),
        (&fixed_fk, &float_fk),
        (&trait_fk, &float_fk),
        (&float_force, &float_force),
        (&fixed_force, &float_force),
    ] {
        println!(
            "| {} | {} | {:.1} | {:.0} | {:.2}x |",
            m.name,
            m.calls,
            m.ns_per_call(),
            m.per_second(),
            m.ns_per_call() / base.ns_per_call()
        );
    }
    println!(
        "\nModelled hardware (NI PCI-7831R at {:.0} MHz, one FSM, pipelined multipliers):\n",
        cycles::CLOCK_HZ / 1e6
    );
    println!(
        "| operation | cycles | latency on the board | results per second | to the host with DMA (board/fpga) |"
    );
    println!("|---|---|---|---|---|");
    println!(
        "| forward kinematics | {FK_CYCLES} | {:.3} us | {:.0} | {:.3} us |",
        hw_fk_s * 1e6,
        cycles::per_second(FK_CYCLES),
        FK.latency_ns() as f64 / 1e3
    );
    println!(
        "| FK + force (tau = J^T F) | {FORCE_CYCLES} | {:.3} us | {:.0} | {:.3} us |",
        hw_force_s * 1e6,
        cycles::per_second(FORCE_CYCLES),
        FK_FORCE.latency_ns() as f64 / 1e3
    );
    println!(
        "\nDMA model (assumed): {} us per FIFO transfer + {:.1} ns per 32-bit word; FK reads back {} \
         words, FK + force writes {} and reads {}; a tick's command reaches the motors {:.3} us \
         after the encoder latch.",
        fpga_board::DMA_TRANSFER_NS as f64 / 1e3,
        fpga_board::DMA_WORD_PS as f64 / 1e3,
        FK.words_to_host,
        FK_FORCE.words_to_board,
        FK_FORCE.words_to_host,
        fpga_board::command_delay_ns() as f64 / 1e3
    );
    println!(
        "\nbit-exact FK takes {fk_ratio:.2}x the float FK's time per call (goal: within 3x); \
         force path {force_ratio:.2}x."
    );
}
