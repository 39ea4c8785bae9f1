//! `penelope replay FILE`: what a recording holds — its channels (topic, schema, message
//! count), its first and last message's times and its duration, and its metadata (the node,
//! what the recorder lost).

use std::path::PathBuf;
use std::process::ExitCode;

use penelope_supervisor::runs::mcap_log::summarize;

use super::usage;

/// Options of `penelope replay`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The recording (an MCAP file: `run.mcap` of `penelope demo`, or `penelope node --record`).
    pub file: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `penelope replay`.
///
/// # Errors
/// A usage error (exit code 2) when the file cannot be read or is not MCAP.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
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
    let width = summary
        .channels
        .iter()
        .map(|c| c.topic.len())
        .max()
        .unwrap_or(5)
        .max(5);
    println!(
        "  {:<width$}  {:<36}  {:>10}",
        "topic", "schema", "messages"
    );
    for c in &summary.channels {
        let schema = if c.schema.is_empty() {
            "(none)".to_string()
        } else {
            format!("{} ({})", c.schema, c.schema_encoding)
        };
        println!("  {:<width$}  {:<36}  {:>10}", c.topic, schema, c.messages);
    }
    for (name, entries) in &summary.metadata {
        let list: Vec<String> = entries.iter().map(|(k, v)| format!("{k}={v}")).collect();
        println!("  metadata {name}: {}", list.join(" "));
    }
    Ok(ExitCode::SUCCESS)
}
