//! Synthesis for the board: Yosys maps the RTL onto the Virtex-II (`synth_xilinx -family
//! xc2v`), and the design must fit the XC2V1000 and its deepest register-to-register path must
//! fit one 40 MHz period under the datasheet delay figures of
//! `penelope_fpga::synthesis::DelayModel::VIRTEX2` (see `fpga/SPEC.md`, "Synthesis").
//!
//! Needs Yosys. With `PENELOPE_REQUIRE_COSIM=1` (set by `scripts/test`) a missing Yosys fails
//! this test; without it, it prints a loud SKIPPED line and passes.

use penelope_fpga::cosim;
use penelope_fpga::synthesis::{self, DelayModel, Netlist, XC2V1000};

#[test]
fn rtl_fits_the_xc2v1000_and_40_mhz() {
    let test = "rtl_fits_the_xc2v1000_and_40_mhz";
    if !cosim::tool_or_skip(test, "yosys", cosim::tool_available("yosys", "-V"), "yosys") {
        return;
    }
    let work = cosim::scratch_dir("synth");
    let (blif, stat) = synthesis::synthesize(&work).expect("yosys");
    let netlist = Netlist::parse_blif(&blif).expect("the mapped netlist parses");
    let used = netlist.resources();

    // The netlist read back is the one Yosys reports on.
    for (cell, ours) in [
        ("MULT18X18", used.mults),
        ("MUXCY", used.carry),
        ("MUXF5", used.muxf5),
    ] {
        assert_eq!(synthesis::stat_count(&stat, cell), ours, "{cell} count");
    }
    let stat_luts: u32 = ["INV", "LUT1", "LUT2", "LUT3", "LUT4"]
        .iter()
        .map(|c| synthesis::stat_count(&stat, c))
        .sum();
    assert_eq!(stat_luts, used.luts, "LUT count");

    eprintln!("resources: {used:?}\n  of the XC2V1000: {XC2V1000:?}");
    let excess = used.excess(&XC2V1000);
    assert!(
        excess.is_empty(),
        "the design does not fit the XC2V1000: {excess:?}"
    );
    // The intent of the RTL, not only its fit: the sine table is block RAM (an asynchronous
    // read would have become ~20,000 LUTs), and every product is on MULT18X18 blocks: four per
    // 25x25 multiplier (three of them) and one per 17x10 interpolation product (two).
    assert!(used.brams > 0, "the sine table did not map to block RAM");
    assert!(
        used.mults >= 3 * 4 + 2,
        "only {} MULT18X18: some products went to LUTs",
        used.mults
    );

    let model = DelayModel::VIRTEX2;
    let path = netlist.critical_path(&model).expect("timing");
    eprintln!(
        "deepest register-to-register path: {:.2} ns of {:.1} ns \
         ({} LUT levels, {} MULT18X18, {} carry cells, {} MUXF)",
        path.delay, model.period, path.lut_levels, path.mults, path.carry_cells, path.muxf
    );
    for (kind, net) in &path.cells {
        eprintln!("  {kind:<12} {net}");
    }
    assert!(
        path.delay <= model.period,
        "the deepest path, {:.2} ns, exceeds the 40 MHz period: {:?}",
        path.delay,
        path.cells
    );
    let _ = std::fs::remove_dir_all(&work);
}
