//! `slam2world schema [NAME]`: the JSON Schema of a document the commands
//! write (`report`, `align`, `imu-init`, `evaluate`, `demo`, `truth`), or with
//! `-o DIR` every schema as `DIR/NAME.schema.json`.

use std::path::PathBuf;

use clap::Args;

use super::args::print;
use crate::error::{Error, Result};
use crate::pipeline::report::{schemas, to_json_bytes};

/// Arguments of `schema`.
#[derive(Args, Debug)]
pub struct SchemaArgs {
    /// Which document: report, align, imu-init, evaluate, demo, truth or follow.
    #[arg(value_name = "NAME", required_unless_present = "output")]
    name: Option<String>,
    /// Write every schema into this folder instead.
    #[arg(short, long, value_name = "DIR")]
    output: Option<PathBuf>,
}

/// Prints one schema, or writes them all.
pub fn run(args: &SchemaArgs) -> Result<()> {
    let all = schemas();
    if let Some(dir) = &args.output {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        for (name, schema) in &all {
            let path = dir.join(format!("{name}.schema.json"));
            crate::io::atomic::write_bytes_atomic(&path, &to_json_bytes(schema)?)?;
        }
        return Ok(());
    }
    let name = args.name.as_deref().unwrap_or_default();
    match all.iter().find(|(n, _)| *n == name) {
        Some((_, schema)) => print(&String::from_utf8_lossy(&to_json_bytes(schema)?)),
        None => Err(Error::invalid(
            "NAME",
            format!(
                "no schema {}; one of {}",
                crate::error::cut(name),
                all.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
            ),
        )),
    }
}
