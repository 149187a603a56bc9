//! `slam2world serve OUT/`: a finished conversion's metric world on a
//! Foxglove WebSocket ([`crate::live::WorldServer`]) until Ctrl-C; and
//! `slam2world layout`: the Foxglove layout that shows it.

use std::path::PathBuf;
use std::time::Duration;

use clap::Args;

use super::args::print;
use crate::error::Result;
use crate::live::{ServeOptions, WorldServer};

/// Arguments of `serve`.
#[derive(Args, Debug)]
pub struct ServeArgs {
    /// A conversion's output folder (or its world.mcap).
    #[arg(value_name = "OUT")]
    world: PathBuf,
    /// Address to listen on: this machine only by default; `0.0.0.0` for
    /// every interface (the robot's network).
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// Port (Foxglove's default; 0 takes a free one, printed).
    #[arg(long, default_value_t = 8765)]
    port: u16,
}

/// Serves until SIGINT or SIGTERM, then stops cleanly (exit code 0).
pub fn run(args: &ServeArgs) -> Result<()> {
    let server = WorldServer::start(
        &args.world,
        &ServeOptions {
            host: args.host.clone(),
            port: args.port,
        },
    )?;
    let topics = server.topics();
    print(&format!(
        "serving {} on {} ({} topics: {}); open it in Foxglove (Open connection, Foxglove \
         WebSocket); Ctrl-C stops\n",
        server.path().display(),
        server.url(),
        topics.len(),
        topics.join(", ")
    ))?;
    while crate::interrupt::pending_signal().is_none() {
        std::thread::sleep(Duration::from_millis(100));
    }
    server.stop();
    Ok(())
}

/// Arguments of `layout`.
#[derive(Args, Debug)]
pub struct LayoutArgs {
    /// Write the layout to this file instead of printing it.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
}

/// Prints or writes [`crate::live::FOXGLOVE_LAYOUT`].
pub fn run_layout(args: &LayoutArgs) -> Result<()> {
    let layout = crate::live::FOXGLOVE_LAYOUT;
    match &args.output {
        Some(path) => {
            crate::io::atomic::write_bytes_atomic(path, layout.as_bytes())?;
            print(&format!(
                "wrote {}; in Foxglove: Layouts, Import from file\n",
                path.display()
            ))
        }
        None => print(layout),
    }
}
