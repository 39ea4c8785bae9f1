//! Co-simulation behind the board: the FRHC's joint angles and displayed wrenches of a demo run
//! on `board/fpga`, fed to the Verilog RTL (`fpga/rtl`, in Verilator or Icarus Verilog), give
//! exactly the pose and joint torques the board handed the master's loop (no tolerance), and
//! each result took the cycles the board's latency model charges.
//!
//! Needs Verilator or Icarus Verilog; without one the test prints a loud SKIPPED line and
//! passes, unless `PENELOPE_REQUIRE_COSIM=1` (as `scripts/test` sets it).

use std::time::Duration;

use nalgebra::Vector3;
use penelope_fpga::cosim::{self, Bench, KinVector};
use penelope_fpga::pipeline::{POS, TORQUE};
use penelope_fpga::{DhTable, FpgaKinematics};
use penelope_hal::{Kinematics, RobotModel, Wrench};
use penelope_runtime::objects::clock::ClockMode;
use penelope_runtime::objects::fpga_board::{FK, FK_FORCE};
use penelope_runtime::objects::kinematics::RobotKinematics;
use penelope_supervisor::runs::{
    DEMO_SYSTEM, MasterKinematics, RunOptions, run, with_master_kinematics,
};
use penelope_supervisor::system::SystemFile;

/// Every this many master ticks is co-simulated.
const EVERY: usize = 5;

#[test]
fn the_rtl_behind_the_board_gives_the_boards_words_on_the_demos_inputs() {
    if !cosim::simulator_or_skip(
        "the_rtl_behind_the_board_gives_the_boards_words_on_the_demos_inputs",
    ) {
        return;
    }
    // The demo with the FRHC on its FPGA board, through the push and the taps (wrenches).
    let demo = SystemFile::parse(DEMO_SYSTEM).unwrap();
    let file = with_master_kinematics(&demo, MasterKinematics::Fpga).unwrap();
    let options = RunOptions {
        duration: Some(Duration::from_secs(20)),
        clock: ClockMode::Simulated,
        ..RunOptions::default()
    };
    let out = run(&file, &options, &mut |_| {}).unwrap();
    let board = &out.info.master_model;
    assert!(matches!(board, RobotKinematics::FpgaBoard { .. }));

    // The hardware words of each sampled tick, as the board's host interface quantizes them.
    let model = FpgaKinematics::frhc();
    let ticks: Vec<(penelope_hal::JointVector, Wrench)> = out
        .master
        .iter()
        .step_by(EVERY)
        .map(|t| (t.sample.q, t.sample.commanded_wrench))
        .collect();
    assert!(ticks.len() > 3_000, "{} ticks", ticks.len());
    let pushing = ticks.iter().filter(|(_, w)| w.force.norm() > 1.0).count();
    assert!(pushing > 100, "only {pushing} ticks display a force");
    let vectors: Vec<KinVector> = ticks
        .iter()
        .map(|(q, w)| {
            let run = model.torque_words(q, w).expect("finite telemetry");
            KinVector {
                force: true,
                flange: run.flange_frame,
                q: run.fk.q,
                wrench: run.wrench,
                table: DhTable::frhc(),
            }
        })
        .collect();

    let work = cosim::scratch_dir("board");
    let bench = cosim::compile(Bench::Kin, &work, &[]).expect("simulator build");
    let rtl = cosim::run_kin(&bench, "board", &vectors).expect("simulator run");
    assert_eq!(rtl.len(), vectors.len());
    for (k, ((q, w), words)) in ticks.iter().zip(&rtl).enumerate() {
        // What the board handed the loop: the pose and `J^T F`.
        let pose = board.forward(q).translation.vector;
        let tau = board.wrench_to_torques(q, w).unwrap();
        let rtl_p = Vector3::from(words.p.map(|x| x as f64 * POS.lsb()));
        assert_eq!(pose, rtl_p, "tick {k}: position");
        for j in 0..6 {
            assert_eq!(
                tau[j],
                words.tau[j] as f64 * TORQUE.lsb(),
                "tick {k}: joint {j} torque"
            );
        }
        assert_eq!(words.cycles, FK_FORCE.cycles, "tick {k}: cycles");
    }
    assert_eq!(FK.cycles, penelope_fpga::cycles::FK_CYCLES);
    let _ = std::fs::remove_dir_all(&work);
}
