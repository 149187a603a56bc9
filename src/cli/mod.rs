//! The `slam2world` command line (clap). The binary `src/bin/slam2world.rs` and
//! the wheel's console script both call [`main_with_args`].
//!
//! Exit codes: 0 success, 1 bad data (one readable line on stderr), 2 usage,
//! 130 / 143 stopped by SIGINT / SIGTERM (no output of the run written; the
//! previous outputs intact; a second signal ends the process at once).

use std::ffi::OsString;

use clap::{Parser, Subcommand};

pub mod align;
mod align_files;
pub mod ape_plot;
pub mod args;
pub mod convert;
pub mod follow;
pub mod imu_init;
pub mod inspect;
pub mod schema;
pub mod serve;
pub mod sim;
pub mod transform_cloud;

use crate::error::Result;

/// Metric, gravity-aligned 3-D worlds from monocular SLAM maps.
#[derive(Parser, Debug)]
#[command(name = "slam2world", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Fit the Sim(3) between two trajectory files (or two pose topics of a log) and print the error statistics.
    Align(Box<align::AlignArgs>),
    /// Metric scale, gravity direction and IMU biases of SLAM keyframes from raw IMU samples.
    ImuInit(imu_init::ImuInitArgs),
    /// Convert a log (MCAP, ROS 1 bag, rosbag2) or a reconstruction (COLMAP, DROID-SLAM, DPVO, MASt3R-SLAM, DSO, ORB-SLAM3) into metric, gravity-aligned outputs.
    Convert(Box<convert::ConvertArgs>),
    /// Follow a log while it is written: the metric world and the 2-D map updated after every keyframe.
    Follow(Box<follow::FollowArgs>),
    /// List the topics of a log (MCAP, ROS 1 bag, rosbag2) and what slam2world can use.
    Inspect(inspect::InspectArgs),
    /// Simulate the paper's experiment and write the LSD-SLAM log (MCAP) and its truth.
    Simulate(sim::SimulateArgs),
    /// Score a converted cloud and T_world_slam against a simulation's truth.
    Evaluate(sim::EvaluateArgs),
    /// Simulate the paper-size run, convert, score, write outputs and figures.
    Demo(sim::DemoArgs),
    /// Align EST to REF and carry a SLAM-frame point cloud (PLY or x y z text) into the world frame.
    TransformCloud(Box<transform_cloud::TransformCloudArgs>),
    /// Serve a conversion's metric world (OUT/world.mcap) on a Foxglove WebSocket until Ctrl-C.
    Serve(serve::ServeArgs),
    /// Print (or write with -o) the Foxglove layout of the metric world: the 3-D scene, the session's state, its fit and latency.
    Layout(serve::LayoutArgs),
    /// Print the JSON Schema of a document the commands write (report.json, align --json, …).
    Schema(schema::SchemaArgs),
    /// Convert many logs on Ray (one task per log): the `slam2world` console script of the Python package runs it.
    Batch(BatchArgs),
}

/// `slam2world batch`: the arguments are read by the Python package's
/// console script (`slam2world.batch`), which runs one `convert` per log on Ray.
#[derive(clap::Args, Debug)]
pub struct BatchArgs {
    /// Inputs, `-o OUT/` and convert options, as `slam2world.batch` reads them.
    #[arg(
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "ARGS"
    )]
    args: Vec<OsString>,
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Align(args) => align::run(*args),
        Command::ImuInit(args) => imu_init::run(args),
        Command::Convert(args) => convert::run(&args),
        Command::Follow(args) => follow::run(&args),
        Command::Inspect(args) => inspect::run(&args),
        Command::Simulate(args) => sim::run_simulate(&args),
        Command::Evaluate(args) => sim::run_evaluate(&args),
        Command::Demo(args) => sim::run_demo(&args),
        Command::TransformCloud(args) => transform_cloud::run(*args),
        Command::Schema(args) => schema::run(&args),
        Command::Serve(args) => serve::run(&args),
        Command::Layout(args) => serve::run_layout(&args),
        Command::Batch(_) => Err(crate::Error::invalid(
            "batch",
            "batch runs on Ray from the Python package: pip install 'slam2world[ray]', then run \
             its `slam2world batch` console script (or slam2world.batch.convert_many)",
        )),
    }
}

/// Parses `args` (the program name first) as `slam2world convert …` and runs
/// it, returning its error instead of printing it (the batch path of the
/// Python package turns it into a typed exception and a summary row). A
/// command line that does not parse, or names another command, is an
/// [`crate::Error::InvalidArgument`] with clap's message.
pub fn run_convert_args<I, T>(args: I) -> Result<()>
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = Cli::try_parse_from(args)
        .map_err(|e| crate::Error::invalid("convert arguments", e.to_string().trim_end()))?;
    match cli.command {
        Command::Convert(args) => {
            let guard = crate::interrupt::Guard::new(crate::interrupt::Second::Terminates);
            let r = convert::run(&args);
            drop(guard);
            r
        }
        _ => Err(crate::Error::invalid(
            "convert arguments",
            "the command line must be `slam2world convert …`",
        )),
    }
}

/// Parses `args` (the program name first) and runs the command; returns the
/// process exit code. Never panics on user input.
pub fn main_with_args<I, T>(args: I) -> i32
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return code;
        }
    };
    let guard = crate::interrupt::Guard::new(crate::interrupt::Second::Terminates);
    let result = run(cli);
    drop(guard);
    match result {
        Ok(()) => 0,
        Err(e @ crate::Error::Interrupted { signal }) => {
            eprintln!("slam2world: {e}");
            crate::interrupt::exit_code(signal)
        }
        Err(e) => {
            eprintln!("slam2world: error: {e}");
            1
        }
    }
}
