//! `penelope netft-sim`: an ATI Net F/T emulator on a UDP port, answering the RDT protocol at up
//! to 7 kHz. Its load is a contact model: the shapes given (`--plane`, `--sphere`) probed at a
//! tool, either an emulated Galil DMC's arm served from the same process (`--galil-link`, so
//! `config/demo-galil-netft.toml` runs end to end) or a probe that presses and releases slowly
//! along the sensor's z axis.
//!
//! Prints the address, then serves until interrupted; read it with `penelope netft --addr ADDR
//! monitor`.

use std::process::ExitCode;

use nalgebra::{Unit, Vector3};
use penelope_drivers::galil::emulator::{DmcConfig, PtyEmulator, PtyOptions};
use penelope_drivers::netft::Calibration;
use penelope_drivers::netft::emulator::{
    EmulatorConfig, MAX_RATE_HZ, NetFtEmulator, ProbedContact, galil_tool_pose,
};
use penelope_drivers::sim::environment::{ContactModel, Environment, Shape};
use penelope_hal::{NamedPose, Pose};

/// Options.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where to answer, ip:port (a real box: port 49152).
    #[arg(long, default_value = "127.0.0.1:49152")]
    pub bind: String,
    /// RDT output rate, Hz, 1..=7000.
    #[arg(long, default_value_t = 1000.0)]
    pub rate: f64,
    /// Counts per newton.
    #[arg(long, default_value_t = 1_000_000.0)]
    pub counts_per_force: f64,
    /// Counts per newton-metre.
    #[arg(long, default_value_t = 1_000_000.0)]
    pub counts_per_torque: f64,
    /// Noise standard deviation, N (torque: a fortieth of it, N·m).
    #[arg(long, default_value_t = 0.02)]
    pub noise: f64,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A plane of the environment: x,y,z (a point, m), nx,ny,nz (normal into free space),
    /// stiffness (N/m), damping (N·s/m); repeat for more.
    #[arg(long, value_name = "X,Y,Z,NX,NY,NZ,K,B")]
    pub plane: Vec<String>,
    /// A sphere of the environment: x,y,z (centre, m), radius (m), stiffness, damping.
    #[arg(long, value_name = "X,Y,Z,R,K,B")]
    pub sphere: Vec<String>,
    /// Also serve a Galil DMC emulator (bare motors, as `penelope galil-sim`) with a symbolic
    /// link at this path; the sensor sits on the tool of `--arm-model`, whose joints are its
    /// axes (encoder zero at the model's `start` pose).
    #[arg(long)]
    pub galil_link: Option<std::path::PathBuf>,
    /// The robot on the emulated DMC: puma200, puma560 or frhc.
    #[arg(long, default_value = "puma200")]
    pub arm_model: String,
    /// The sensor frame's origin in the tool frame, x,y,z m.
    #[arg(long, value_name = "X,Y,Z", default_value = "0,0,0")]
    pub mount: String,
    /// Stop after this many seconds (default: run until interrupted).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
}

fn numbers(flag: &str, text: &str, n: usize) -> anyhow::Result<Vec<f64>> {
    let v: Vec<f64> = text
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| crate::cmd::usage(format!("{flag} {text:?}: {e}")))?;
    if v.len() != n || !v.iter().all(|x| x.is_finite()) {
        return Err(crate::cmd::usage(format!(
            "{flag} {text:?}: needs {n} finite comma-separated numbers"
        )));
    }
    Ok(v)
}

fn environment(args: &Args) -> anyhow::Result<Environment> {
    let mut env = Environment::new();
    let mut add = |shape, k: f64, b: f64| -> anyhow::Result<()> {
        if !(0.0..=1e7).contains(&k) || !(0.0..=1e5).contains(&b) {
            return Err(crate::cmd::usage(
                "stiffness must be 0..=1e7 N/m and damping 0..=1e5 N·s/m",
            ));
        }
        env = std::mem::take(&mut env)
            .with(ContactModel {
                shape,
                stiffness: k,
                damping: b,
            })
            .map_err(|_| crate::cmd::usage("at most 8 shapes"))?;
        Ok(())
    };
    for p in &args.plane {
        let v = numbers("--plane", p, 8)?;
        let n = Vector3::new(v[3], v[4], v[5]);
        if n.norm() < 1e-9 {
            return Err(crate::cmd::usage("--plane: the normal must not be zero"));
        }
        let shape = Shape::Plane {
            point: Vector3::new(v[0], v[1], v[2]),
            normal: Unit::new_normalize(n),
        };
        add(shape, v[6], v[7])?;
    }
    for s in &args.sphere {
        let v = numbers("--sphere", s, 6)?;
        if v[3] <= 0.0 {
            return Err(crate::cmd::usage("--sphere: the radius must be positive"));
        }
        let shape = Shape::Sphere {
            center: Vector3::new(v[0], v[1], v[2]),
            radius: v[3],
        };
        add(shape, v[4], v[5])?;
    }
    Ok(env)
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let bind: std::net::SocketAddr = args
        .bind
        .parse()
        .map_err(|e| crate::cmd::usage(format!("--bind {:?}: {e} (ip:port)", args.bind)))?;
    if !(args.rate.is_finite() && (1.0..=MAX_RATE_HZ).contains(&args.rate)) {
        return Err(crate::cmd::usage("--rate must be 1..=7000 Hz"));
    }
    let calibration = Calibration {
        counts_per_force: args.counts_per_force,
        counts_per_torque: args.counts_per_torque,
    };
    if !calibration.is_valid() {
        return Err(crate::cmd::usage(
            "counts per force and torque must be positive",
        ));
    }
    if !(args.noise.is_finite() && args.noise >= 0.0) {
        return Err(crate::cmd::usage("--noise must be >= 0"));
    }
    if let Some(d) = args.duration
        && !(d.is_finite() && d >= 0.0)
    {
        return Err(crate::cmd::usage(
            "--duration must be a non-negative number of seconds",
        ));
    }
    let m = numbers("--mount", &args.mount, 3)?;
    let mount = Pose::translation(m[0], m[1], m[2]);
    let env = environment(&args)?;
    let config = EmulatorConfig {
        bind,
        rate_hz: args.rate,
        calibration,
        noise: [args.noise, args.noise / 40.0],
        seed: args.seed,
        ..EmulatorConfig::default()
    };
    let mut galil = None;
    let emu = match &args.galil_link {
        Some(link) => {
            let Some(model) = penelope_drivers::model::by_name(&args.arm_model) else {
                return Err(crate::cmd::usage(
                    "--arm-model must be puma200, puma560 or frhc",
                ));
            };
            let dmc = PtyEmulator::spawn(PtyOptions {
                dmc: DmcConfig::default(),
                ..PtyOptions::default()
            })?;
            let _ = std::fs::remove_file(link);
            std::os::unix::fs::symlink(dmc.path(), link)?;
            eprintln!(
                "netft-sim: Galil DMC emulator on {} (link {})",
                dmc.path().display(),
                link.display()
            );
            let zero = model.named_pose(NamedPose::Start);
            let pose = galil_tool_pose(dmc.observer(), model, zero);
            let emu = NetFtEmulator::spawn(config, ProbedContact::new(env, mount, pose))?;
            galil = Some(dmc);
            emu
        }
        None => {
            // No arm: a probe at the origin of the sensor frame pressing into the shapes along
            // the base z axis and back, 2 cm over 4 s.
            let probe = move || {
                let t = START.elapsed().as_secs_f64();
                let z = -0.01 * (1.0 - (std::f64::consts::PI * t / 2.0).cos());
                let vz =
                    -0.01 * std::f64::consts::PI / 2.0 * (std::f64::consts::PI * t / 2.0).sin();
                Some((Pose::translation(0.0, 0.0, z), Vector3::new(0.0, 0.0, vz)))
            };
            NetFtEmulator::spawn(config, ProbedContact::new(env, mount, probe))?
        }
    };
    println!("{}", emu.local_addr());
    eprintln!(
        "netft-sim: Net F/T emulator on {} at {} Hz; interrupt to stop",
        emu.local_addr(),
        args.rate
    );
    super::serve_until(args.duration, || emu.is_running())?;
    let c = emu.counters();
    eprintln!(
        "netft-sim: {} records sent, {} requests, {} bad requests, {} biases",
        c.sent, c.requests, c.bad_requests, c.biases
    );
    emu.stop();
    if let (Some(dmc), Some(link)) = (galil, &args.galil_link) {
        let _ = std::fs::remove_file(link);
        dmc.stop();
    }
    Ok(ExitCode::SUCCESS)
}

/// When the process started (the free probe's clock).
static START: std::sync::LazyLock<std::time::Instant> =
    std::sync::LazyLock::new(std::time::Instant::now);
