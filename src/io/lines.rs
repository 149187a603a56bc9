//! Text formats line by line: the trajectory and point readers (TUM, EuRoC,
//! KITTI, IMU CSV, `x y z` points) go through [`for_each_line`] (lines of at
//! most [`MAX_LINE_BYTES`], UTF-8, a byte-order mark dropped) and parse
//! numbers with [`parse_fields`] (errors naming the line and field); a format
//! is told from a file's [`head`] (KITTI, GNSS); the pose writers (TUM,
//! EuRoC, KITTI) write a line per pose with [`pose_text`].

use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::trajectory::Trajectory;

/// Longest line the text readers accept, bytes: far above any real pose
/// line, so that a file without line breaks (`/dev/zero`) is refused at once.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// The first 8 KiB of a file (what a format is told from).
pub(crate) fn head(path: &Path) -> Result<Vec<u8>> {
    use std::io::Read as _;
    let mut head = Vec::with_capacity(8192);
    std::fs::File::open(path)
        .map_err(|e| Error::io(path, e))?
        .take(8192)
        .read_to_end(&mut head)
        .map_err(|e| Error::io(path, e))?;
    Ok(head)
}

/// Calls `f(line number, line)` for each line of the file at `path`, read
/// as a stream: lines longer than [`MAX_LINE_BYTES`] (a file without line
/// breaks, `/dev/zero`) and lines that are not UTF-8 are format errors
/// naming the line; a leading byte-order mark is dropped.
pub(crate) fn for_each_line(
    path: &Path,
    what: &str,
    f: impl FnMut(usize, &str) -> Result<()>,
) -> Result<()> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    bounded_lines(path, what, std::io::BufReader::new(file), f)
}

pub(crate) fn parse_fields(path: &Path, line: usize, fields: &[&str]) -> Result<Vec<f64>> {
    fields
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let v: f64 = f.trim().parse().map_err(|_| {
                Error::parse(
                    path,
                    line,
                    format!("field {} is not a number: {}", k + 1, crate::error::cut(f)),
                )
            })?;
            if !v.is_finite() {
                return Err(Error::parse(
                    path,
                    line,
                    format!("field {} is not finite: {}", k + 1, crate::error::cut(f)),
                ));
            }
            Ok(v)
        })
        .collect()
}

/// Lines of at most [`MAX_LINE_BYTES`], read without holding more than one;
/// `what` names the kind of file in the error of a long line.
pub(crate) fn bounded_lines(
    path: &Path,
    what: &str,
    mut r: impl std::io::BufRead,
    mut f: impl FnMut(usize, &str) -> Result<()>,
) -> Result<()> {
    let mut buf = Vec::new();
    let mut line = 0usize;
    loop {
        buf.clear();
        line += 1;
        loop {
            let chunk = r.fill_buf().map_err(|e| Error::io(path, e))?;
            if chunk.is_empty() {
                break;
            }
            let (take, done) = match chunk.iter().position(|&b| b == b'\n') {
                Some(i) => (i + 1, true),
                None => (chunk.len(), false),
            };
            if buf.len() + take > MAX_LINE_BYTES + 1 {
                return Err(Error::parse(
                    path,
                    line,
                    format!("line longer than {MAX_LINE_BYTES} bytes: not {what}"),
                ));
            }
            buf.extend_from_slice(&chunk[..take]);
            r.consume(take);
            if done {
                break;
            }
        }
        if buf.is_empty() {
            return Ok(());
        }
        let mut bytes = buf.as_slice();
        if line == 1 {
            bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
        }
        let text = std::str::from_utf8(bytes).map_err(|e| {
            Error::parse(
                path,
                line,
                format!(
                    "not UTF-8 text (byte {} of the line): not {what}",
                    e.valid_up_to() + 1
                ),
            )
        })?;
        f(line, text)?;
    }
}

/// The text of `traj` a line per pose: `header`, then `row(out, stamp,
/// position, orientation)` for each pose (the identity for a trajectory
/// without orientations). A file of these formats has no count in it, so
/// one without rows reads as a wrong file to every reader (this one and
/// evo): none is written (`format` names it in the error).
pub(crate) fn pose_text(
    traj: &Trajectory,
    format: &str,
    header: &str,
    mut row: impl FnMut(&mut String, f64, &Vector3<f64>, &UnitQuaternion<f64>),
) -> Result<Vec<u8>> {
    traj.check_lengths()?;
    if traj.is_empty() {
        return Err(Error::invalid(
            "trajectory",
            format!("no poses to write (a {format} file without rows is refused by its readers)"),
        ));
    }
    let identity = UnitQuaternion::identity();
    let mut s = String::with_capacity(header.len() + 128 * traj.len());
    s.push_str(header);
    for i in 0..traj.len() {
        let q = traj.orientations.as_ref().map_or(&identity, |o| &o[i]);
        row(&mut s, traj.timestamps[i], &traj.positions[i], q);
    }
    Ok(s.into_bytes())
}
