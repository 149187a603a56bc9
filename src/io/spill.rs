//! Temporary files of the bounded-memory conversion: what a long log would
//! otherwise hold in memory whole.
//!
//! - [`PixelSpill`]: the per-pixel arrays of every keyframe message, written
//!   as the log is read (inside the parallel chunk tasks) and read back a
//!   batch of keyframes at a time once `T_world_slam` is known;
//! - [`CloudFile`]: the world cloud, appended keyframe by keyframe and read
//!   back in bounded pieces by each output writer ([`CloudRef`]);
//! - [`RowSpill`]: rows of numbers (a reference trajectory's poses, raw IMU
//!   samples) written as the log is read, read back ([`RowFile`]) a piece at
//!   a time by the steps that use them.
//!
//! Both are anonymous files in the temporary folder (`TMPDIR`, else `/tmp`):
//! they take no name and are gone when closed, a crash included.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::trajectory::Trajectory;

#[cfg(unix)]
fn write_at(f: &File, buf: &[u8], offset: u64) -> std::io::Result<()> {
    std::os::unix::fs::FileExt::write_all_at(f, buf, offset)
}

#[cfg(unix)]
fn read_at(f: &File, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(f, buf, offset)
}

#[cfg(windows)]
fn write_at(f: &File, mut buf: &[u8], mut offset: u64) -> std::io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match f.seek_write(buf, offset)? {
            0 => return Err(std::io::ErrorKind::WriteZero.into()),
            n => {
                buf = &buf[n..];
                offset += n as u64;
            }
        }
    }
    Ok(())
}

#[cfg(windows)]
fn read_at(f: &File, mut buf: &mut [u8], mut offset: u64) -> std::io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match f.seek_read(buf, offset)? {
            0 => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            n => {
                buf = &mut buf[n..];
                offset += n as u64;
            }
        }
    }
    Ok(())
}

fn temp_file() -> Result<(File, PathBuf)> {
    let dir = std::env::temp_dir();
    let file = tempfile::tempfile_in(&dir).map_err(|e| Error::io(&dir, e))?;
    Ok((file, dir))
}

/// Where one keyframe message's pixels lie in a [`PixelSpill`]: the message's
/// LSD-SLAM point cloud bytes (inverse depth, variance, colour: 12 bytes a
/// pixel), unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpilledPixels {
    offset: u64,
    /// Pixels (`width × height` for a well-formed message).
    pub pixels: usize,
}

/// Keyframe pixels written once, read back by keyframe.
#[derive(Debug)]
pub struct PixelSpill {
    file: File,
    dir: PathBuf,
    end: AtomicU64,
}

impl PixelSpill {
    /// An empty spill in the temporary folder.
    pub fn new() -> Result<PixelSpill> {
        let (file, dir) = temp_file()?;
        Ok(PixelSpill {
            file,
            dir,
            end: AtomicU64::new(0),
        })
    }

    /// Bytes written so far.
    pub fn len(&self) -> u64 {
        self.end.load(Ordering::Relaxed)
    }

    /// True before the first write.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Appends one message's point cloud bytes (any thread may call it);
    /// an I/O error is returned as its text (the caller names the message).
    pub fn put(&self, pointcloud: &[u8]) -> std::result::Result<SpilledPixels, String> {
        let n = pointcloud.len() as u64;
        let offset = self.end.fetch_add(n, Ordering::Relaxed);
        write_at(&self.file, pointcloud, offset)
            .map_err(|e| format!("{}: {e}", self.dir.display()))?;
        Ok(SpilledPixels {
            offset,
            pixels: pointcloud.len() / crate::io::messages::decode::POINT_BYTES,
        })
    }

    /// The arrays of `at`: inverse depth, variance and colour (RGB).
    /// Read a piece at a time (a keyframe's bytes are never whole in memory
    /// beside its arrays).
    pub fn get(&self, at: SpilledPixels) -> Result<(Vec<f32>, Vec<f32>, Vec<u8>)> {
        use crate::io::messages::decode::{split_pointcloud_into, POINT_BYTES};
        const PIECE: usize = 1 << 14;
        let n = at.pixels;
        let mut out = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(3 * n),
        );
        let mut bytes = vec![0u8; PIECE.min(n) * POINT_BYTES];
        let mut done = 0;
        while done < n {
            let k = PIECE.min(n - done);
            let piece = &mut bytes[..k * POINT_BYTES];
            read_at(&self.file, piece, at.offset + (done * POINT_BYTES) as u64)
                .map_err(|e| Error::io(&self.dir, e))?;
            split_pointcloud_into(piece, &mut out);
            done += k;
        }
        Ok(out)
    }
}

/// The pixels of a log's keyframes left on disk: `at[i]` those of keyframe
/// `i` of the log (the latest version of each id).
#[derive(Debug)]
pub struct SpilledKeyframes {
    /// The spill the log was read into (every version of every keyframe).
    pub spill: PixelSpill,
    /// Where each keyframe's pixels are.
    pub at: Vec<SpilledPixels>,
}

/// Rows of `f64`s as a scan gives them (a trajectory's poses, raw IMU
/// samples), appended to a temporary file as little-endian bytes. A write
/// error is kept and returned by [`RowSpill::finish`] (the scan that feeds
/// it cannot fail).
#[derive(Debug)]
pub struct RowSpill {
    out: std::result::Result<std::io::BufWriter<File>, String>,
    dir: PathBuf,
    width: usize,
    rows: usize,
}

impl RowSpill {
    /// An empty spill of rows of `width` values in the temporary folder.
    pub fn new(width: usize) -> RowSpill {
        let dir = std::env::temp_dir();
        let out = tempfile::tempfile_in(&dir)
            .map(|f| std::io::BufWriter::with_capacity(1 << 16, f))
            .map_err(|e| format!("{}: {e}", dir.display()));
        RowSpill {
            out,
            dir,
            width: width.max(1),
            rows: 0,
        }
    }

    /// Appends one row (`width` values; more are cut, fewer padded with 0).
    pub fn push(&mut self, row: &[f64]) {
        use std::io::Write;
        let Ok(out) = &mut self.out else { return };
        let mut bytes = [0u8; 8 * MAX_WIDTH];
        let w = self.width.min(MAX_WIDTH);
        for (k, v) in row.iter().take(w).enumerate() {
            bytes[8 * k..8 * k + 8].copy_from_slice(&v.to_le_bytes());
        }
        match out.write_all(&bytes[..8 * w]) {
            Ok(()) => self.rows += 1,
            Err(e) => self.out = Err(format!("{}: {e}", self.dir.display())),
        }
    }

    /// Rows given so far.
    pub fn len(&self) -> usize {
        self.rows
    }

    /// True before the first row.
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    /// The rows written, on disk; `what` names them in the error when one
    /// could not be written.
    pub fn finish(self, what: &str) -> Result<RowFile> {
        let io = |e: String| {
            Error::io(
                &self.dir,
                std::io::Error::other(format!(
                    "{what} could not be set aside in the temporary folder (TMPDIR): {e}"
                )),
            )
        };
        let file = self
            .out
            .map_err(&io)?
            .into_inner()
            .map_err(|e| io(e.error().to_string()))?;
        Ok(RowFile {
            file,
            dir: self.dir,
            width: self.width.min(MAX_WIDTH),
            rows: self.rows,
        })
    }
}

/// The widest row of a [`RowSpill`].
const MAX_WIDTH: usize = 8;

/// The rows of a [`RowSpill`], in the order they were given, read back a
/// piece at a time.
#[derive(Debug)]
pub struct RowFile {
    file: File,
    dir: PathBuf,
    width: usize,
    rows: usize,
}

impl RowFile {
    /// Rows held.
    pub fn len(&self) -> usize {
        self.rows
    }

    /// True without rows.
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    /// Values per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Every row, in order, in pieces of at most `max` rows: `f` gets the
    /// index of the piece's first row and its values (rows × width).
    pub fn for_each_piece(
        &self,
        max: usize,
        mut f: impl FnMut(usize, &[f64]) -> Result<()>,
    ) -> Result<()> {
        let max = max.max(1);
        let row_bytes = 8 * self.width;
        let mut bytes = vec![0u8; max.min(self.rows) * row_bytes];
        let mut values = Vec::with_capacity(max.min(self.rows) * self.width);
        let mut start = 0;
        while start < self.rows {
            let k = max.min(self.rows - start);
            let piece = &mut bytes[..k * row_bytes];
            read_at(&self.file, piece, (start * row_bytes) as u64)
                .map_err(|e| Error::io(&self.dir, e))?;
            values.clear();
            values.extend(piece.chunks_exact(8).map(le_f64));
            f(start, &values)?;
            start += k;
        }
        Ok(())
    }

    /// Row `i`'s values, or `None` past the end.
    pub fn row(&self, i: usize) -> Result<Option<Vec<f64>>> {
        if i >= self.rows {
            return Ok(None);
        }
        let mut bytes = vec![0u8; 8 * self.width];
        read_at(&self.file, &mut bytes, (i * 8 * self.width) as u64)
            .map_err(|e| Error::io(&self.dir, e))?;
        Ok(Some(bytes.chunks_exact(8).map(le_f64).collect()))
    }
}

/// The `f64` of 8 little-endian bytes.
fn le_f64(b: &[u8]) -> f64 {
    let mut v = [0u8; 8];
    v.copy_from_slice(b);
    f64::from_le_bytes(v)
}

/// Rows per piece when a [`RowFile`] is read whole.
pub const ROW_PIECE: usize = 4096;

/// A trajectory with orientations on disk: a [`RowFile`] of rows `t, x, y,
/// z, qx, qy, qz, qw`, times non-decreasing, read back a piece at a time
/// ([`TrajectoryRef`]) or whole ([`TrajectoryFile::load`]). A bounded
/// conversion's reference poses wait here between the alignment and the
/// writers.
#[derive(Debug)]
pub struct TrajectoryFile {
    rows: std::sync::Arc<RowFile>,
    /// Where the poses came from (the log), for errors.
    source: PathBuf,
    /// Their topic, for errors.
    topic: String,
}

impl TrajectoryFile {
    /// The poses of `rows` (8 values a row, times non-decreasing) of
    /// `topic` in `source`.
    pub fn new(
        rows: std::sync::Arc<RowFile>,
        source: &Path,
        topic: &str,
    ) -> Result<TrajectoryFile> {
        if rows.width() != 8 {
            return Err(Error::invalid(
                "trajectory file",
                format!("rows of {} values, not t x y z qx qy qz qw", rows.width()),
            ));
        }
        Ok(TrajectoryFile {
            rows,
            source: source.to_path_buf(),
            topic: topic.to_string(),
        })
    }

    /// `t` (with its orientations, identity where it has none) written to
    /// a temporary file, named `topic` of `source` in errors (for tests: a
    /// conversion's reference reaches disk as the log is scanned).
    #[cfg(test)]
    pub(crate) fn write(t: &Trajectory, source: &Path, topic: &str) -> Result<TrajectoryFile> {
        let mut spill = RowSpill::new(8);
        TrajectoryRef::Memory(t).for_each_piece(
            ROW_PIECE,
            |_, times, positions, orientations| {
                for (i, (time, p)) in times.iter().zip(positions).enumerate() {
                    let q = orientations.map_or([0.0, 0.0, 0.0, 1.0], |q| {
                        let c = q[i].coords;
                        [c[0], c[1], c[2], c[3]]
                    });
                    spill.push(&[*time, p.x, p.y, p.z, q[0], q[1], q[2], q[3]]);
                }
                Ok(())
            },
        )?;
        let rows = spill.finish(&format!("the poses of {topic}"))?;
        TrajectoryFile::new(std::sync::Arc::new(rows), source, topic)
    }

    /// Poses held.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True without poses.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The topic the poses came from.
    pub fn topic(&self) -> &str {
        &self.topic
    }

    /// The trajectory, read back whole and checked as one read in memory is
    /// ([`Trajectory::try_new`]; its error names the log and the topic).
    pub fn load(&self) -> Result<Trajectory> {
        let n = self.len();
        let (mut t, mut p, mut q) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        TrajectoryRef::File(self).for_each_piece(
            ROW_PIECE,
            |_, times, positions, orientations| {
                t.extend_from_slice(times);
                p.extend_from_slice(positions);
                q.extend_from_slice(orientations.unwrap_or_default());
                Ok(())
            },
        )?;
        Trajectory::try_new(t, p, Some(q))
            .map_err(|e| Error::samples(&self.source, &self.topic, e.to_string()))
    }
}

/// The pose of a [`TrajectoryFile`] row `t x y z qx qy qz qw`.
pub(crate) fn pose_of_row(r: &[f64]) -> (f64, Vector3<f64>, UnitQuaternion<f64>) {
    (
        r[0],
        Vector3::new(r[1], r[2], r[3]),
        UnitQuaternion::new_unchecked(Quaternion::new(r[7], r[4], r[5], r[6])),
    )
}

/// A trajectory to read: in memory, or on disk ([`TrajectoryFile`]). Its
/// readers take it a piece at a time, so that one on disk is never whole in
/// memory; the pieces of both are the same poses.
#[derive(Clone, Copy, Debug)]
pub enum TrajectoryRef<'a> {
    /// In memory.
    Memory(&'a Trajectory),
    /// On disk.
    File(&'a TrajectoryFile),
}

impl<'a> From<&'a Trajectory> for TrajectoryRef<'a> {
    fn from(t: &'a Trajectory) -> Self {
        TrajectoryRef::Memory(t)
    }
}

impl TrajectoryRef<'_> {
    /// Poses held.
    pub fn len(&self) -> usize {
        match self {
            TrajectoryRef::Memory(t) => t.len(),
            TrajectoryRef::File(f) => f.len(),
        }
    }

    /// True without poses.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every pose, in order, in pieces of at most `max`: `f` gets the index
    /// of the piece's first pose, its times, positions and orientations
    /// (when the trajectory has them).
    pub fn for_each_piece(
        &self,
        max: usize,
        mut f: impl FnMut(usize, &[f64], &[Vector3<f64>], Option<&[UnitQuaternion<f64>]>) -> Result<()>,
    ) -> Result<()> {
        let max = max.max(1);
        match self {
            TrajectoryRef::Memory(t) => {
                let mut start = 0;
                while start < t.len() {
                    let end = (start + max).min(t.len());
                    let q = t.orientations.as_ref().map(|q| &q[start..end]);
                    f(
                        start,
                        &t.timestamps[start..end],
                        &t.positions[start..end],
                        q,
                    )?;
                    start = end;
                }
                Ok(())
            }
            TrajectoryRef::File(file) => {
                let (mut t, mut p, mut q) = (Vec::new(), Vec::new(), Vec::new());
                file.rows.for_each_piece(max, |first, values| {
                    t.clear();
                    p.clear();
                    q.clear();
                    for r in values.chunks_exact(8) {
                        let (time, position, orientation) = pose_of_row(r);
                        t.push(time);
                        p.push(position);
                        q.push(orientation);
                    }
                    f(first, &t, &p, Some(&q))
                })
            }
        }
    }

    /// The positions of poses `indices` (any order), `None` for an index
    /// past the end.
    pub fn positions_at(&self, indices: &[usize]) -> Result<Vec<Option<Vector3<f64>>>> {
        match self {
            TrajectoryRef::Memory(t) => Ok(indices
                .iter()
                .map(|&i| t.positions.get(i).copied())
                .collect()),
            TrajectoryRef::File(file) => indices
                .iter()
                .map(|&i| Ok(file.rows.row(i)?.map(|r| Vector3::new(r[1], r[2], r[3]))))
                .collect(),
        }
    }
}

/// A world cloud on disk: `f32` coordinates and RGB colours in two files,
/// appended in order, read back in pieces.
#[derive(Debug)]
pub struct CloudFile {
    points: File,
    colors: Option<File>,
    dir: PathBuf,
    len: usize,
}

impl CloudFile {
    /// An empty cloud (with colours when `colors`).
    pub fn new(colors: bool) -> Result<CloudFile> {
        let (points, dir) = temp_file()?;
        let colors = if colors { Some(temp_file()?.0) } else { None };
        Ok(CloudFile {
            points,
            colors,
            dir,
            len: 0,
        })
    }

    /// Points held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True without points.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// True when the points carry colours.
    pub fn has_colors(&self) -> bool {
        self.colors.is_some()
    }

    /// Bytes on disk.
    pub fn bytes(&self) -> u64 {
        self.len as u64 * if self.colors.is_some() { 15 } else { 12 }
    }

    /// Appends `points` (`n × 3`) and their colours (`n × 3`, present exactly
    /// when the cloud has colours).
    pub fn push(&mut self, points: &[f32], colors: Option<&[u8]>) -> Result<()> {
        let n = points.len() / 3;
        let mut bytes = Vec::with_capacity(points.len() * 4);
        for v in points {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        let io = |e| Error::io(&self.dir, e);
        write_at(&self.points, &bytes, self.len as u64 * 12).map_err(io)?;
        match (&self.colors, colors) {
            (Some(f), Some(c)) if c.len() == 3 * n => {
                write_at(f, c, self.len as u64 * 3).map_err(io)?
            }
            (None, None) => {}
            _ => {
                return Err(Error::invalid(
                    "cloud",
                    "colours given for some keyframes and not for others",
                ))
            }
        }
        self.len += n;
        Ok(())
    }

    /// Points `start .. start + n`: coordinates and colours.
    fn read(&self, start: usize, n: usize) -> Result<(Vec<f32>, Option<Vec<u8>>)> {
        let io = |e| Error::io(&self.dir, e);
        let mut bytes = vec![0u8; 12 * n];
        read_at(&self.points, &mut bytes, start as u64 * 12).map_err(io)?;
        let points = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let colors = match &self.colors {
            Some(f) => {
                let mut c = vec![0u8; 3 * n];
                read_at(f, &mut c, start as u64 * 3).map_err(io)?;
                Some(c)
            }
            None => None,
        };
        Ok((points, colors))
    }

    /// The temporary folder the files are in.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

/// A world cloud to write: in memory, or on disk ([`CloudFile`]). Writers
/// take it a piece at a time, so that a cloud on disk is never whole in
/// memory; the pieces of both are the same points in the same order.
#[derive(Clone, Copy, Debug)]
pub enum CloudRef<'a> {
    /// Coordinates (`n × 3`) and colours (`n × 3`) in memory.
    Memory(&'a [f32], Option<&'a [u8]>),
    /// A cloud on disk.
    File(&'a CloudFile),
}

impl CloudRef<'_> {
    /// Points.
    pub fn len(&self) -> usize {
        match self {
            CloudRef::Memory(p, _) => p.len() / 3,
            CloudRef::File(f) => f.len(),
        }
    }

    /// True without points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// True when the points carry colours.
    pub fn has_colors(&self) -> bool {
        match self {
            CloudRef::Memory(_, c) => c.is_some(),
            CloudRef::File(f) => f.has_colors(),
        }
    }

    /// Calls `f` with consecutive pieces of at most `max` points (at least
    /// one), in order: coordinates and colours. A cloud in memory is handed
    /// over in slices, one on disk read a piece at a time.
    pub fn for_each_piece(
        &self,
        max: usize,
        f: impl FnMut(&[f32], Option<&[u8]>) -> Result<()>,
    ) -> Result<()> {
        self.for_each_piece_in(0, self.len(), max, f)
    }

    /// [`CloudRef::for_each_piece`] of points `start .. start + n` (clipped
    /// to the cloud).
    pub fn for_each_piece_in(
        &self,
        start: usize,
        n: usize,
        max: usize,
        mut f: impl FnMut(&[f32], Option<&[u8]>) -> Result<()>,
    ) -> Result<()> {
        let max = max.max(1);
        let end = start.saturating_add(n).min(self.len());
        let mut at = start;
        while at < end {
            let len = max.min(end - at);
            match self {
                CloudRef::Memory(points, colors) => f(
                    &points[3 * at..3 * (at + len)],
                    colors.map(|c| &c[3 * at..3 * (at + len)]),
                )?,
                CloudRef::File(file) => {
                    let (points, colors) = file.read(at, len)?;
                    f(&points, colors.as_deref())?;
                }
            }
            at += len;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_on_disk_come_back_bit_for_bit_in_any_pieces() {
        let width = 7;
        let mut spill = RowSpill::new(width);
        let n = 3 * ROW_PIECE + 17;
        let v = |i: usize, k: usize| match (i + k) % 5 {
            0 => -0.0,
            1 => f64::MIN_POSITIVE / 4.0,
            2 => 1e300,
            3 => f64::NAN,
            _ => (i as f64).sin() * (k as f64 + 1.0),
        };
        let row = |i: usize| (0..width).map(|k| v(i, k)).collect::<Vec<f64>>();
        for i in 0..n {
            spill.push(&row(i));
        }
        assert_eq!(spill.len(), n);
        let file = spill.finish("rows").unwrap();
        assert_eq!((file.len(), file.width()), (n, width));
        for max in [1, 1000, ROW_PIECE, n, 10 * n] {
            let mut next = 0;
            file.for_each_piece(max, |first, values| {
                assert_eq!(first, next);
                assert!(values.len() <= max * width && values.len() % width == 0);
                for (j, r) in values.chunks_exact(width).enumerate() {
                    let want = row(first + j);
                    assert!(r.iter().zip(&want).all(|(a, b)| a.to_bits() == b.to_bits()));
                }
                next += values.len() / width;
                Ok(())
            })
            .unwrap();
            assert_eq!(next, n);
        }
        let last = file.row(n - 1).unwrap().unwrap();
        assert!(last
            .iter()
            .zip(&row(n - 1))
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        assert!(file.row(n).unwrap().is_none());
        // An error in the callback stops the reading and is returned.
        let mut calls = 0;
        let r = file.for_each_piece(10, |_, _| {
            calls += 1;
            Err(Error::invalid("x", "stop"))
        });
        assert!(r.is_err() && calls == 1);
    }

    #[test]
    fn a_trajectory_on_disk_reads_as_the_one_in_memory() {
        let n = 2 * ROW_PIECE + 5;
        let t: Vec<f64> = (0..n).map(|i| (i / 2) as f64 * 0.01).collect();
        let p: Vec<Vector3<f64>> = (0..n)
            .map(|i| Vector3::new(i as f64, -(i as f64), (i as f64).sqrt()))
            .collect();
        let q: Vec<UnitQuaternion<f64>> = (0..n)
            .map(|i| UnitQuaternion::from_euler_angles(0.1, 0.0, i as f64 * 1e-3))
            .collect();
        let traj = Trajectory::try_new(t, p, Some(q)).unwrap();
        let file = TrajectoryFile::write(&traj, Path::new("log.mcap"), "/gt").unwrap();
        let back = file.load().unwrap();
        assert_eq!(back.timestamps, traj.timestamps);
        assert_eq!(back.positions, traj.positions);
        assert_eq!(back.orientations, traj.orientations);
        let (mem, disk) = (TrajectoryRef::Memory(&traj), TrajectoryRef::File(&file));
        assert_eq!((mem.len(), disk.len()), (n, n));
        let pieces = |r: TrajectoryRef<'_>, max: usize| {
            let mut got = Vec::new();
            r.for_each_piece(max, |first, t, p, q| {
                got.push((first, t.to_vec(), p.to_vec(), q.map(<[_]>::to_vec)));
                Ok(())
            })
            .unwrap();
            got
        };
        for max in [1, 777, ROW_PIECE, 10 * n] {
            assert_eq!(pieces(mem, max), pieces(disk, max), "pieces of {max}");
        }
        let at = [n - 1, 0, 3, n, 3];
        assert_eq!(
            mem.positions_at(&at).unwrap(),
            disk.positions_at(&at).unwrap()
        );
        assert_eq!(disk.positions_at(&at).unwrap()[3], None);
        // Rows of another width are no trajectory.
        let imu = std::sync::Arc::new(RowSpill::new(7).finish("imu").unwrap());
        assert!(TrajectoryFile::new(imu, Path::new("log.mcap"), "/imu").is_err());
    }

    #[test]
    fn a_cloud_file_gives_back_what_was_pushed_in_any_pieces() {
        let mut file = CloudFile::new(true).unwrap();
        let pts: Vec<f32> = (0..3000).map(|i| i as f32 * 0.5).collect();
        let cols: Vec<u8> = (0..3000).map(|i| (i % 251) as u8).collect();
        file.push(&pts[..600], Some(&cols[..600])).unwrap();
        file.push(&pts[600..], Some(&cols[600..])).unwrap();
        assert_eq!(file.len(), 1000);
        assert!(file.push(&pts[..3], None).is_err());
        for max in [1, 7, 999, 1000, 5000] {
            let (mut p, mut c) = (Vec::new(), Vec::new());
            let mut pieces = 0;
            CloudRef::File(&file)
                .for_each_piece(max, |a, b| {
                    assert!(a.len() <= 3 * max);
                    p.extend_from_slice(a);
                    c.extend_from_slice(b.unwrap());
                    pieces += 1;
                    Ok(())
                })
                .unwrap();
            assert_eq!((p.as_slice(), c.as_slice()), (&pts[..], &cols[..]));
            assert_eq!(pieces, 1000usize.div_ceil(max));
        }
    }

    #[test]
    fn spilled_pixels_read_back_as_the_message_split() {
        let spill = PixelSpill::new().unwrap();
        let a: Vec<u8> = (0..12 * 50).map(|i| (i * 7 % 256) as u8).collect();
        let b: Vec<u8> = (0..12 * 3).map(|i| i as u8).collect();
        let (sa, sb) = (spill.put(&a).unwrap(), spill.put(&b).unwrap());
        assert_eq!((sa.pixels, sb.pixels), (50, 3));
        let split = crate::io::messages::decode::split_pointcloud;
        assert_eq!(spill.get(sb).unwrap(), split(&b));
        assert_eq!(spill.get(sa).unwrap(), split(&a));
        assert_eq!(spill.len(), 12 * 53);
        // A keyframe of several read pieces (16384 pixels each) and a part.
        let c: Vec<u8> = (0..12 * (2 * 16384 + 5))
            .map(|i| (i * 13 % 251) as u8)
            .collect();
        let sc = spill.put(&c).unwrap();
        let got = spill.get(sc).unwrap();
        assert_eq!(got, split(&c));
        assert_eq!(got.0.capacity(), 2 * 16384 + 5, "sized once");
        assert_eq!(spill.get(sa).unwrap(), split(&a));
    }
}
