//! Temporary files of the bounded-memory conversion: what a long log would
//! otherwise hold in memory whole.
//!
//! - [`PixelSpill`]: the per-pixel arrays of every keyframe message, written
//!   as the log is read (inside the parallel chunk tasks) and read back a
//!   batch of keyframes at a time once `T_world_slam` is known;
//! - [`CloudFile`]: the world cloud, appended keyframe by keyframe and read
//!   back in bounded pieces by each output writer ([`CloudRef`]);
//! - [`ImuSpill`]: the raw IMU samples, written as the log is read and read
//!   back ([`SpilledImu::load`]) for the one step that uses them, after the
//!   alignment, so that they are not held beside the reference and the live
//!   frames.
//!
//! Both are anonymous files in the temporary folder (`TMPDIR`, else `/tmp`):
//! they take no name and are gone when closed, a crash included.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::Vector3;

use crate::error::{Error, Result};

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
    pub fn get(&self, at: SpilledPixels) -> Result<(Vec<f32>, Vec<f32>, Vec<u8>)> {
        let mut bytes = vec![0u8; at.pixels * crate::io::messages::decode::POINT_BYTES];
        read_at(&self.file, &mut bytes, at.offset).map_err(|e| Error::io(&self.dir, e))?;
        Ok(crate::io::messages::decode::split_pointcloud(&bytes))
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

/// Raw IMU samples as a scan gives them, appended to a temporary file:
/// a row is the time, the angular rate and the specific force, seven
/// little-endian `f64`s. A write error is kept and returned by
/// [`ImuSpill::finish`] (the scan that feeds it cannot fail).
#[derive(Debug)]
pub struct ImuSpill {
    out: std::result::Result<std::io::BufWriter<File>, String>,
    dir: PathBuf,
    rows: usize,
}

/// Bytes of one [`ImuSpill`] row.
const IMU_ROW: usize = 7 * 8;

impl ImuSpill {
    /// An empty spill in the temporary folder.
    pub fn new() -> ImuSpill {
        let dir = std::env::temp_dir();
        let out = tempfile::tempfile_in(&dir)
            .map(|f| std::io::BufWriter::with_capacity(1 << 16, f))
            .map_err(|e| format!("{}: {e}", dir.display()));
        ImuSpill { out, dir, rows: 0 }
    }

    /// Appends one sample.
    pub fn push(&mut self, time: f64, gyro: &Vector3<f64>, accel: &Vector3<f64>) {
        use std::io::Write;
        let Ok(out) = &mut self.out else { return };
        let mut row = [0u8; IMU_ROW];
        for (k, v) in std::iter::once(time)
            .chain(gyro.iter().copied())
            .chain(accel.iter().copied())
            .enumerate()
        {
            row[8 * k..8 * k + 8].copy_from_slice(&v.to_le_bytes());
        }
        match out.write_all(&row) {
            Ok(()) => self.rows += 1,
            Err(e) => self.out = Err(format!("{}: {e}", self.dir.display())),
        }
    }

    /// The samples written, on disk; an error when one could not be.
    pub fn finish(self, source: &Path, topic: &str) -> Result<SpilledImu> {
        let io = |what: String| {
            Error::io(
                &self.dir,
                std::io::Error::other(format!(
                    "the IMU samples of {topic} in {} could not be set aside in the \
                     temporary folder (TMPDIR): {what}",
                    source.display()
                )),
            )
        };
        let file = self
            .out
            .map_err(&io)?
            .into_inner()
            .map_err(|e| io(e.error().to_string()))?;
        Ok(SpilledImu {
            file,
            dir: self.dir,
            rows: self.rows,
        })
    }
}

impl Default for ImuSpill {
    fn default() -> Self {
        ImuSpill::new()
    }
}

/// IMU rows as columns: times, angular rates, specific forces.
pub type ImuColumns = (Vec<f64>, Vec<Vector3<f64>>, Vec<Vector3<f64>>);

/// The IMU samples of an [`ImuSpill`], in the order they were given.
#[derive(Debug)]
pub struct SpilledImu {
    file: File,
    dir: PathBuf,
    rows: usize,
}

impl SpilledImu {
    /// Samples held.
    pub fn len(&self) -> usize {
        self.rows
    }

    /// True without samples.
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    /// The samples read back: times, angular rates and specific forces, in
    /// the order given (read a piece at a time into rows of exact size).
    pub fn read(&self) -> Result<ImuColumns> {
        let n = self.rows;
        let (mut times, mut gyro, mut accel) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        const PIECE: usize = 4096;
        let mut bytes = vec![0u8; PIECE * IMU_ROW];
        let mut start = 0;
        while start < n {
            let k = PIECE.min(n - start);
            let piece = &mut bytes[..k * IMU_ROW];
            read_at(&self.file, piece, (start * IMU_ROW) as u64)
                .map_err(|e| Error::io(&self.dir, e))?;
            for row in piece.chunks_exact(IMU_ROW) {
                let v = |i: usize| {
                    let mut b = [0u8; 8];
                    b.copy_from_slice(&row[8 * i..8 * i + 8]);
                    f64::from_le_bytes(b)
                };
                times.push(v(0));
                gyro.push(Vector3::new(v(1), v(2), v(3)));
                accel.push(Vector3::new(v(4), v(5), v(6)));
            }
            start += k;
        }
        Ok((times, gyro, accel))
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
    fn imu_samples_on_disk_come_back_bit_for_bit_across_pieces() {
        let mut spill = ImuSpill::new();
        let n = 3 * 4096 + 17;
        let v = |i: usize, k: usize| match (i + k) % 5 {
            0 => -0.0,
            1 => f64::MIN_POSITIVE / 4.0,
            2 => 1e300,
            _ => (i as f64).sin() * (k as f64 + 1.0),
        };
        let row = |i: usize| {
            (
                i as f64 * 0.005,
                Vector3::new(v(i, 1), v(i, 2), v(i, 3)),
                Vector3::new(v(i, 4), v(i, 5), v(i, 6)),
            )
        };
        for i in 0..n {
            let (t, g, a) = row(i);
            spill.push(t, &g, &a);
        }
        let on_disk = spill.finish(Path::new("log.mcap"), "/imu0").unwrap();
        assert_eq!(on_disk.len(), n);
        let (times, gyro, accel) = on_disk.read().unwrap();
        assert_eq!((times.capacity(), gyro.capacity()), (n, n));
        for i in 0..n {
            let (t, g, a) = row(i);
            assert_eq!(times[i].to_bits(), t.to_bits());
            for k in 0..3 {
                assert_eq!(gyro[i][k].to_bits(), g[k].to_bits(), "row {i}");
                assert_eq!(accel[i][k].to_bits(), a[k].to_bits(), "row {i}");
            }
        }
        // Read twice, the same.
        assert_eq!(on_disk.read().unwrap().0, times);
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
    }
}
