//! `penelope kin <robot> <op>`: kinematics and dynamics of a robot model from the command line.
//!
//! `<robot>` is `puma560`, `puma200`, `frhc`, the path of a DH file (see
//! `drivers/robots/*.toml` for the format), or the path of a URDF file (`*.urdf`; the chain from
//! its root link to `--tip`, default the single leaf link). Joint values are comma-separated radians (metres for
//! prismatic joints), or the name of a pose in the robot's file (`start`, `qn`, ...).
//! `--json` prints one JSON object; bad input exits with code 2.

use std::fmt::Write as _;
use std::process::ExitCode;

use nalgebra::{Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion};
use penelope_drivers::model::{self, SerialRobotModel};
use penelope_hal::{
    Dynamics, IkSolutions, InverseKinematics, JacobianFrame, JointVector, Kinematics, Pose,
};
use serde_json::json;

use crate::cmd::usage;

mod info;
use info::info;

/// Options of `penelope kin`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The robot: puma560, puma200, frhc, the path of a DH file (TOML), or of a URDF file
    /// (`*.urdf`).
    pub robot: String,
    /// A URDF robot's tip link (the tool frame); default: the single leaf link.
    #[arg(long, global = true)]
    pub tip: Option<String>,
    /// What to compute.
    #[command(subcommand)]
    pub op: Op,
    /// Print one JSON object instead of text.
    #[arg(long, global = true)]
    pub json: bool,
    /// Compute fk and jacobian with the bit-exact model of the FPGA board (FRHC only); fk also
    /// reports the raw fixed-point words and the modelled cycle count at 40 MHz.
    #[arg(long, global = true)]
    pub fpga: bool,
}

/// Joint positions.
#[derive(clap::Args, Debug)]
pub struct JointArg {
    /// Joint positions: comma-separated radians (metres for prismatic joints), or a pose name
    /// from the robot's file (nest, start, work, ...).
    #[arg(long, allow_hyphen_values = true)]
    pub q: String,
}

/// The frame of a Jacobian.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameArg {
    /// Rows are the tool's velocity in the base frame.
    Base,
    /// Rows are the tool's velocity in the tool frame.
    Tool,
}

/// The operations.
#[derive(clap::Subcommand, Debug)]
pub enum Op {
    /// Forward kinematics: the tool pose T (4x4 homogeneous, metres) at --q; with --json also
    /// every link frame (`links`: name and T in the base frame, the root first, the tool last:
    /// the frames a recording's `/tf` carries).
    Fk(JointArg),
    /// The geometric Jacobian at --q, rows [v; w] (m/s and rad/s per joint unit speed).
    Jacobian {
        /// Joint positions.
        #[command(flatten)]
        joints: JointArg,
        /// The frame the rows are expressed in.
        #[arg(long, value_enum, default_value_t = FrameArg::Base)]
        frame: FrameArg,
    },
    /// Inverse kinematics: every branch reaching the tool pose --pose.
    Ik {
        /// The tool pose: 16 comma-separated numbers, the 4x4 homogeneous transform row-major
        /// (the rotation is projected onto the nearest rotation matrix).
        #[arg(long, allow_hyphen_values = true)]
        pose: String,
    },
    /// Joint torques (N·m) that hold the arm still at --q against gravity.
    Gravity(JointArg),
    /// The joint-space inertia matrix (kg·m², reflected motor inertia on the diagonal) at --q.
    Inertia(JointArg),
    /// Inverse dynamics by recursive Newton-Euler: torques for --qdd at --q, --qd (no friction).
    Rne {
        /// Joint positions.
        #[command(flatten)]
        joints: JointArg,
        /// Joint speeds, comma-separated rad/s.
        #[arg(long, allow_hyphen_values = true)]
        qd: String,
        /// Joint accelerations, comma-separated rad/s².
        #[arg(long, allow_hyphen_values = true)]
        qdd: String,
    },
    /// The model: DH table, limits, named poses and what is assumed.
    Info,
}

/// Runs `penelope kin`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let out = output(&args)?;
    println!("{}", out.trim_end());
    Ok(ExitCode::SUCCESS)
}

/// What `penelope kin` prints.
fn output(args: &Args) -> anyhow::Result<String> {
    let m = load(&args.robot, args.tip.as_deref())?;
    let n = m.joint_count();
    if args.fpga {
        return fpga_output(args, &m);
    }
    let out = match &args.op {
        Op::Fk(j) => fk_output(&m, &joints(&m, "--q", &j.q)?, args.json),
        Op::Jacobian { joints: j, frame } => {
            jacobian_output(&m, &joints(&m, "--q", &j.q)?, *frame, args.json)
        }
        Op::Ik { pose } => ik_output(&m, pose, args.json)?,
        Op::Gravity(j) => {
            let q = joints(&m, "--q", &j.q)?;
            let tau = m.gravity(&q);
            if args.json {
                json!({ "tau": &tau.as_slice()[..n] }).to_string()
            } else {
                let mut s = header(&m, "gravity (holding torque)", &q);
                s += &per_joint(&m, &tau, "N·m");
                s
            }
        }
        Op::Inertia(j) => {
            let q = joints(&m, "--q", &j.q)?;
            let mm = m.inertia(&q).view((0, 0), (n, n)).into_owned();
            if args.json {
                json!({ "M": rows(&mm) }).to_string()
            } else {
                let mut s = header(&m, "joint-space inertia", &q);
                s += "M (kg·m², reflected motor inertia Jm G² on the diagonal) =\n";
                s += &matrix_text(&mm, None);
                s
            }
        }
        Op::Rne { joints: j, qd, qdd } => {
            let q = joints(&m, "--q", &j.q)?;
            let qd = joints(&m, "--qd", qd)?;
            let qdd = joints(&m, "--qdd", qdd)?;
            let tau = m.inverse_dynamics(&q, &qd, &qdd);
            if args.json {
                json!({ "tau": &tau.as_slice()[..n] }).to_string()
            } else {
                let mut s = header(&m, "inverse dynamics (Newton-Euler, no friction)", &q);
                s += &per_joint(&m, &tau, "N·m");
                s
            }
        }
        Op::Info => info(&m, args.json),
    };
    Ok(out)
}

/// `kin fk`: the tool pose at `q` (the matrix; as text also the position and roll-pitch-yaw;
/// as JSON also every link frame).
fn fk_output(m: &SerialRobotModel, q: &JointVector, json: bool) -> String {
    let t = m.forward_matrix(q);
    if json {
        let links: Vec<serde_json::Value> = m
            .link_names()
            .into_iter()
            .zip(m.link_frames(q))
            .map(|(frame, pose)| json!({ "frame": frame, "T": rows(&pose.to_homogeneous()) }))
            .collect();
        json!({ "T": rows(&t), "links": links }).to_string()
    } else {
        let p = m.forward(q);
        let (roll, pitch, yaw) = p.rotation.euler_angles();
        let mut s = header(m, "forward kinematics", q);
        s += &format!(
            "T (tool pose in the base frame; m) =\n{}",
            matrix_text(&t, None)
        );
        let v = p.translation.vector;
        s += &format!(
            "position (m):   x {:.6}  y {:.6}  z {:.6}\nroll-pitch-yaw (deg): {:.4} {:.4} {:.4}\n",
            v.x,
            v.y,
            v.z,
            roll.to_degrees(),
            pitch.to_degrees(),
            yaw.to_degrees()
        );
        s
    }
}

/// `kin jacobian`: the geometric Jacobian at `q` in `frame`.
fn jacobian_output(m: &SerialRobotModel, q: &JointVector, frame: FrameArg, json: bool) -> String {
    let n = m.joint_count();
    let frame = match frame {
        FrameArg::Base => JacobianFrame::Base,
        FrameArg::Tool => JacobianFrame::Tool,
    };
    let jac = m.jacobian(q, frame).columns(0, n).into_owned();
    if json {
        json!({ "J": rows(&jac) }).to_string()
    } else {
        let mut s = header(m, "geometric Jacobian", q);
        let _ = writeln!(
            s,
            "J ({} frame; rows vx vy vz [m/s] wx wy wz [rad/s], one column per joint) =",
            if frame == JacobianFrame::Base {
                "base"
            } else {
                "tool"
            }
        );
        s += &matrix_text(&jac, Some(&["vx", "vy", "vz", "wx", "wy", "wz"]));
        s
    }
}

/// `kin ik`: every inverse kinematics branch for `pose`, with whether it is within the limits.
fn ik_output(m: &SerialRobotModel, pose: &str, json: bool) -> anyhow::Result<String> {
    let n = m.joint_count();
    let target = parse_pose(pose)?;
    let mut sols = IkSolutions::new();
    m.inverse_all(&target, &mut sols)
        .map_err(|e| anyhow::anyhow!("inverse kinematics: {e}"))?;
    Ok(if json {
        let list: Vec<_> = sols
            .iter()
            .map(|s| {
                json!({
                    "branch": s.branch,
                    "q": &s.q.as_slice()[..n],
                    "within_limits": s.within_limits,
                })
            })
            .collect();
        json!({ "solutions": list }).to_string()
    } else {
        let mut s = format!(
            "{} inverse kinematics ({}): {} solution(s)\n",
            m.name(),
            if m.has_closed_form() {
                "closed form"
            } else {
                "damped least squares"
            },
            sols.len()
        );
        let _ = writeln!(s, "{:<18} {:<62} limits", "branch", "q (rad)");
        for sol in &sols {
            let q: Vec<String> = sol.q.iter().take(n).map(|x| format!("{x:9.5}")).collect();
            let _ = writeln!(
                s,
                "{:<18} {:<62} {}",
                sol.branch,
                q.join(" "),
                if sol.within_limits { "ok" } else { "OUTSIDE" }
            );
        }
        s
    })
}

/// A built-in robot or a DH file; anything else is a usage error.
/// `--fpga`: fk and jacobian from the bit-exact FPGA model of the FRHC.
fn fpga_output(args: &Args, m: &SerialRobotModel) -> anyhow::Result<String> {
    use penelope_fpga::{FpgaKinematics, cycles, pipeline};
    if m.name() != "frhc" {
        return Err(usage(format!(
            "--fpga models the FRHC's FPGA board; robot `{}` has no FPGA kinematics",
            args.robot
        )));
    }
    let fpga = FpgaKinematics::frhc();
    match &args.op {
        Op::Fk(j) => {
            let q = joints(m, "--q", &j.q)?;
            let run = fpga.fk_words(&q).map_err(|e| usage(format!("--q: {e}")))?;
            let t = FpgaKinematics::pose_of(&run.words).to_homogeneous();
            let seconds = cycles::seconds(run.cycles);
            if args.json {
                return Ok(json!({
                    "T": rows(&t),
                    "fpga": {
                        "q_words": run.q,
                        "q_format": "<+-,24,1> pi-rad",
                        "r_words": run.words.r,
                        "r_format": pipeline::ROT.to_string(),
                        "p_words": run.words.p,
                        "p_format": pipeline::POS.to_string(),
                        "cycles": run.cycles,
                        "clock_hz": cycles::CLOCK_HZ,
                        "latency_s": seconds,
                    }
                })
                .to_string());
            }
            let mut s = header(m, "forward kinematics (bit-exact FPGA model)", &q);
            s += &format!(
                "T (tool pose in the base frame; m) =\n{}",
                matrix_text(&t, None)
            );
            s += &format!(
                "raw words: p {:?} ({}), r {:?} ({})\n{} cycles at {} MHz = {:.3} µs\n",
                run.words.p,
                pipeline::POS,
                run.words.r,
                pipeline::ROT,
                run.cycles,
                cycles::CLOCK_HZ / 1e6,
                seconds * 1e6
            );
            Ok(s)
        }
        Op::Jacobian { joints: j, frame } => {
            let q = joints(m, "--q", &j.q)?;
            let frame = match frame {
                FrameArg::Base => JacobianFrame::Base,
                FrameArg::Tool => JacobianFrame::Tool,
            };
            let jac = penelope_hal::Kinematics::jacobian(&fpga, &q, frame);
            if args.json {
                Ok(json!({ "J": rows(&jac) }).to_string())
            } else {
                Ok(header(m, "geometric Jacobian (bit-exact FPGA model)", &q)
                    + &matrix_text(&jac, None))
            }
        }
        _ => Err(usage("--fpga applies to fk and jacobian only")),
    }
}

fn load(robot: &str, tip: Option<&str>) -> anyhow::Result<SerialRobotModel> {
    let urdf = model::is_urdf_path(robot);
    if tip.is_some() && !urdf {
        return Err(usage(
            "--tip applies to a URDF robot (a path ending in .urdf)",
        ));
    }
    if let Some(m) = model::by_name(robot) {
        return Ok(m);
    }
    let path = std::path::Path::new(robot);
    if !path.is_file() {
        return Err(usage(format!(
            "unknown robot `{robot}`: expected one of {} or the path of a DH or URDF file",
            model::BUILT_IN.join(", ")
        )));
    }
    if urdf {
        return model::from_urdf_file(path, tip)
            .map_err(|e| usage(format!("invalid URDF file {robot}: {e}")));
    }
    model::from_file(path).map_err(|e| usage(format!("invalid DH file {robot}: {e}")))
}

/// Parses joint values: a pose name, or exactly one finite number per joint.
fn joints(m: &SerialRobotModel, flag: &str, text: &str) -> anyhow::Result<JointVector> {
    let n = m.joint_count();
    if let Some(q) = m.pose(text.trim()) {
        return Ok(q);
    }
    let values = numbers(flag, text)?;
    if values.len() != n {
        return Err(usage(format!(
            "{flag}: {} has {n} joints, got {} value(s)",
            m.name(),
            values.len()
        )));
    }
    let mut q = JointVector::zeros();
    q.as_mut_slice()[..n].copy_from_slice(&values);
    Ok(q)
}

/// Comma-separated finite numbers.
fn numbers(flag: &str, text: &str) -> anyhow::Result<Vec<f64>> {
    text.split(',')
        .enumerate()
        .map(|(i, s)| {
            let s = s.trim();
            let x: f64 = s
                .parse()
                .map_err(|_| usage(format!("{flag}: value {} `{s}` is not a number", i + 1)))?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(usage(format!(
                    "{flag}: value {} is not finite ({s})",
                    i + 1
                )))
            }
        })
        .collect()
}

/// A 4x4 homogeneous transform from 16 row-major numbers: the bottom row must be `0 0 0 1` and
/// the rotation orthonormal to 1e-3 (so a matrix typed with 4 decimals is accepted); it is then
/// projected onto the nearest rotation.
fn parse_pose(text: &str) -> anyhow::Result<Pose> {
    let v = numbers("--pose", text)?;
    if v.len() != 16 {
        return Err(usage(format!(
            "--pose: expected 16 numbers (the 4x4 transform, row-major), got {}",
            v.len()
        )));
    }
    let t = Matrix4::from_row_slice(&v);
    let bottom = [t[(3, 0)], t[(3, 1)], t[(3, 2)], t[(3, 3)]];
    if bottom
        .iter()
        .zip([0.0, 0.0, 0.0, 1.0])
        .any(|(a, b)| (a - b).abs() > 1e-9)
    {
        return Err(usage(format!(
            "--pose: the last row must be 0,0,0,1, got {bottom:?}"
        )));
    }
    let r: Matrix3<f64> = t.fixed_view::<3, 3>(0, 0).into_owned();
    let ortho = (r.transpose() * r - Matrix3::identity()).amax();
    if ortho > 1e-3 || r.determinant() <= 0.0 {
        return Err(usage(format!(
            "--pose: the upper-left 3x3 block is not a rotation (|R^T R - I| = {ortho:.2e}, det = {:.6})",
            r.determinant()
        )));
    }
    let rot = Rotation3::from_matrix_eps(&r, 1e-15, 100, Rotation3::identity());
    Ok(Pose::from_parts(
        Translation3::new(t[(0, 3)], t[(1, 3)], t[(2, 3)]),
        UnitQuaternion::from_rotation_matrix(&rot),
    ))
}

fn rows<R: nalgebra::Dim, C: nalgebra::Dim, S: nalgebra::RawStorage<f64, R, C>>(
    m: &nalgebra::Matrix<f64, R, C, S>,
) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|r| (0..m.ncols()).map(|c| m[(r, c)]).collect())
        .collect()
}

fn header(m: &SerialRobotModel, what: &str, q: &JointVector) -> String {
    let n = m.joint_count();
    let q: Vec<String> = q.iter().take(n).map(|x| format!("{x:.6}")).collect();
    format!("{} {what} at q = [{}]\n", m.name(), q.join(", "))
}

fn matrix_text<R: nalgebra::Dim, C: nalgebra::Dim, S: nalgebra::RawStorage<f64, R, C>>(
    m: &nalgebra::Matrix<f64, R, C, S>,
    labels: Option<&[&str]>,
) -> String {
    let mut s = String::new();
    for r in 0..m.nrows() {
        let label = labels
            .and_then(|l| l.get(r))
            .map_or(String::new(), |l| format!("{l:>3} "));
        let row: Vec<String> = (0..m.ncols())
            .map(|c| {
                let x = m[(r, c)];
                // Print exact zeros for values at rounding level.
                format!("{:>11.6}", if x.abs() < 5e-13 { 0.0 } else { x })
            })
            .collect();
        let _ = writeln!(s, "  {label}[{} ]", row.join(""));
    }
    s
}

fn per_joint(m: &SerialRobotModel, tau: &JointVector, unit: &str) -> String {
    let mut s = String::new();
    for (j, name) in m.joint_names().iter().enumerate() {
        let x = tau[j];
        let _ = writeln!(
            s,
            "  {:>2} {:<14} {:>12.6} {unit}",
            j + 1,
            name,
            if x.abs() < 5e-13 { 0.0 } else { x }
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_must_be_rigid_transforms() {
        let ok = "1,0,0,0.5, 0,1,0,0, 0,0,1,0.3, 0,0,0,1";
        let p = parse_pose(ok).unwrap();
        assert!((p.translation.vector.x - 0.5).abs() < 1e-15);
        for bad in [
            "1,0,0,0, 0,1,0,0, 0,0,1,0",            // 12 numbers
            "2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1",   // scaled
            "-1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1",  // a reflection
            "1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,1,1",   // bottom row
            "1,0,0,nan, 0,1,0,0, 0,0,1,0, 0,0,0,1", // NaN
        ] {
            assert!(parse_pose(bad).is_err(), "{bad}");
        }
    }

    fn json(robot: &str, op: Op) -> serde_json::Value {
        let args = Args {
            robot: robot.into(),
            op,
            json: true,
            fpga: false,
            tip: None,
        };
        serde_json::from_str(&output(&args).unwrap()).unwrap()
    }

    fn q(text: &str) -> JointArg {
        JointArg { q: text.into() }
    }

    #[test]
    fn fpga_fk_matches_the_float_path_and_reports_its_words() {
        let float = json("frhc", Op::Fk(q("0.1,1,2.5,0.2,0.3,0.1")));
        let args = Args {
            robot: "frhc".into(),
            op: Op::Fk(q("0.1,1,2.5,0.2,0.3,0.1")),
            json: true,
            fpga: true,
            tip: None,
        };
        let fpga: serde_json::Value = serde_json::from_str(&output(&args).unwrap()).unwrap();
        for i in 0..3 {
            for j in 0..4 {
                let (a, b) = (
                    float["T"][i][j].as_f64().unwrap(),
                    fpga["T"][i][j].as_f64().unwrap(),
                );
                assert!((a - b).abs() < 1e-5, "T[{i}][{j}]: float {a}, fpga {b}");
            }
        }
        assert_eq!(fpga["fpga"]["cycles"], penelope_fpga::cycles::FK_CYCLES);
        assert_eq!(fpga["fpga"]["p_words"].as_array().unwrap().len(), 3);
        let not_frhc = Args {
            robot: "puma560".into(),
            op: Op::Fk(q("qn")),
            json: true,
            fpga: true,
            tip: None,
        };
        let err = output(&not_frhc).unwrap_err();
        assert!(
            err.downcast_ref::<crate::cmd::UsageError>().is_some(),
            "{err}"
        );
    }

    #[test]
    fn json_shapes_follow_the_issue() {
        let t = json("puma560", Op::Fk(q("qn")));
        assert_eq!(t["T"].as_array().unwrap().len(), 4);
        // Every link frame, the tool's last and equal to T.
        let links = t["links"].as_array().unwrap();
        assert_eq!(links.len(), 8);
        assert_eq!(links[0]["frame"], "base_link");
        assert_eq!(links[7]["frame"], "tool");
        for r in 0..4 {
            for c in 0..4 {
                let (a, b) = (
                    links[7]["T"][r][c].as_f64().unwrap(),
                    t["T"][r][c].as_f64().unwrap(),
                );
                assert!((a - b).abs() < 1e-12, "T[{r}][{c}]: {a} vs {b}");
            }
        }
        assert!((t["T"][0][3].as_f64().unwrap() - 0.596_303_148_574_615_6).abs() < 1e-12);
        let j = json(
            "frhc",
            Op::Jacobian {
                joints: q("start"),
                frame: FrameArg::Tool,
            },
        );
        assert_eq!(j["J"].as_array().unwrap().len(), 6);
        assert_eq!(j["J"][0].as_array().unwrap().len(), 6);
        let g = json("puma560", Op::Gravity(q("qn")));
        assert!((g["tau"][1].as_f64().unwrap() - 31.639_880_378_357_12).abs() < 1e-9);
        let m = json("puma200", Op::Inertia(q("work")));
        assert_eq!(m["M"].as_array().unwrap().len(), 6);
        let r = json(
            "puma560",
            Op::Rne {
                joints: q("qn"),
                qd: "0,0,0,0,0,0".into(),
                qdd: "0,0,0,0,0,0".into(),
            },
        );
        // Static Newton-Euler is the holding torque (two algorithms: equal to rounding).
        for k in 0..6 {
            let (a, b) = (r["tau"][k].as_f64().unwrap(), g["tau"][k].as_f64().unwrap());
            assert!((a - b).abs() < 1e-9, "joint {k}: {a} vs {b}");
        }
        // ik of fk gives 8 branches, each with a name, 6 joints and a limits flag.
        let flat: Vec<String> = t["T"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|row| row.as_array().unwrap().iter().map(|x| x.to_string()))
            .collect();
        let ik = json(
            "puma560",
            Op::Ik {
                pose: flat.join(","),
            },
        );
        let sols = ik["solutions"].as_array().unwrap();
        assert_eq!(sols.len(), 8);
        assert!(sols.iter().all(|s| s["branch"].is_string()
            && s["q"].as_array().unwrap().len() == 6
            && s["within_limits"].is_boolean()));
    }

    #[test]
    fn bad_input_is_a_usage_error() {
        let run_err = |robot: &str, op: Op| {
            let args = Args {
                robot: robot.into(),
                op,
                json: false,
                fpga: false,
                tip: None,
            };
            output(&args).unwrap_err()
        };
        for e in [
            run_err("nosuch", Op::Info),
            run_err("puma560", Op::Fk(q("0,0,0"))),
            run_err("puma560", Op::Gravity(q("0,0,0,0,0,NaN"))),
            run_err(
                "puma560",
                Op::Ik {
                    pose: "1,2,3".into(),
                },
            ),
        ] {
            assert!(e.downcast_ref::<crate::cmd::UsageError>().is_some(), "{e}");
        }
        // An unreachable pose is not a usage error (exit code 1).
        let e = run_err(
            "puma560",
            Op::Ik {
                pose: "1,0,0,5, 0,1,0,0, 0,0,1,0, 0,0,0,1".into(),
            },
        );
        assert!(e.downcast_ref::<crate::cmd::UsageError>().is_none());
    }

    #[test]
    fn joint_values_are_checked() {
        let m = model::puma560();
        assert!(joints(&m, "--q", "0,0,0,0,0,0").is_ok());
        assert!(joints(&m, "--q", "qn").is_ok());
        assert!(joints(&m, "--q", "0,0,0").is_err());
        assert!(joints(&m, "--q", "0,0,0,0,0,inf").is_err());
        assert!(joints(&m, "--q", "0,0,0,0,0,x").is_err());
    }

    fn urdf(file: &str) -> String {
        format!("{}/../drivers/robots/{file}", env!("CARGO_MANIFEST_DIR"))
    }

    #[test]
    fn a_urdf_path_is_a_robot_like_the_built_in_names() {
        let puma = urdf("puma560.urdf");
        for op in ["fk", "jacobian", "gravity", "rne"] {
            let make = || match op {
                "fk" => Op::Fk(q("0.1,0.2,0.3,0.4,0.5,0.6")),
                "jacobian" => Op::Jacobian {
                    joints: q("0.1,0.2,0.3,0.4,0.5,0.6"),
                    frame: FrameArg::Tool,
                },
                "gravity" => Op::Gravity(q("0.1,0.2,0.3,0.4,0.5,0.6")),
                // No acceleration: the DH file's rotor inertia (which URDF lacks) stays out.
                _ => Op::Rne {
                    joints: q("0.1,0.2,0.3,0.4,0.5,0.6"),
                    qd: "0.5,-1,0.3,2,-0.7,1".into(),
                    qdd: "0,0,0,0,0,0".into(),
                },
            };
            // The link frames differ (a URDF's own links against a DH table's): the tool's is T.
            let tool_only = |mut v: serde_json::Value| {
                if let Some(o) = v.as_object_mut() {
                    o.remove("links");
                }
                v
            };
            let (from_urdf, from_dh) = (
                tool_only(json(&puma, make())),
                tool_only(json("puma560", make())),
            );
            let flat = |v: &serde_json::Value| -> Vec<f64> {
                let mut out = Vec::new();
                let mut stack = vec![v.clone()];
                while let Some(x) = stack.pop() {
                    match x {
                        serde_json::Value::Array(a) => stack.extend(a),
                        serde_json::Value::Object(o) => stack.extend(o.into_iter().map(|(_, x)| x)),
                        serde_json::Value::Number(n) => out.push(n.as_f64().unwrap()),
                        _ => {}
                    }
                }
                out
            };
            let (a, b) = (flat(&from_urdf), flat(&from_dh));
            assert_eq!(a.len(), b.len(), "{op}");
            assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-9), "{op}");
        }
        let ik = json(
            &puma,
            Op::Ik {
                pose: "0,0,1,0.5, 0,1,0,0.1, -1,0,0,0.4, 0,0,0,1".into(),
            },
        );
        assert!(!ik["solutions"].as_array().unwrap().is_empty(), "{ik}");
        let info = json(&puma, Op::Info);
        assert_eq!(info["kind"], "urdf");
        assert_eq!(info["inverse_kinematics"], "numerical");
        assert_eq!(info["joints"][1]["origin_xyz"][2], 0.67183);
    }

    #[test]
    fn a_urdf_tip_is_chosen_with_tip() {
        let scara = urdf("scara.urdf");
        let mut args = Args {
            robot: scara.clone(),
            op: Op::Fk(q("0,0,0.1")),
            json: true,
            fpga: false,
            tip: None,
        };
        let err = output(&args).unwrap_err();
        assert!(err.downcast_ref::<crate::cmd::UsageError>().is_some());
        assert!(err.to_string().contains("camera, tool"), "{err}");
        args.tip = Some("tool".into());
        let t: serde_json::Value = serde_json::from_str(&output(&args).unwrap()).unwrap();
        // 0.7 m out along x, 0.5 - 0.1 - 0.1 m up.
        assert!((t["T"][0][3].as_f64().unwrap() - 0.7).abs() < 1e-12, "{t}");
        assert!((t["T"][2][3].as_f64().unwrap() - 0.3).abs() < 1e-12, "{t}");
        let dh_with_tip = Args {
            robot: "puma560".into(),
            op: Op::Info,
            json: false,
            fpga: false,
            tip: Some("tool".into()),
        };
        assert!(output(&dh_with_tip).is_err());
    }
}
