//! Synthesis checks: does the RTL fit the NI PCI-7831R's Virtex-II XC2V1000, and is its
//! deepest register-to-register path within one 40 MHz period? `std` only.
//!
//! [`synthesize`] runs Yosys (`synth_xilinx -family xc2v -flatten -noiopad`: the kinematics
//! core sits inside a LabVIEW FPGA design, so its ports are internal nets, not pins) and writes
//! the mapped netlist as BLIF. [`Netlist::parse_blif`] reads it; [`Netlist::resources`] counts
//! the primitives and [`Netlist::critical_path`] is a static timing estimate over it with the
//! datasheet figures of [`DelayModel::VIRTEX2`].
//!
//! The timing estimate is done before placement and routing: every routed connection costs the
//! same flat net delay, dedicated carry-chain and wide-multiplexer links cost nothing extra.
//! It is an estimate to keep the design honest (a long adder chain or two multipliers in series
//! shows up), not a replacement for the vendor's timing analysis of a placed design.

use std::collections::HashMap;
use std::fmt;
use std::path::Path;
use std::process::Command;

use crate::cosim::{CosimError, rtl_dir};

/// The XC2V1000's capacity (DS031): 5,120 slices of two 4-input LUTs and two flip-flops.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capacity {
    /// Four-input LUTs.
    pub luts: u32,
    /// Flip-flops.
    pub ffs: u32,
    /// 18 x 18 signed multipliers.
    pub mults: u32,
    /// 18 Kb block RAMs.
    pub brams: u32,
    /// MUXF5 (one per slice).
    pub muxf5: u32,
    /// MUXF6, MUXF7, MUXF8 (one MUXFX per slice).
    pub muxfx: u32,
    /// Carry-chain cells MUXCY (two per slice; as many XORCY).
    pub carry: u32,
}

/// The Virtex-II XC2V1000.
pub const XC2V1000: Capacity = Capacity {
    luts: 10_240,
    ffs: 10_240,
    mults: 40,
    brams: 40,
    muxf5: 5_120,
    muxfx: 5_120,
    carry: 10_240,
};

/// Primitive counts of a mapped netlist (the same fields as [`Capacity`]).
pub type Resources = Capacity;

impl Capacity {
    /// The resources in `self` that exceed `cap`, by name, as `(name, used, available)`.
    pub fn excess(&self, cap: &Capacity) -> Vec<(&'static str, u32, u32)> {
        [
            ("LUT", self.luts, cap.luts),
            ("flip-flop", self.ffs, cap.ffs),
            ("MULT18X18", self.mults, cap.mults),
            ("block RAM", self.brams, cap.brams),
            ("MUXF5", self.muxf5, cap.muxf5),
            ("MUXF6-8", self.muxfx, cap.muxfx),
            ("MUXCY", self.carry, cap.carry),
        ]
        .into_iter()
        .filter(|(_, used, avail)| used > avail)
        .collect()
    }
}

/// Delay figures, nanoseconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DelayModel {
    /// The clock period.
    pub period: f64,
    /// Flip-flop clock to output (T_CKO).
    pub ff_clk_to_out: f64,
    /// Flip-flop setup, D, CE or set/reset input (T_DICK, T_CECK, T_SRCK; the largest).
    pub ff_setup: f64,
    /// Block RAM clock to data output (T_BCKO).
    pub bram_clk_to_out: f64,
    /// Block RAM address / enable setup (T_BACK).
    pub bram_setup: f64,
    /// LUT input to output (T_ILO); inverters count as LUTs.
    pub lut: f64,
    /// MUXF5..MUXF8 input to output.
    pub muxf: f64,
    /// MULT18X18 (combinational) A, B to P (T_MULT).
    pub mult: f64,
    /// Entering a carry chain: MUXCY DI or S to O (about T_OPCYF).
    pub carry_in: f64,
    /// Along a carry chain: MUXCY CI to O, per bit (about T_BYP, dedicated routing).
    pub carry_bit: f64,
    /// XORCY input to output (about T_CINY).
    pub xor: f64,
    /// One routed connection between cells (flat, before placement).
    pub net: f64,
}

impl DelayModel {
    /// Virtex-II, slowest speed grade (-4), rounded up from DS031 (v3.5) switching
    /// characteristics; the net delay is a typical routed connection.
    pub const VIRTEX2: DelayModel = DelayModel {
        period: 25.0,
        ff_clk_to_out: 0.6,
        ff_setup: 0.5,
        bram_clk_to_out: 3.0,
        bram_setup: 0.5,
        lut: 0.44,
        muxf: 0.5,
        mult: 5.0,
        carry_in: 0.8,
        carry_bit: 0.1,
        xor: 0.5,
        net: 0.6,
    };
}

/// One cell of a mapped netlist.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Cell {
    /// The primitive (`LUT4`, `FDRE`, `MULT18X18`, ...; `$buf` for a BLIF `.names` alias).
    pub kind: String,
    /// `(pin, net)` of every connection; bus pins keep their index (`A[3]`).
    pub pins: Vec<(String, String)>,
    /// The instance name when the netlist gives one.
    pub name: Option<String>,
}

/// Why a netlist could not be read or analysed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum NetlistError {
    /// A line the reader does not understand.
    Syntax(String),
    /// A primitive the delay model does not know (add it rather than guess).
    UnknownCell(String),
    /// A combinational loop through this net.
    Loop(String),
}

impl fmt::Display for NetlistError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NetlistError::Syntax(l) => write!(f, "BLIF syntax: {l}"),
            NetlistError::UnknownCell(c) => write!(f, "no delay figure for primitive {c}"),
            NetlistError::Loop(n) => write!(f, "combinational loop through {n}"),
        }
    }
}

impl std::error::Error for NetlistError {}

/// A flattened, technology-mapped netlist.
#[derive(Clone, Debug, Default)]
pub struct Netlist {
    /// Primary inputs.
    pub inputs: Vec<String>,
    /// Primary outputs.
    pub outputs: Vec<String>,
    /// The cells.
    pub cells: Vec<Cell>,
}

/// The deepest register-to-register path.
#[derive(Clone, Debug, PartialEq)]
pub struct CriticalPath {
    /// Its delay, clock-to-out and setup included, ns.
    pub delay: f64,
    /// The cells along it, start to end, as `(kind, output net)`.
    pub cells: Vec<(String, String)>,
    /// LUT levels (LUTs and inverters) on it.
    pub lut_levels: u32,
    /// MULT18X18 blocks in series on it.
    pub mults: u32,
    /// Carry-chain cells (MUXCY, XORCY) on it.
    pub carry_cells: u32,
    /// MUXF5..MUXF8 on it.
    pub muxf: u32,
}

enum Role {
    /// Starts paths at its outputs (after `clk_to_out`), ends them at its inputs (`setup`).
    Sequential { clk_to_out: f64, setup: f64 },
    /// Combinational: its arcs are given by `Netlist::arc`.
    Logic,
    /// A constant driver or clock buffer: starts nothing.
    Constant,
}

fn base(pin: &str) -> &str {
    pin.split('[').next().unwrap_or(pin)
}

fn is_output(kind: &str, pin: &str) -> bool {
    let p = base(pin);
    match kind {
        "$buf" => p == "Y",
        k if k.starts_with("FD") => p == "Q",
        k if k.starts_with("RAMB16") => p.starts_with("DO"),
        "MULT18X18" => p == "P",
        _ => p == "O",
    }
}

impl Netlist {
    /// Reads the top model of a BLIF file as Yosys's `write_blif` writes it (one model after
    /// `-flatten`; `.names` with one input is an alias, with none a constant).
    ///
    /// # Errors
    /// [`NetlistError::Syntax`] on anything else.
    pub fn parse_blif(text: &str) -> Result<Netlist, NetlistError> {
        let mut n = Netlist::default();
        // Join continuation lines.
        let mut lines: Vec<String> = Vec::new();
        let mut pending = String::new();
        for raw in text.lines() {
            let l = raw.split('#').next().unwrap_or("").trim_end();
            if let Some(head) = l.strip_suffix('\\') {
                pending.push_str(head);
                pending.push(' ');
                continue;
            }
            pending.push_str(l);
            lines.push(std::mem::take(&mut pending));
        }
        let mut in_model = false;
        let mut names_cover = false;
        for line in &lines {
            let mut w = line.split_whitespace();
            let Some(first) = w.next() else { continue };
            if !first.starts_with('.') {
                if names_cover {
                    continue; // the cover of a .names (an alias or constant)
                }
                return Err(NetlistError::Syntax(line.clone()));
            }
            names_cover = false;
            match first {
                ".model" if in_model => break, // only the top model
                ".model" => in_model = true,
                ".inputs" => n.inputs.extend(w.map(str::to_string)),
                ".outputs" => n.outputs.extend(w.map(str::to_string)),
                ".names" => {
                    names_cover = true;
                    let nets: Vec<&str> = w.collect();
                    match nets.as_slice() {
                        [] => return Err(NetlistError::Syntax(line.clone())),
                        [out] => n.cells.push(Cell {
                            kind: "$const".into(),
                            pins: vec![("Y".into(), (*out).into())],
                            name: None,
                        }),
                        [a, out] => n.cells.push(Cell {
                            kind: "$buf".into(),
                            pins: vec![("A".into(), (*a).into()), ("Y".into(), (*out).into())],
                            name: None,
                        }),
                        _ => return Err(NetlistError::UnknownCell(format!(".names {line}"))),
                    }
                }
                ".subckt" | ".gate" => {
                    let kind = w
                        .next()
                        .ok_or_else(|| NetlistError::Syntax(line.clone()))?
                        .to_string();
                    let mut pins = Vec::new();
                    for pc in w {
                        let (p, net) = pc
                            .split_once('=')
                            .ok_or_else(|| NetlistError::Syntax(line.clone()))?;
                        pins.push((p.to_string(), net.to_string()));
                    }
                    n.cells.push(Cell {
                        kind,
                        pins,
                        name: None,
                    });
                }
                ".cname" => {
                    if let Some(c) = n.cells.last_mut() {
                        c.name = w.next().map(str::to_string);
                    }
                }
                ".param" | ".attr" | ".end" => {}
                _ => return Err(NetlistError::Syntax(line.clone())),
            }
        }
        Ok(n)
    }

    /// Counts the primitives against [`Capacity`]'s fields: LUT1..LUT4 and INV are LUTs,
    /// FD* flip-flops, RAMB16* block RAMs.
    pub fn resources(&self) -> Resources {
        let mut r = Resources {
            luts: 0,
            ffs: 0,
            mults: 0,
            brams: 0,
            muxf5: 0,
            muxfx: 0,
            carry: 0,
        };
        for c in &self.cells {
            let k = c.kind.as_str();
            match k {
                "INV" | "LUT1" | "LUT2" | "LUT3" | "LUT4" => r.luts += 1,
                "MULT18X18" => r.mults += 1,
                "MUXF5" => r.muxf5 += 1,
                "MUXF6" | "MUXF7" | "MUXF8" => r.muxfx += 1,
                "MUXCY" => r.carry += 1,
                _ if k.starts_with("FD") => r.ffs += 1,
                _ if k.starts_with("RAMB16") => r.brams += 1,
                _ => {}
            }
        }
        r
    }

    fn role(kind: &str, m: &DelayModel) -> Result<Role, NetlistError> {
        Ok(match kind {
            k if k.starts_with("FD") => Role::Sequential {
                clk_to_out: m.ff_clk_to_out,
                setup: m.ff_setup,
            },
            k if k.starts_with("RAMB16") => Role::Sequential {
                clk_to_out: m.bram_clk_to_out,
                setup: m.bram_setup,
            },
            "$const" | "BUFG" => Role::Constant,
            "$buf" | "INV" | "LUT1" | "LUT2" | "LUT3" | "LUT4" | "MUXF5" | "MUXF6" | "MUXF7"
            | "MUXF8" | "MUXCY" | "XORCY" | "MULT18X18" => Role::Logic,
            other => return Err(NetlistError::UnknownCell(other.to_string())),
        })
    }

    /// `(intrinsic delay, routed?)` from input `pin` of a combinational `kind` to its output.
    fn arc(kind: &str, pin: &str, m: &DelayModel) -> (f64, bool) {
        match (kind, base(pin)) {
            ("$buf", _) => (0.0, false),
            ("MUXCY", "CI") => (m.carry_bit, false),
            ("MUXCY", _) => (m.carry_in, true),
            ("XORCY", "CI") => (m.xor, false),
            ("XORCY", _) => (m.xor, true),
            ("MULT18X18", _) => (m.mult, true),
            // A wide multiplexer's data inputs come from the LUTs or multiplexers of its own
            // slice or neighbour (dedicated); its select is routed.
            (k, "S") if k.starts_with("MUXF") => (m.muxf, true),
            (k, _) if k.starts_with("MUXF") => (m.muxf, false),
            _ => (m.lut, true),
        }
    }

    /// The deepest register-to-register path under `model`: primary inputs count as register
    /// outputs and primary outputs as register inputs (the core's ports connect to registers
    /// of the surrounding design). Clock pins are not timing arcs.
    ///
    /// # Errors
    /// [`NetlistError::UnknownCell`] for a primitive without figures, [`NetlistError::Loop`]
    /// for a combinational loop.
    pub fn critical_path(&self, m: &DelayModel) -> Result<CriticalPath, NetlistError> {
        let mut timing = Arrivals::new(self, m)?;
        // The endpoint reached latest, its setup included.
        let mut best: (f64, &str) = (f64::NEG_INFINITY, "");
        for (net, setup) in self.endpoints(&timing.roles, m) {
            let t = timing.eval(net)?;
            let total = t + m.net + setup;
            if total > best.0 {
                best = (total, net);
            }
        }
        Ok(timing.walk_back(best))
    }

    /// Where paths end, each with its setup time: sequential inputs (not clocks), then primary
    /// outputs.
    fn endpoints(&self, roles: &[Role], m: &DelayModel) -> Vec<(&str, f64)> {
        let mut endpoints: Vec<(&str, f64)> = Vec::new();
        for (i, c) in self.cells.iter().enumerate() {
            if let Role::Sequential { setup, .. } = roles[i] {
                for (p, net) in &c.pins {
                    if !is_output(&c.kind, p) && !is_clock(&c.kind, p) {
                        endpoints.push((net.as_str(), setup));
                    }
                }
            }
        }
        for o in &self.outputs {
            endpoints.push((o.as_str(), m.ff_setup));
        }
        endpoints
    }
}

/// Whether `pin` of a `kind` cell is a clock input (not a timing arc).
fn is_clock(kind: &str, pin: &str) -> bool {
    let p = base(pin);
    (p == "C" || p == "CLKA" || p == "CLKB")
        && (kind.starts_with("FD") || kind.starts_with("RAMB16"))
}

/// When a signal arriving at `t` on input `pin` of a `kind` cell reaches its outputs (the
/// arc's delay, and the net's when the arc is routed).
fn through(kind: &str, pin: &str, t: f64, m: &DelayModel) -> f64 {
    let (d, routed) = Netlist::arc(kind, pin, m);
    t + d + if routed { m.net } else { 0.0 }
}

/// The arrival times of a netlist's nets under a delay model, evaluated on demand.
struct Arrivals<'a> {
    nl: &'a Netlist,
    m: &'a DelayModel,
    /// The cell driving each net.
    driver: HashMap<&'a str, usize>,
    /// Each cell's timing role.
    roles: Vec<Role>,
    /// The arrival time at each net evaluated so far, and the cell that set it (for the path
    /// report).
    arrival: HashMap<&'a str, (f64, Option<usize>)>,
    /// Nets whose inputs are being evaluated (`true`) or were (`false`): one met again while
    /// its inputs are being evaluated closes a combinational loop.
    visiting: HashMap<&'a str, bool>,
}

impl<'a> Arrivals<'a> {
    /// Each net's driver and each cell's role; the primary inputs arrive as register outputs.
    fn new(nl: &'a Netlist, m: &'a DelayModel) -> Result<Self, NetlistError> {
        let mut driver: HashMap<&str, usize> = HashMap::new();
        let mut roles = Vec::with_capacity(nl.cells.len());
        for (i, c) in nl.cells.iter().enumerate() {
            roles.push(Netlist::role(&c.kind, m)?);
            for (p, net) in &c.pins {
                if is_output(&c.kind, p) {
                    driver.insert(net.as_str(), i);
                }
            }
        }
        let mut arrival: HashMap<&str, (f64, Option<usize>)> = HashMap::new();
        for i in &nl.inputs {
            arrival.insert(i.as_str(), (m.ff_clk_to_out, None));
        }
        Ok(Arrivals {
            nl,
            m,
            driver,
            roles,
            arrival,
            visiting: HashMap::new(),
        })
    }

    /// The arrival time at `net`: iterative depth-first evaluation of its drivers' inputs.
    fn eval(&mut self, net: &'a str) -> Result<f64, NetlistError> {
        let (nl, m) = (self.nl, self.m);
        let mut stack: Vec<&'a str> = vec![net];
        while let Some(&n) = stack.last() {
            if self.arrival.contains_key(n) {
                stack.pop();
                continue;
            }
            let Some(&ci) = self.driver.get(n) else {
                self.arrival.insert(n, (f64::NEG_INFINITY, None)); // undriven: no path
                stack.pop();
                continue;
            };
            let cell = &nl.cells[ci];
            match self.roles[ci] {
                Role::Sequential { clk_to_out, .. } => {
                    self.arrival.insert(n, (clk_to_out, Some(ci)));
                    stack.pop();
                    continue;
                }
                Role::Constant => {
                    self.arrival.insert(n, (f64::NEG_INFINITY, None));
                    stack.pop();
                    continue;
                }
                Role::Logic => {}
            }
            let mut pending = false;
            let mut worst = f64::NEG_INFINITY;
            for (p, inet) in &cell.pins {
                if is_output(&cell.kind, p) {
                    continue;
                }
                match self.arrival.get(inet.as_str()) {
                    Some(&(t, _)) => worst = worst.max(through(&cell.kind, p, t, m)),
                    None => {
                        if self.visiting.get(inet.as_str()) == Some(&true) {
                            return Err(NetlistError::Loop(inet.clone()));
                        }
                        pending = true;
                        stack.push(inet.as_str());
                    }
                }
            }
            if pending {
                self.visiting.insert(n, true);
                continue;
            }
            self.visiting.insert(n, false);
            // Every output of the cell gets the same arrival.
            for (p, onet) in &cell.pins {
                if is_output(&cell.kind, p) {
                    self.arrival.insert(onet.as_str(), (worst, Some(ci)));
                }
            }
            self.arrival.entry(n).or_insert((worst, Some(ci)));
            stack.pop();
        }
        Ok(self.arrival[net].0)
    }

    /// The path that ends at `end` (delay, net), walked back along the latest arrivals
    /// (delays included) to the register or input it starts from.
    fn walk_back(&self, end: (f64, &'a str)) -> CriticalPath {
        let m = self.m;
        let mut path = CriticalPath {
            delay: end.0,
            cells: Vec::new(),
            lut_levels: 0,
            mults: 0,
            carry_cells: 0,
            muxf: 0,
        };
        let mut net = end.1;
        while let Some(&(_, Some(ci))) = self.arrival.get(net) {
            let cell = &self.nl.cells[ci];
            path.cells.push((cell.kind.clone(), net.to_string()));
            match cell.kind.as_str() {
                "INV" | "LUT1" | "LUT2" | "LUT3" | "LUT4" => path.lut_levels += 1,
                "MULT18X18" => path.mults += 1,
                "MUXCY" | "XORCY" => path.carry_cells += 1,
                k if k.starts_with("MUXF") => path.muxf += 1,
                _ => {}
            }
            if !matches!(self.roles[ci], Role::Logic) {
                break;
            }
            // The input with the latest arrival (delays included).
            let mut worst: (f64, Option<&str>) = (f64::NEG_INFINITY, None);
            for (p, inet) in &cell.pins {
                if is_output(&cell.kind, p) {
                    continue;
                }
                if let Some(&(t, _)) = self.arrival.get(inet.as_str()) {
                    let t = through(&cell.kind, p, t, m);
                    if t > worst.0 {
                        worst = (t, Some(inet.as_str()));
                    }
                }
            }
            match worst.1 {
                Some(n) => net = n,
                None => break,
            }
        }
        path.cells.reverse();
        path
    }
}

/// Runs Yosys on the RTL (`penelope_kin.v`, `kin_sincos.v`) in `work`: `synth_xilinx -family
/// xc2v -flatten -noiopad`, then `stat` into `stat.txt` and the netlist into `netlist.blif`.
/// Returns the netlist text and Yosys's `stat` report.
///
/// # Errors
/// [`CosimError`] when Yosys cannot run or fails.
pub fn synthesize(work: &Path) -> Result<(String, String), CosimError> {
    std::fs::create_dir_all(work)?;
    let rtl = rtl_dir();
    let blif = work.join("netlist.blif");
    let stat = work.join("stat.txt");
    let script = format!(
        "read_verilog -DSINCOS_TABLE=\"{table}\" {kin} {sc}; \
         synth_xilinx -family xc2v -top penelope_kin -flatten -noiopad; \
         tee -q -o {stat} stat; write_blif {blif}",
        table = rtl.join("sincos_table.hex").display(),
        kin = rtl.join("penelope_kin.v").display(),
        sc = rtl.join("kin_sincos.v").display(),
        stat = stat.display(),
        blif = blif.display(),
    );
    let out = Command::new("yosys")
        .arg("-q")
        .arg("-p")
        .arg(&script)
        .current_dir(work)
        .output()?;
    if !out.status.success() {
        return Err(CosimError::Tool {
            command: format!("yosys -p '{script}'"),
            output: format!(
                "{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            ),
        });
    }
    Ok((
        std::fs::read_to_string(blif)?,
        std::fs::read_to_string(stat)?,
    ))
}

/// The count of `cell` in a Yosys `stat` report (0 when absent).
pub fn stat_count(stat: &str, cell: &str) -> u32 {
    stat.lines()
        .filter_map(|l| {
            let mut w = l.split_whitespace();
            match (w.next(), w.next(), w.next()) {
                (Some(name), Some(n), None) if name == cell => n.parse::<u32>().ok(),
                _ => None,
            }
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    const M: DelayModel = DelayModel::VIRTEX2;

    // Two registers with three LUTs between them, and a multiplier on a second path.
    const SMALL: &str = "\
.model top
.inputs clk a
.outputs y
.names $false
.subckt FDRE C=clk CE=$true D=a Q=q0 R=$false
.subckt LUT2 I0=q0 I1=a O=n1
.param INIT 0110
.subckt LUT1 I0=n1 O=n2
.subckt LUT3 I0=n2 I1=q0 I2=a \\
   O=n3
.subckt FDRE C=clk CE=$true D=n3 Q=q1 R=$false
.subckt MULT18X18 A[0]=q1 B[0]=q0 P[0]=m0 P[1]=m1
.subckt FDRE C=clk CE=$true D=m1 Q=q2 R=$false
.names q2 y
1 1
.end
";

    #[test]
    fn a_lut_chain_costs_what_the_model_says() {
        let n = Netlist::parse_blif(SMALL).unwrap();
        let r = n.resources();
        assert_eq!((r.luts, r.ffs, r.mults, r.brams), (3, 3, 1, 0));
        let p = n.critical_path(&M).unwrap();
        // q1 -> MULT -> q2: clock-to-out, net, multiplier, net, setup.
        let mult = M.ff_clk_to_out + M.net + M.mult + M.net + M.ff_setup;
        // q0 -> 3 LUTs -> q1.
        let luts = M.ff_clk_to_out + 3.0 * (M.net + M.lut) + M.net + M.ff_setup;
        assert!((p.delay - mult.max(luts)).abs() < 1e-9, "{p:?}");
        assert_eq!(p.mults, 1);
        // Make the LUT chain the longer one: it is found, with its three levels.
        let slow = DelayModel { lut: 3.0, ..M };
        let p = n.critical_path(&slow).unwrap();
        assert_eq!(p.lut_levels, 3, "{p:?}");
        assert_eq!(p.mults, 0);
    }

    #[test]
    fn loops_and_unknown_cells_are_errors() {
        let looped = ".model t\n.inputs a\n.outputs y\n.subckt LUT2 I0=a I1=x O=x\n\
                      .subckt FDRE C=a CE=a D=x Q=y R=a\n.end\n";
        let n = Netlist::parse_blif(looped).unwrap();
        assert!(matches!(n.critical_path(&M), Err(NetlistError::Loop(_))));
        let odd = ".model t\n.subckt DSP48 A=a P=p\n.end\n";
        let n = Netlist::parse_blif(odd).unwrap();
        assert!(matches!(
            n.critical_path(&M),
            Err(NetlistError::UnknownCell(_))
        ));
    }

    #[test]
    fn capacity_excess_names_the_resource() {
        let mut r = XC2V1000;
        assert!(r.excess(&XC2V1000).is_empty());
        r.mults = 41;
        assert_eq!(r.excess(&XC2V1000), vec![("MULT18X18", 41, 40)]);
    }

    #[test]
    fn stat_counts_are_read() {
        let s = "   Number of cells: 10\n     LUT4      7\n     MULT18X18     3\n";
        assert_eq!(stat_count(s, "LUT4"), 7);
        assert_eq!(stat_count(s, "MULT18X18"), 3);
        assert_eq!(stat_count(s, "FDRE"), 0);
    }
}
