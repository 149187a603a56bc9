//! `slam2world inspect LOG`: the container, then every topic with its type,
//! encoding, count and time range (from the index where the container has
//! one), and what slam2world can use. LOG is an MCAP file, a ROS 1 bag, a
//! rosbag2 folder or `.db3`.

use std::path::PathBuf;

use clap::Args;

use super::args::print;
use crate::error::Result;
use crate::io::log::{inspect_log, Inspection};
use crate::io::messages::ReadMode;

/// Arguments of `inspect`.
#[derive(Args, Debug)]
pub struct InspectArgs {
    /// The log: MCAP, ROS 1 bag, rosbag2 folder (or its metadata.yaml) or .db3.
    pub log: PathBuf,
}

fn seconds(ns: u64) -> String {
    format!("{:.3}", ns as f64 * 1e-9)
}

/// Prints the inventory of the log to stdout.
pub fn run(args: &InspectArgs) -> Result<()> {
    print(&text(&inspect_log(&args.log)?))
}

/// The inventory as `inspect` prints it.
pub fn text(inv: &Inspection) -> String {
    let mode = match (inv.mode, inv.from_index) {
        (ReadMode::Indexed, true) => "indexed (counts from the index)",
        (ReadMode::Indexed, false) => "indexed",
        (ReadMode::Linear, _) => "linear scan (no usable index)",
    };
    let mut s = format!("{}\n", inv.path.display());
    s += &format!(
        "container: {}   profile: {}   read: {mode}\n",
        inv.container.name(),
        if inv.profile.is_empty() {
            "-"
        } else {
            &inv.profile
        }
    );
    let all: Vec<(u64, u64)> = inv.topics.iter().filter_map(|t| t.time_range).collect();
    if let (Some(start), Some(end)) = (all.iter().map(|r| r.0).min(), all.iter().map(|r| r.1).max())
    {
        s += &format!(
            "time: {} .. {} s ({:.3} s)\n",
            seconds(start),
            seconds(end),
            (end - start) as f64 * 1e-9
        );
    }
    s += "\n";
    s += &format!(
        "{:<32} {:<46} {:<10} {:>8}  {:<33} use\n",
        "topic", "type (schema encoding)", "messages", "count", "time range (s)"
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
        s += &format!(
            "{:<32} {:<46} {:<10} {:>8}  {:<33} {usage}\n",
            t.topic, schema, t.message_encoding, t.count, range
        );
    }
    s += "\n";
    if inv.picks.is_empty() {
        s += "slam2world finds nothing it can use in this log\n";
    }
    for (role, topic) in &inv.picks {
        s += &format!("default {role:<10} {topic}\n");
    }
    s
}
