//! `slam2world transform-cloud IN --align EST REF -o OUT.ply`: fit `T_world_slam`
//! between a SLAM keyframe trajectory (EST) and a reference (REF), carry a point
//! cloud in the SLAM frame (a PLY file, or `x y z` text such as ORB-SLAM's
//! `MapPoints.txt`) into the world frame and write it as a binary PLY. The
//! conversion pipeline with the text-file source ([`TrajectoryFiles`]).

use std::path::PathBuf;

use clap::Args;

use super::align::format;
use super::args::{print, FitArgs};
use crate::error::{Error, Result};
use crate::io::atomic::OutputSet;
use crate::io::text::TrajectoryFormat;
use crate::pipeline::source::TrajectoryFiles;
use crate::pipeline::{convert_source, ConvertOptions};

/// Options of `slam2world transform-cloud`.
#[derive(Args, Debug)]
pub struct TransformCloudArgs {
    /// Point cloud in the SLAM frame: PLY (any format) or whitespace-separated `x y z` text.
    #[arg(value_name = "IN")]
    input: PathBuf,
    /// The SLAM keyframe trajectory and the reference trajectory to align.
    #[arg(long, num_args = 2, value_names = ["EST", "REF"], required = true)]
    align: Vec<PathBuf>,
    /// Output PLY (binary little-endian), written atomically.
    #[arg(short, long, value_name = "OUT.ply")]
    output: PathBuf,
    /// Format of EST (and of REF unless --ref-format is given): tum, euroc,
    /// kitti or transforms (default: found from the file, as `align` finds
    /// it; KITTI poses and frame-ordered scenes are stamped by their index).
    #[arg(long, value_name = "tum|euroc|kitti|transforms", value_parser = format)]
    format: Option<TrajectoryFormat>,
    /// Format of REF (default: found from the file, else the same as --format).
    #[arg(long, value_name = "tum|euroc|kitti|transforms", value_parser = format)]
    ref_format: Option<TrajectoryFormat>,
    #[command(flatten)]
    fit: FitArgs,
}

/// Runs the command; prints one summary line to stdout.
pub fn run(args: TransformCloudArgs) -> Result<()> {
    let [est, reference] = args.align.as_slice() else {
        return Err(Error::invalid("--align", "needs EST and REF"));
    };
    let opts = ConvertOptions {
        align: args.fit.options(),
        confidence: args.fit.confidence,
        ..ConvertOptions::default()
    };
    opts.check()?;
    // The output is none of the inputs: refused before the work.
    let mut outputs = OutputSet::new().with_inputs([&args.input, est, reference]);
    outputs.check_output(&args.output)?;
    let slam_format = TrajectoryFormat::of_file(args.format, est)?;
    let ref_format = TrajectoryFormat::of_reference(args.ref_format, args.format, reference)?;
    let source = TrajectoryFiles {
        slam: est.clone(),
        slam_format,
        reference: Some((reference.clone(), ref_format)),
        cloud: Some(args.input.clone()),
    };
    let c = convert_source(&source, &opts)?;
    c.ply_into(&mut outputs, &args.output)?;
    outputs.commit()?;
    let ape = c.report.ape.as_ref().map_or(f64::NAN, |a| a.rmse);
    print(&format!(
        "aligned {} pose pairs: scale {:.9}, APE rmse {:.6} m; wrote {} points to {}\n",
        c.report.pairs.len(),
        c.transform().scale,
        ape,
        c.cloud.len(),
        args.output.display()
    ))
}
