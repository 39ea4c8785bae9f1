//! `penelope recording info FILE`: what a recording holds — its channels (topic, schema,
//! message count), its first and last message's times and its duration, and its metadata (the
//! node, what the recorder lost).
//!
//! `penelope recording rerun FILE [--config SYSTEM.toml]`: runs a recorded simulated-clock demo
//! again against its recorded operator and contact forces
//! ([`rerun`](penelope_supervisor::runs::rerun)) and reports, per controller and signal, the
//! ticks that differ and by how much. Exit code 0: bit for bit the same; 1: different.

use std::path::PathBuf;
use std::process::ExitCode;

use penelope_runtime::objects::recording::mcap_log::{ChannelSummary, summarize};
use penelope_supervisor::runs::rerun::{Rerun, rerun};

use super::usage;

/// `penelope recording`: what a recording holds, or the recorded run run again.
#[derive(clap::Subcommand, Debug)]
pub enum RecordingCommand {
    /// What a recording (MCAP) holds: channels, schemas, message counts, start, end, duration,
    /// metadata.
    Info(InfoArgs),
    /// Run a recorded simulated-clock demo again against its recorded operator and contact
    /// forces, and report what differs (exit code 1 if anything does).
    Rerun(RerunArgs),
}

/// Options of `penelope recording info`.
#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The recording (an MCAP file: `run.mcap` of `penelope demo`, or `penelope node --record`).
    pub file: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Options of `penelope recording rerun`.
#[derive(clap::Args, Debug)]
pub struct RerunArgs {
    /// The recording of a simulated-clock demo (`run.mcap` of `penelope demo --sim-clock`).
    pub file: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// This system file instead of the one recorded (for example with another gain); the
    /// recorded run's options (duration, seed, law, kinematics) still apply.
    #[arg(long, value_name = "SYSTEM.toml")]
    pub config: Option<PathBuf>,
}

/// Runs `penelope recording`.
///
/// # Errors
/// A usage error (exit code 2) when the file cannot be read or is not a recording.
pub fn run(command: RecordingCommand) -> anyhow::Result<ExitCode> {
    match command {
        RecordingCommand::Info(args) => info(&args),
        RecordingCommand::Rerun(args) => run_again(&args),
    }
}

/// `penelope recording info`.
fn info(args: &InfoArgs) -> anyhow::Result<ExitCode> {
    let summary = summarize(&args.file).map_err(|e| usage(e.to_string()))?;
    if args.json {
        let mut value = serde_json::to_value(&summary)?;
        value["duration_ns"] = summary.duration_ns().into();
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!("{}", args.file.display());
    println!(
        "  profile {:?}, {} messages on {} channels",
        summary.profile,
        summary.messages,
        summary.channels.len()
    );
    let secs = |ns: u64| ns as f64 * 1e-9;
    println!(
        "  start {:.6} s, end {:.6} s, duration {:.6} s (log times, the node's clock)",
        secs(summary.start_ns),
        secs(summary.end_ns),
        secs(summary.duration_ns())
    );
    for line in channel_table(&summary.channels) {
        println!("{line}");
    }
    for (name, entries) in &summary.metadata {
        // A long text (the `run` record's system file) is shown by its size.
        let list: Vec<String> = entries
            .iter()
            .map(|(k, v)| match v.lines().count() {
                0 | 1 => format!("{k}={v}"),
                n => format!("{k}=({n} lines)"),
            })
            .collect();
        println!("  metadata {name}: {}", list.join(" "));
    }
    Ok(ExitCode::SUCCESS)
}

/// The channels as a table with a header: topic, schema (with its encoding) and message
/// count, each column as wide as its widest cell (in characters), so that a long name moves
/// the columns after it rather than pushing its own row out of line.
fn channel_table(channels: &[ChannelSummary]) -> Vec<String> {
    let rows: Vec<[String; 3]> = channels
        .iter()
        .map(|c| {
            let schema = if c.schema.is_empty() {
                "(none)".to_string()
            } else {
                format!("{} ({})", c.schema, c.schema_encoding)
            };
            [c.topic.clone(), schema, c.messages.to_string()]
        })
        .collect();
    let header = ["topic", "schema", "messages"].map(String::from);
    let width = |column: usize| {
        std::iter::once(&header)
            .chain(&rows)
            .map(|row| row[column].chars().count())
            .max()
            .unwrap_or(0)
    };
    let (topic, schema, messages) = (width(0), width(1), width(2));
    std::iter::once(&header)
        .chain(&rows)
        .map(|[t, s, m]| format!("  {t:<topic$}  {s:<schema$}  {m:>messages$}"))
        .collect()
}

/// `penelope recording rerun`.
fn run_again(args: &RerunArgs) -> anyhow::Result<ExitCode> {
    let config = match &args.config {
        Some(p) => Some((
            std::fs::read_to_string(p)
                .map_err(|e| usage(format!("reading the system file {}: {e}", p.display())))?,
            p.display().to_string(),
        )),
        None => None,
    };
    let result = rerun(
        &args.file,
        config.as_ref().map(|(t, p)| (t.as_str(), p.as_str())),
        &mut |_| {},
    )
    .map_err(|e| usage(e.to_string()))?;
    if args.json {
        let mut value = serde_json::to_value(&result)?;
        value["identical"] = result.identical().into();
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        print_rerun(&result);
    }
    Ok(if result.identical() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

fn print_rerun(r: &Rerun) {
    println!(
        "{}: run again on the simulated clock (system file: {}), its operator and contact forces replayed",
        r.recording.display(),
        r.system_from
    );
    for c in &r.controllers {
        let verdict = if c.identical() {
            "identical, bit for bit".to_string()
        } else {
            format!("{} of {} ticks differ", c.differing_ticks, c.compared)
        };
        println!(
            "  {}: {} ticks recorded, {} run again: {verdict}",
            c.controller, c.recorded, c.rerun
        );
        if c.signals.is_empty() {
            continue;
        }
        println!(
            "    {:<28} {:>14} {:>16} {:>12}",
            "signal", "ticks differing", "max abs diff", "first seq"
        );
        for s in &c.signals {
            println!(
                "    {:<28} {:>14} {:>16.6e} {:>12}",
                s.signal, s.differing_ticks, s.max_abs_diff, s.first_seq
            );
        }
    }
    println!(
        "  {}",
        if r.identical() {
            "the rerun gives the recording back bit for bit"
        } else {
            "the rerun differs from the recording"
        }
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(topic: &str, schema: &str, messages: u64) -> ChannelSummary {
        ChannelSummary {
            topic: topic.into(),
            schema: schema.into(),
            schema_encoding: if schema.is_empty() { "" } else { "jsonschema" }.into(),
            message_encoding: "json".into(),
            messages,
        }
    }

    #[test]
    fn the_channel_tables_columns_line_up_whatever_the_names_length() {
        let channels = [
            channel("/clock", "penelope.Clock", 7),
            channel(
                "/controllers/a-controller-with-a-very-long-name-indeed",
                "penelope.Tick",
                123_456,
            ),
            channel(
                "/x",
                "foxglove.FrameTransformsWithAVeryLongSchemaNameToo",
                1,
            ),
            channel("/tf_static", "", 0),
        ];
        let lines = channel_table(&channels);
        for line in &lines {
            println!("{line}");
        }
        assert_eq!(lines.len(), 5, "a header and a row per channel");
        // Where each line's schema column starts, and where its count ends.
        let schema_at = |line: &str, schema: &str| line.find(schema).unwrap();
        let starts = [
            schema_at(&lines[0], "schema"),
            schema_at(&lines[1], "penelope.Clock"),
            schema_at(&lines[2], "penelope.Tick"),
            schema_at(&lines[3], "foxglove.FrameTransforms"),
            schema_at(&lines[4], "(none)"),
        ];
        assert!(starts.iter().all(|&s| s == starts[0]), "{starts:?}");
        assert_eq!(starts[0], 2 + channels[1].topic.len() + 2);
        let ends: Vec<usize> = lines.iter().map(|l| l.chars().count()).collect();
        assert!(ends.iter().all(|&e| e == ends[0]), "{ends:?}");
        assert!(lines[2].ends_with(" 123456"), "{}", lines[2]);
        assert!(
            lines[3].contains("foxglove.FrameTransformsWithAVeryLongSchemaNameToo (jsonschema)  "),
            "{}",
            lines[3]
        );
    }
}
