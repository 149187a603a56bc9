//! `slam2world inspect LOG.mcap`: topics, schemas, encodings, counts, time
//! range, and what slam2world can use.

use std::path::PathBuf;

use clap::Args;

use crate::error::Result;
use crate::io::mcap::{inspect_mcap, ReadMode};

/// Arguments of `inspect`.
#[derive(Args, Debug)]
pub struct InspectArgs {
    /// The MCAP log.
    pub log: PathBuf,
}

fn seconds(ns: u64) -> String {
    format!("{:.3}", ns as f64 * 1e-9)
}

/// Prints the inventory of the log to stdout.
pub fn run(args: &InspectArgs) -> Result<()> {
    let inv = inspect_mcap(&args.log)?;
    let mode = match inv.mode {
        ReadMode::Indexed => "indexed",
        ReadMode::Linear => "linear scan",
    };
    println!("{}", args.log.display());
    println!(
        "profile: {}   read: {mode}",
        if inv.profile.is_empty() {
            "-"
        } else {
            &inv.profile
        }
    );
    let all: Vec<(u64, u64)> = inv.topics.iter().filter_map(|t| t.time_range).collect();
    if let (Some(start), Some(end)) = (all.iter().map(|r| r.0).min(), all.iter().map(|r| r.1).max())
    {
        println!(
            "time: {} .. {} s ({:.3} s)",
            seconds(start),
            seconds(end),
            (end - start) as f64 * 1e-9
        );
    }
    println!();
    println!(
        "{:<32} {:<46} {:<10} {:>8}  {:<33} use",
        "topic", "schema (encoding)", "messages", "count", "time range (s)"
    );
    for t in &inv.topics {
        let schema = if t.schema_name.is_empty() {
            "(none)".to_string()
        } else {
            format!("{} ({})", t.schema_name, t.schema_encoding)
        };
        let range = t
            .time_range
            .map(|(a, b)| format!("{} .. {}", seconds(a), seconds(b)))
            .unwrap_or_else(|| "-".into());
        let usage = match t.kind {
            Some(k) if k.encodings().contains(&t.message_encoding.as_str()) => {
                k.usage().to_string()
            }
            Some(_) => format!("unsupported encoding {}", t.message_encoding),
            None => "-".into(),
        };
        println!(
            "{:<32} {:<46} {:<10} {:>8}  {:<33} {usage}",
            t.topic, schema, t.message_encoding, t.count, range
        );
    }
    println!();
    if inv.picks.is_empty() {
        println!("slam2world finds nothing it can use in this log");
    }
    for (role, topic) in &inv.picks {
        println!("default {role:<10} {topic}");
    }
    Ok(())
}
