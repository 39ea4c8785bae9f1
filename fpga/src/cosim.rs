//! Co-simulation: runs the Verilog RTL in a simulator and compares every word with the Rust
//! model. `std` only.
//!
//! The simulator is Verilator (`verilator --binary --timing`) when it is installed, else Icarus
//! Verilog (`iverilog`, `vvp`); `PENELOPE_SIMULATOR=icarus` or `=verilator` forces one. Both run
//! the same test benches and give the same words; Verilator builds in about 6 s and then runs
//! the benches about 30 to 50 times faster (see `BENCHMARKS.md`).
//!
//! Vectors go through **one** simulator process per batch, as text files of hex words (see
//! `rtl/tb_kin.v` and `rtl/tb_sincos.v` for the formats). The comparison is exact integer
//! equality; there is no tolerance anywhere.
//!
//! The exhaustive sine/cosine sweep (all 2^24 angles) compares a 64-bit hash per block of
//! 65,536 angles (`h = h * 0x9E3779B97F4A7C15 + {sin, cos}`, odd multiplier: a single differing
//! word always changes the hash); on a mismatch, [`sincos_dump`] re-runs that block word by word
//! to name the first differing angle.

use std::fmt;
use std::fs;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::dh::{DhTable, JOINTS};
use crate::pipeline::{self, POS};
use crate::sincos::sin_cos;

/// Angles per hashed block of the sine/cosine sweep.
pub const SINCOS_BLOCK: u32 = 1 << 16;
/// The hash multiplier of the sine/cosine sweep.
pub const SINCOS_HASH_MULTIPLIER: u64 = 0x9E37_79B9_7F4A_7C15;

/// Why a co-simulation could not run.
#[derive(Debug)]
pub enum CosimError {
    /// A file could not be read or written, or a tool could not be started.
    Io(std::io::Error),
    /// The simulator (or its compiler) exited with an error.
    Tool {
        /// The command.
        command: String,
        /// What it printed.
        output: String,
    },
    /// The simulator's output file did not parse.
    Parse(String),
}

impl fmt::Display for CosimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CosimError::Io(e) => write!(f, "co-simulation I/O: {e}"),
            CosimError::Tool { command, output } => write!(f, "`{command}` failed:\n{output}"),
            CosimError::Parse(m) => write!(f, "simulator output: {m}"),
        }
    }
}

impl std::error::Error for CosimError {}

impl From<std::io::Error> for CosimError {
    fn from(e: std::io::Error) -> Self {
        CosimError::Io(e)
    }
}

/// The directory holding the RTL sources (`fpga/rtl`).
pub fn rtl_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("rtl")
}

/// A Verilog simulator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Simulator {
    /// Icarus Verilog: `iverilog` compiles, `vvp` runs.
    Icarus,
    /// Verilator: `verilator --binary --timing` builds an executable.
    Verilator,
}

impl Simulator {
    /// True when this simulator's tools can be started.
    pub fn available(self) -> bool {
        match self {
            Simulator::Icarus => tool_available("iverilog", "-V") && tool_available("vvp", "-V"),
            Simulator::Verilator => tool_available("verilator", "--version"),
        }
    }

    /// The simulator the co-simulation uses: `PENELOPE_SIMULATOR` (`icarus` or `verilator`)
    /// when set, else Verilator when installed, else Icarus. `None` when the chosen one (or
    /// both) is missing.
    pub fn chosen() -> Option<Simulator> {
        match std::env::var("PENELOPE_SIMULATOR").as_deref() {
            Ok("icarus") => Some(Simulator::Icarus).filter(|s| s.available()),
            Ok("verilator") => Some(Simulator::Verilator).filter(|s| s.available()),
            _ => [Simulator::Verilator, Simulator::Icarus]
                .into_iter()
                .find(|s| s.available()),
        }
    }
}

/// True when a simulator can be started (see [`Simulator::chosen`]).
pub fn simulator_available() -> bool {
    Simulator::chosen().is_some()
}

/// For tests: true when the simulator is installed. When it is not, prints a loud `SKIPPED`
/// line and returns false, unless the environment variable `PENELOPE_REQUIRE_COSIM` is `1`
/// (as `scripts/test` sets it).
///
/// # Panics
/// When the simulator is missing and `PENELOPE_REQUIRE_COSIM=1`: the test must fail, not skip.
pub fn simulator_or_skip(test: &str) -> bool {
    tool_or_skip(
        test,
        "a Verilog simulator (verilator, or iverilog/vvp)",
        simulator_available(),
        "verilator iverilog",
    )
}

/// True when `tool` can be started and prints something for `arg` (for example `yosys -V`;
/// `iverilog -V` exits with an error status, so the status is not used).
pub fn tool_available(tool: &str, arg: &str) -> bool {
    Command::new(tool)
        .arg(arg)
        .output()
        .map(|o| !o.stdout.is_empty() || !o.stderr.is_empty())
        .unwrap_or(false)
}

/// For tests: `available` as is; when false, prints a loud `SKIPPED` line naming `tools` and
/// the Debian `package` that provides them, unless `PENELOPE_REQUIRE_COSIM=1`.
///
/// # Panics
/// When a tool is missing and `PENELOPE_REQUIRE_COSIM=1`: the test must fail, not skip.
pub fn tool_or_skip(test: &str, tools: &str, available: bool, package: &str) -> bool {
    if available {
        return true;
    }
    if std::env::var("PENELOPE_REQUIRE_COSIM").is_ok_and(|v| v == "1") {
        panic!(
            "{test}: PENELOPE_REQUIRE_COSIM=1 but {tools} is not installed \
             (apt-get install -y {package})"
        );
    }
    // Straight to the process's stderr: the test harness captures `eprintln!`, and this line
    // must be seen.
    let _ = writeln!(
        std::io::stderr(),
        "\n*** SKIPPED {test}: {tools} not installed; this RTL check did NOT run. \
         Install {package} (scripts/test does) to run it. ***\n"
    );
    false
}

/// A scratch directory for one test's simulator files (under the system temp directory).
pub fn scratch_dir(tag: &str) -> PathBuf {
    std::env::temp_dir().join(format!("penelope-fpga-cosim-{}-{tag}", std::process::id()))
}

/// Which test bench to build.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bench {
    /// `tb_kin`: the whole `penelope_kin` pipeline.
    Kin,
    /// `tb_sincos`: the sine/cosine unit alone.
    SinCos,
}

/// A compiled test bench.
#[derive(Clone, Debug)]
pub struct Compiled {
    /// The simulator it was built for.
    pub simulator: Simulator,
    /// The `vvp` image (Icarus) or the executable (Verilator).
    pub image: PathBuf,
    /// The scratch directory it lives in.
    pub work: PathBuf,
}

impl Compiled {
    /// The command that runs the bench; the caller adds the `+PLUSARGS`.
    fn command(&self) -> Command {
        match self.simulator {
            Simulator::Icarus => {
                let mut cmd = Command::new("vvp");
                cmd.arg("-n").arg(&self.image);
                cmd
            }
            Simulator::Verilator => Command::new(&self.image),
        }
    }
}

/// Compiles a test bench into `work` with the [`Simulator::chosen`] simulator, with extra
/// `` `define``s (for example `MUTANT_HALF_UP`).
///
/// # Errors
/// [`CosimError`] when no simulator is installed, or it rejects the sources (a Verilator
/// warning in a bench is an error too).
pub fn compile(bench: Bench, work: &Path, defines: &[&str]) -> Result<Compiled, CosimError> {
    let simulator = Simulator::chosen().ok_or_else(|| {
        CosimError::Io(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            "no Verilog simulator (verilator or iverilog) is installed",
        ))
    })?;
    compile_with(simulator, bench, work, defines)
}

/// [`compile`] with a given simulator.
///
/// # Errors
/// As [`compile`].
pub fn compile_with(
    simulator: Simulator,
    bench: Bench,
    work: &Path,
    defines: &[&str],
) -> Result<Compiled, CosimError> {
    fs::create_dir_all(work)?;
    let rtl = rtl_dir();
    let (name, files): (&str, &[&str]) = match bench {
        Bench::Kin => ("tb_kin", &["penelope_kin.v", "kin_sincos.v", "tb_kin.v"]),
        Bench::SinCos => ("tb_sincos", &["kin_sincos.v", "tb_sincos.v"]),
    };
    let table = format!(
        "-DSINCOS_TABLE=\"{}\"",
        rtl.join("sincos_table.hex").display()
    );
    let (mut cmd, image) = match simulator {
        Simulator::Icarus => {
            let image = work.join(format!("{name}.vvp"));
            let mut cmd = Command::new("iverilog");
            cmd.arg("-g2005").arg("-o").arg(&image);
            (cmd, image)
        }
        Simulator::Verilator => {
            let mdir = work.join(format!("obj_{name}"));
            let mut cmd = Command::new("verilator");
            // One build job: the machine is shared with the other tests.
            cmd.args(["--binary", "--timing", "-j", "1", "--top-module", name])
                .arg("--Mdir")
                .arg(&mdir)
                .args(["-o", name]);
            (cmd, mdir.join(name))
        }
    };
    cmd.arg(table);
    for d in defines {
        cmd.arg(format!("-D{d}"));
    }
    for f in files {
        cmd.arg(rtl.join(f));
    }
    run(cmd)?;
    Ok(Compiled {
        simulator,
        image,
        work: work.to_path_buf(),
    })
}

fn run(mut cmd: Command) -> Result<String, CosimError> {
    let out = cmd.output()?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if !out.status.success() || text.contains("ERROR") {
        return Err(CosimError::Tool {
            command: format!("{cmd:?}"),
            output: text,
        });
    }
    Ok(text)
}

/// One input vector of the kinematics pipeline, in hardware words.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KinVector {
    /// Run the force path after the forward kinematics.
    pub force: bool,
    /// The wrench is in the flange frame.
    pub flange: bool,
    /// Binary joint angles, raw `<+-,24,1>`.
    pub q: [i32; JOINTS],
    /// Wrench `[f; m]`, raw `<+-,25,8>`.
    pub wrench: [i32; 6],
    /// The DH table.
    pub table: DhTable,
}

/// Every output word of one vector, from the RTL or the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KinOutput {
    /// Rotation words, row-major.
    pub r: [[i32; 3]; 3],
    /// Position words.
    pub p: [i32; 3],
    /// Base-frame wrench words (force vectors only).
    pub base_wrench: [i32; 6],
    /// Torque words (force vectors only).
    pub tau: [i32; 6],
    /// Clock cycles from start to done.
    pub cycles: u32,
}

/// The Rust model's answer to `v`, in the shape the RTL gives it.
pub fn model(v: &KinVector) -> KinOutput {
    let q = v.q.map(|x| sign_extend(x as i64 as u64, 24) as i32);
    let fk = pipeline::forward(&v.table, &q);
    let (base_wrench, tau, cycles) = if v.force {
        let f = pipeline::joint_torques(&fk, &v.wrench, v.flange);
        (f.base_wrench, f.tau, crate::cycles::FORCE_CYCLES)
    } else {
        ([0; 6], [0; 6], crate::cycles::FK_CYCLES)
    };
    KinOutput {
        r: fk.r,
        p: fk.p,
        base_wrench,
        tau,
        cycles,
    }
}

fn sign_extend(bits: u64, width: u32) -> i64 {
    let sh = 64 - width;
    ((bits << sh) as i64) >> sh
}

fn mask(x: i32, width: u32) -> u64 {
    (x as i64 as u64) & ((1u64 << width) - 1)
}

/// Runs `vectors` through the compiled `tb_kin` in one simulator process; `tag` names the scratch
/// files.
///
/// # Errors
/// [`CosimError`] when the simulator fails or its output does not parse.
pub fn run_kin(
    bench: &Compiled,
    tag: &str,
    vectors: &[KinVector],
) -> Result<Vec<KinOutput>, CosimError> {
    let input = bench.work.join(format!("{tag}.in.hex"));
    let output = bench.work.join(format!("{tag}.out.hex"));
    {
        let mut w = BufWriter::new(fs::File::create(&input)?);
        let mut previous: Option<DhTable> = None;
        for v in vectors {
            let new_table = previous != Some(v.table);
            previous = Some(v.table);
            let flags = v.force as u32 | (v.flange as u32) << 1 | (new_table as u32) << 2;
            write!(w, "{flags:x}")?;
            for x in v.q {
                write!(w, " {:x}", mask(x, 24))?;
            }
            for x in v.wrench {
                write!(w, " {:x}", mask(x, 25))?;
            }
            if new_table {
                let rows = v.table.rows();
                for r in rows {
                    write!(w, " {:x}", mask(r.offset, 24))?;
                }
                for r in rows {
                    write!(w, " {:x}", mask(r.a, 25))?;
                }
                for r in rows {
                    write!(w, " {:x}", mask(r.d, 25))?;
                }
                for r in rows {
                    write!(w, " {:x}", r.alpha.code())?;
                }
            }
            writeln!(w)?;
        }
        w.flush()?;
    }
    let mut cmd = bench.command();
    cmd.arg(format!("+IN={}", input.display()))
        .arg(format!("+OUT={}", output.display()));
    run(cmd)?;
    let reader = BufReader::new(fs::File::open(&output)?);
    let mut out = Vec::with_capacity(vectors.len());
    for (n, line) in reader.lines().enumerate() {
        let line = line?;
        let words: Vec<&str> = line.split_whitespace().collect();
        if words.len() != 25 {
            return Err(CosimError::Parse(format!("line {n}: {line}")));
        }
        let hex = |k: usize, width: u32| -> Result<i32, CosimError> {
            u64::from_str_radix(words[k], 16)
                .map(|b| sign_extend(b, width) as i32)
                .map_err(|_| CosimError::Parse(format!("line {n}: word {k}: {}", words[k])))
        };
        let mut o = KinOutput {
            r: [[0; 3]; 3],
            p: [0; 3],
            base_wrench: [0; 6],
            tau: [0; 6],
            cycles: words[24]
                .parse()
                .map_err(|_| CosimError::Parse(format!("line {n}: cycles")))?,
        };
        for i in 0..9 {
            o.r[i / 3][i % 3] = hex(i, 25)?;
        }
        for i in 0..3 {
            o.p[i] = hex(9 + i, POS.word_length())?;
        }
        for i in 0..6 {
            o.base_wrench[i] = hex(12 + i, 25)?;
            o.tau[i] = hex(18 + i, 25)?;
        }
        out.push(o);
    }
    if out.len() != vectors.len() {
        return Err(CosimError::Parse(format!(
            "{} results for {} vectors",
            out.len(),
            vectors.len()
        )));
    }
    Ok(out)
}

/// Compares RTL results with the model, word by word. Force words are compared only for force
/// vectors (the RTL leaves them unchanged otherwise).
///
/// # Errors
/// A description of the first differing vector.
pub fn compare(vectors: &[KinVector], rtl: &[KinOutput]) -> Result<(), String> {
    for (n, (v, got)) in vectors.iter().zip(rtl).enumerate() {
        let mut want = model(v);
        let mut got = *got;
        if !v.force {
            got.base_wrench = [0; 6];
            got.tau = [0; 6];
            want.base_wrench = [0; 6];
            want.tau = [0; 6];
        }
        if got != want {
            return Err(format!(
                "vector {n} differs:\n  input {v:?}\n  RTL   {got:?}\n  model {want:?}"
            ));
        }
    }
    if vectors.len() != rtl.len() {
        return Err(format!(
            "{} results for {} vectors",
            rtl.len(),
            vectors.len()
        ));
    }
    Ok(())
}

/// The sine/cosine word pair as the test bench hashes it: `{sin, cos}`, 50 bits.
fn sincos_word(angle: u32) -> u64 {
    let (s, c) = sin_cos(angle as i32);
    mask(s, 25) << 25 | mask(c, 25)
}

/// The model's hashes of `blocks` blocks of [`SINCOS_BLOCK`] angles from `start`.
pub fn sincos_model_hashes(start: u32, blocks: u32) -> Vec<u64> {
    (0..blocks)
        .map(|b| {
            let first = start.wrapping_add(b * SINCOS_BLOCK);
            (0..SINCOS_BLOCK).fold(0u64, |h, k| {
                h.wrapping_mul(SINCOS_HASH_MULTIPLIER)
                    .wrapping_add(sincos_word(first.wrapping_add(k) & 0xff_ffff))
            })
        })
        .collect()
}

/// The RTL's hashes of `blocks` blocks of [`SINCOS_BLOCK`] angles from `start`.
///
/// # Errors
/// [`CosimError`] when the simulator fails or its output does not parse.
pub fn sincos_rtl_hashes(
    bench: &Compiled,
    tag: &str,
    start: u32,
    blocks: u32,
) -> Result<Vec<u64>, CosimError> {
    let output = bench.work.join(format!("{tag}.hash"));
    let mut cmd = bench.command();
    cmd.arg(format!("+START={:x}", start & 0xff_ffff))
        .arg(format!("+BLOCKS={blocks}"))
        .arg(format!("+OUT={}", output.display()));
    run(cmd)?;
    let text = fs::read_to_string(&output)?;
    let hashes: Result<Vec<u64>, _> = text
        .split_whitespace()
        .map(|w| u64::from_str_radix(w, 16))
        .collect();
    let hashes = hashes.map_err(|e| CosimError::Parse(e.to_string()))?;
    if hashes.len() != blocks as usize {
        return Err(CosimError::Parse(format!(
            "{} hashes for {blocks} blocks",
            hashes.len()
        )));
    }
    Ok(hashes)
}

/// Runs one block word by word and returns the first angle whose RTL output differs from the
/// model, as `(angle, rtl (sin, cos), model (sin, cos))`.
///
/// # Errors
/// [`CosimError`] when the simulator fails or its output does not parse.
#[allow(clippy::type_complexity)]
pub fn sincos_dump(
    bench: &Compiled,
    tag: &str,
    start: u32,
) -> Result<Option<(u32, (i32, i32), (i32, i32))>, CosimError> {
    let output = bench.work.join(format!("{tag}.dump"));
    let mut cmd = bench.command();
    cmd.arg(format!("+START={:x}", start & 0xff_ffff))
        .arg("+BLOCKS=1")
        .arg("+DUMP")
        .arg(format!("+OUT={}", output.display()));
    run(cmd)?;
    let text = fs::read_to_string(&output)?;
    for line in text.lines() {
        let w: Vec<u64> = line
            .split_whitespace()
            .map(|x| u64::from_str_radix(x, 16))
            .collect::<Result<_, _>>()
            .map_err(|e| CosimError::Parse(e.to_string()))?;
        if w.len() != 3 {
            return Err(CosimError::Parse(line.to_string()));
        }
        let angle = w[0] as u32;
        let got = (sign_extend(w[1], 25) as i32, sign_extend(w[2], 25) as i32);
        let want = sin_cos(angle as i32);
        if got != want {
            return Ok(Some((angle, got, want)));
        }
    }
    Ok(None)
}
