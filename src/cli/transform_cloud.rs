//! `slam2world transform-cloud IN --align EST REF -o OUT.ply`: fit `T_world_slam`
//! between a SLAM keyframe trajectory (EST) and a reference (REF), carry a point
//! cloud in the SLAM frame (a PLY file, or `x y z` text such as ORB-SLAM's
//! `MapPoints.txt`) into the world frame and write it as a binary PLY.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use clap::Args;

use super::align::{finite, non_negative, read, Format};
use crate::cloud::PointCloud;
use crate::error::{Error, Result};
use crate::io::ply::{read_ply, read_xyz_text, write_ply};
use crate::trajectory::{align_trajectories, TrajectoryAlignOptions};

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
    /// Format of EST (and of REF unless --ref-format is given).
    #[arg(long, value_enum, default_value = "tum")]
    format: Format,
    /// Format of REF (default: the same as --format).
    #[arg(long, value_enum)]
    ref_format: Option<Format>,
    /// Largest time difference of a matched pair, seconds.
    #[arg(long, default_value_t = 0.01, value_name = "S", value_parser = non_negative)]
    max_diff: f64,
    /// Seconds added to the EST stamps before matching.
    #[arg(long, default_value_t = 0.0, value_name = "S", allow_negative_numbers = true, value_parser = finite)]
    offset: f64,
    /// Fit SE(3) (scale fixed to 1) instead of Sim(3).
    #[arg(long)]
    no_scale: bool,
}

/// A PLY file (recognised by its `ply` magic line) or `x y z` text.
pub fn read_cloud(path: &Path) -> Result<PointCloud> {
    let mut head = [0u8; 4];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .map_err(|e| Error::io(path, e))?;
    let is_ply = n >= 4 && &head[..3] == b"ply" && (head[3] == b'\n' || head[3] == b'\r');
    if is_ply {
        read_ply(path)
    } else {
        read_xyz_text(path)
    }
}

/// Runs the command; prints one summary line to stdout.
pub fn run(args: TransformCloudArgs) -> Result<()> {
    let [est_path, ref_path] = args.align.as_slice() else {
        return Err(Error::invalid("--align", "needs EST and REF"));
    };
    let cloud = read_cloud(&args.input)?;
    let est = read(est_path, args.format)?;
    let reference = read(ref_path, args.ref_format.unwrap_or(args.format))?;
    let opts = TrajectoryAlignOptions {
        max_diff: args.max_diff,
        offset: args.offset,
        scale: !args.no_scale,
        ..TrajectoryAlignOptions::default()
    };
    let fit = align_trajectories(&est, &reference, &opts)?;
    let t = fit.alignment.transform;
    let world = cloud.transformed(&t)?;
    write_ply(&args.output, &world)?;
    let line = format!(
        "aligned {} pose pairs: scale {:.9}, APE rmse {:.6} m; wrote {} points to {}\n",
        fit.pairs.len(),
        t.scale,
        fit.ape.rmse,
        world.len(),
        args.output.display()
    );
    let mut out = std::io::stdout().lock();
    out.write_all(line.as_bytes())
        .and_then(|_| out.flush())
        .map_err(|e| Error::io("<stdout>", e))
}
