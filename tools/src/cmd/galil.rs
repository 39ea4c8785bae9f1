//! `penelope galil`: drive a Galil DMC motion controller over a serial line (or the emulator's
//! pseudo-terminal from `penelope galil-sim`).

use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Subcommand;
use penelope_drivers::galil::{
    Axes, Client, ClientConfig, Command, GalilError, Operand, SerialLink, SerialSettings, Setting,
    Tell,
};

/// Options.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Serial device (`/dev/ttyUSB0`, or the path `penelope galil-sim` printed).
    #[arg(long)]
    pub port: String,
    /// Baud rate (8N1, no handshake).
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Reply timeout, ms.
    #[arg(long, default_value_t = 1000)]
    pub timeout_ms: u64,
    /// What to do.
    #[command(subcommand)]
    pub action: Action,
}

/// What to do with the board.
#[derive(Subcommand, Debug)]
pub enum Action {
    /// Send one command line and print the reply (`error <code>: <text>` and exit 1 on rejection).
    Send {
        /// The command text, e.g. "TP" or "SH A;BG A".
        command: String,
    },
    /// Model, firmware and axis count.
    Info,
    /// Motor positions, counts.
    Positions {
        /// Print `{"axes": [counts...]}`.
        #[arg(long)]
        json: bool,
    },
    /// Live positions and position errors.
    Monitor {
        /// Sample period, ms.
        #[arg(long, default_value_t = 200)]
        interval_ms: u64,
        /// Stop after this many samples (default: run until interrupted).
        #[arg(long)]
        count: Option<u64>,
    },
    /// Jog one axis at a speed (servo on first); stop it with `stop`.
    Jog {
        /// Axis letter, A..H.
        #[arg(long, default_value = "A")]
        axis: String,
        /// Speed, counts/s (signed).
        #[arg(long)]
        speed: f64,
    },
    /// Move one axis to a position or by a distance (servo on first).
    Move {
        /// Axis letter, A..H.
        #[arg(long, default_value = "A")]
        axis: String,
        /// Absolute target, counts.
        #[arg(long, conflicts_with = "by", required_unless_present = "by")]
        to: Option<f64>,
        /// Relative distance, counts.
        #[arg(long)]
        by: Option<f64>,
        /// Slew speed, counts/s.
        #[arg(long)]
        speed: Option<f64>,
        /// Return at once instead of waiting for the move to end.
        #[arg(long)]
        no_wait: bool,
    },
    /// Stop motion (decelerated), or abort at once with `--abort`.
    Stop {
        /// Abort motion at once (`AB 1`) instead of decelerating (`ST`).
        #[arg(long)]
        abort: bool,
    },
}

fn axis_index(letter: &str) -> anyhow::Result<usize> {
    match Axes::parse(letter) {
        Some(a) if a.count() == 1 => Ok(a.indices().next().unwrap_or(0)),
        _ => Err(crate::cmd::usage(format!(
            "--axis must be one letter A..H, not {letter:?}"
        ))),
    }
}

fn finite(name: &str, v: f64) -> anyhow::Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(crate::cmd::usage(format!("{name} must be a finite number")))
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    // Check user input before touching the line.
    match &args.action {
        Action::Jog { axis, speed } => {
            axis_index(axis)?;
            finite("--speed", *speed)?;
        }
        Action::Move {
            axis,
            to,
            by,
            speed,
            ..
        } => {
            axis_index(axis)?;
            for (n, v) in [("--to", to), ("--by", by), ("--speed", speed)] {
                if let Some(v) = v {
                    finite(n, *v)?;
                }
            }
        }
        _ => {}
    }
    let link = SerialLink::open(&SerialSettings::new(args.port.clone(), args.baud))
        .map_err(|e| anyhow::anyhow!("cannot open {}: {e}", args.port))?;
    let config = ClientConfig {
        timeout: Duration::from_millis(args.timeout_ms.max(1)),
        ..ClientConfig::default()
    };
    let mut client = Client::new(link, config);
    let info = client.initialize()?;
    let axes = info.layout.axes;
    let result = match args.action {
        Action::Send { command } => return send(&mut client, &command),
        Action::Info => {
            println!("model     {}", info.identity.model);
            println!("firmware  {}", info.identity.firmware);
            println!("axes      {axes}");
            println!(
                "record    {} bytes (QZ {}, {}, {}, {})",
                info.layout.record_len(),
                info.layout.axes,
                info.layout.general,
                info.layout.coordinated,
                info.layout.axis
            );
            Ok(())
        }
        Action::Positions { json } => client.positions().map(|p| {
            if json {
                println!("{}", serde_json::json!({ "axes": p.as_slice() }));
            } else {
                let cells: Vec<String> = p.iter().map(i64::to_string).collect();
                println!("{}", cells.join(" "));
            }
        }),
        Action::Monitor { interval_ms, count } => monitor(&mut client, axes, interval_ms, count),
        Action::Jog { axis, speed } => {
            let i = axis_index(&axis)?;
            let mut values = [None; 8];
            values[i] = Some(speed);
            let one = Axes(1 << i);
            client
                .ack(&Command::ServoHere(one))
                .and_then(|()| client.set(Setting::Jog, &values[..=i]))
                .and_then(|()| client.ack(&Command::Begin(one)))
        }
        Action::Move {
            axis,
            to,
            by,
            speed,
            no_wait,
        } => {
            let i = axis_index(&axis)?;
            move_axis(&mut client, i, to, by, speed, no_wait)
        }
        Action::Stop { abort } => {
            if abort {
                client.ack(&Command::Abort { motion_only: true })
            } else {
                client.ack(&Command::Stop(Axes::NONE))
            }
        }
    };
    match result {
        Ok(()) => Ok(ExitCode::SUCCESS),
        Err(e) => rejected_or(e),
    }
}

fn rejected_or(e: GalilError) -> anyhow::Result<ExitCode> {
    if let GalilError::Rejected { code, text } = &e {
        eprintln!("error {code}: {text}");
        return Ok(ExitCode::from(1));
    }
    Err(e.into())
}

fn send(client: &mut Client<SerialLink>, command: &str) -> anyhow::Result<ExitCode> {
    match client.send_text(command) {
        Ok(replies) => {
            for r in replies {
                if !r.as_str().is_empty() {
                    println!("{}", r.as_str());
                } else if !r.text.is_empty() && r.as_str().is_empty() {
                    // Binary (a QR record): hex.
                    let hex: Vec<String> = r.text.iter().map(|b| format!("{b:02x}")).collect();
                    println!("{}", hex.join(" "));
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        Err(GalilError::Rejected { code, text }) => {
            println!("error {code}: {text}");
            Ok(ExitCode::from(1))
        }
        Err(GalilError::InvalidArgument(why)) => Err(crate::cmd::usage(why)),
        Err(GalilError::LineTooLong) => Err(crate::cmd::usage("command longer than 80 characters")),
        Err(e) => Err(e.into()),
    }
}

fn monitor(
    client: &mut Client<SerialLink>,
    axes: usize,
    interval_ms: u64,
    count: Option<u64>,
) -> Result<(), GalilError> {
    let header: Vec<String> = (0..axes)
        .map(|i| format!("{:>12}", format!("{}pos/err", char::from(b'A' + i as u8))))
        .collect();
    println!("{:>8} {}", "t [s]", header.join(""));
    let start = Instant::now();
    let mut n = 0u64;
    loop {
        let p = client.tell(Tell::Position, Axes::NONE)?;
        let e = client.tell(Tell::Error, Axes::NONE)?;
        let cells: Vec<String> = p
            .iter()
            .zip(e.iter())
            .map(|(p, e)| format!("{:>12}", format!("{p}/{e}")))
            .collect();
        println!("{:>8.2} {}", start.elapsed().as_secs_f64(), cells.join(""));
        let text = client.take_unsolicited();
        if !text.is_empty() {
            println!("# board: {}", String::from_utf8_lossy(&text).trim_end());
        }
        n += 1;
        if count.is_some_and(|c| n >= c) {
            return Ok(());
        }
        std::thread::sleep(Duration::from_millis(interval_ms));
    }
}

fn move_axis(
    client: &mut Client<SerialLink>,
    i: usize,
    to: Option<f64>,
    by: Option<f64>,
    speed: Option<f64>,
    no_wait: bool,
) -> Result<(), GalilError> {
    let one = Axes(1 << i);
    let mut values = [None; 8];
    client.ack(&Command::ServoHere(one))?;
    // Position tracking would make PA move at once: leave it for a profiled move.
    values[i] = Some(0.0);
    client.set(Setting::PositionTracking, &values[..=i])?;
    if let Some(s) = speed {
        values[i] = Some(s);
        client.set(Setting::Speed, &values[..=i])?;
    }
    match (to, by) {
        (Some(t), _) => {
            values[i] = Some(t);
            client.set(Setting::PositionAbsolute, &values[..=i])?;
        }
        (None, Some(d)) => {
            values[i] = Some(d);
            client.set(Setting::PositionRelative, &values[..=i])?;
        }
        (None, None) => return Err(GalilError::InvalidArgument("--to or --by")),
    }
    client.ack(&Command::Begin(one))?;
    if no_wait {
        return Ok(());
    }
    // From the host, poll `MG _BGx` (AM/MC only wait inside programs).
    while client.message(Operand::Moving, i)? != 0.0 {
        std::thread::sleep(Duration::from_millis(20));
    }
    let p = client.tell(Tell::Position, one)?;
    let sc = client.tell(Tell::StopCode, one)?;
    println!(
        "axis {} at {} counts (stop code {})",
        char::from(b'A' + i as u8),
        p.first().copied().unwrap_or(0.0),
        sc.first().copied().unwrap_or(0.0)
    );
    Ok(())
}
