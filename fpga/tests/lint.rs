//! Lint: the synthesizable RTL (`penelope_kin.v`, `kin_sincos.v`) is clean under
//! `verilator --lint-only -Wall`; any warning fails. The only waivers in the sources are
//! `_unused` sinks for bits dropped on purpose by truncation, each with its comment.
//!
//! Needs Verilator. With `PENELOPE_REQUIRE_COSIM=1` (set by `scripts/test`) a missing
//! Verilator fails this test; without it, it prints a loud SKIPPED line and passes.

use std::process::Command;

use penelope_fpga::cosim;

fn lint(defines: &[&str]) -> (bool, String) {
    let rtl = cosim::rtl_dir();
    let mut cmd = Command::new("verilator");
    cmd.args(["--lint-only", "-Wall", "--top-module", "penelope_kin"]);
    for d in defines {
        cmd.arg(format!("-D{d}"));
    }
    cmd.arg(rtl.join("penelope_kin.v"))
        .arg(rtl.join("kin_sincos.v"));
    let out = cmd.output().expect("verilator runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let clean = out.status.success() && !text.contains("%Warning") && !text.contains("%Error");
    (clean, text)
}

#[test]
fn rtl_is_clean_under_verilator_wall() {
    let test = "rtl_is_clean_under_verilator_wall";
    if !cosim::tool_or_skip(
        test,
        "verilator",
        cosim::tool_available("verilator", "--version"),
        "verilator",
    ) {
        return;
    }
    let (clean, text) = lint(&[]);
    assert!(clean, "verilator --lint-only -Wall:\n{text}");
}

#[test]
fn the_lint_check_can_fail() {
    // A planted width bug must be reported, so a clean verdict above means something.
    if !cosim::tool_or_skip(
        "the_lint_check_can_fail",
        "verilator",
        cosim::tool_available("verilator", "--version"),
        "verilator",
    ) {
        return;
    }
    let (clean, text) = lint(&["MUTANT_LINT_WIDTH"]);
    assert!(!clean, "the planted lint error was not reported:\n{text}");
    assert!(text.contains("WIDTH"), "{text}");
}
