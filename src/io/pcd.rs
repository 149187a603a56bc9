//! Binary PCD (PCL's Point Cloud Data, v0.7) as PCL writes it.
//!
//! `FIELDS x y z` (`SIZE 4`, `TYPE F`), plus `rgb` when the cloud has colours:
//! PCL's `PointXYZRGB` packing, the 32 bits `0x00RRGGBB` stored as a float
//! (`TYPE F`). Unorganised (`HEIGHT 1`), identity `VIEWPOINT`, `DATA binary`
//! (little-endian records of 12 or 16 bytes). Coordinates are those of the
//! cloud, as `f32` metres (a local frame such as ENU: `f32` cannot carry UTM
//! or ECEF coordinates to the millimetre). Written atomically.

use std::io::{BufWriter, Write};
use std::path::Path;

use rayon::prelude::*;

use crate::cloud::PointCloud;
use crate::error::{Error, Result};
use crate::io::atomic::OutputSet;
use crate::io::spill::CloudRef;

/// PCL's packed colour: `0x00RRGGBB` as the bits of an `f32`.
pub fn pack_rgb(r: u8, g: u8, b: u8) -> f32 {
    f32::from_bits(((r as u32) << 16) | ((g as u32) << 8) | b as u32)
}

/// Writes `cloud` as a binary PCD (module doc).
pub fn write_pcd(path: impl AsRef<Path>, cloud: &PointCloud) -> Result<()> {
    write_pcd_parts(path.as_ref(), &cloud.points, cloud.colors.as_deref())
}

/// [`write_pcd`] from the raw buffers: `points` `(N, 3)` f32, `colors` `(N, 3)` bytes.
pub fn write_pcd_parts(path: &Path, points: &[f32], colors: Option<&[u8]>) -> Result<()> {
    crate::io::ply::check_shapes(points, colors)?;
    pcd_into(None, path, CloudRef::Memory(points, colors))
}

/// [`write_pcd_parts`] as one output of `set`.
pub fn write_pcd_into(
    set: &mut OutputSet,
    path: &Path,
    points: &[f32],
    colors: Option<&[u8]>,
) -> Result<()> {
    crate::io::ply::check_shapes(points, colors)?;
    pcd_into(Some(set), path, CloudRef::Memory(points, colors))
}

/// [`write_pcd_into`] of a cloud in memory or on disk, a piece at a time.
pub fn write_pcd_cloud_into(set: &mut OutputSet, path: &Path, cloud: CloudRef<'_>) -> Result<()> {
    pcd_into(Some(set), path, cloud)
}

fn pcd_into(set: Option<&mut OutputSet>, path: &Path, cloud: CloudRef<'_>) -> Result<()> {
    let n = cloud.len();
    let (fields, size, kind, count, stride) = match cloud.has_colors() {
        true => ("x y z rgb", "4 4 4 4", "F F F F", "1 1 1 1", 16),
        false => ("x y z", "4 4 4", "F F F", "1 1 1", 12),
    };
    let header = format!(
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {fields}\nSIZE {size}\n\
         TYPE {kind}\nCOUNT {count}\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n"
    );
    const BATCH: usize = 1 << 18;
    let io_err = |e| Error::io(path, e);
    let body = |file: &std::fs::File| {
        let mut w = BufWriter::with_capacity(1 << 20, file);
        w.write_all(header.as_bytes()).map_err(io_err)?;
        let mut buf = Vec::new();
        cloud.for_each_piece(BATCH, |points, colors| {
            buf.clear();
            buf.resize(points.len() / 3 * stride, 0u8);
            buf.par_chunks_exact_mut(stride)
                .enumerate()
                .for_each(|(i, rec)| {
                    for k in 0..3 {
                        rec[4 * k..4 * k + 4].copy_from_slice(&points[3 * i + k].to_le_bytes());
                    }
                    if let Some(c) = colors {
                        let rgb = pack_rgb(c[3 * i], c[3 * i + 1], c[3 * i + 2]);
                        rec[12..16].copy_from_slice(&rgb.to_le_bytes());
                    }
                });
            w.write_all(&buf).map_err(io_err)
        })?;
        w.flush().map_err(io_err)
    };
    match set {
        Some(set) => set.write(path, body),
        None => crate::io::atomic::write_atomic(path, body),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_and_records() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.pcd");
        let cloud = PointCloud::try_new(
            vec![1.0, 2.0, 3.0, -4.0, 5.5, 6.0],
            Some(vec![255, 128, 1, 0, 0, 9]),
            None,
        )
        .unwrap();
        write_pcd(&path, &cloud).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let text_end = bytes
            .windows(12)
            .position(|w| w == b"DATA binary\n")
            .unwrap()
            + 12;
        let header = std::str::from_utf8(&bytes[..text_end]).unwrap();
        assert!(header.contains("FIELDS x y z rgb\n") && header.contains("POINTS 2\n"));
        let data = &bytes[text_end..];
        assert_eq!(data.len(), 32);
        assert_eq!(f32::from_le_bytes(data[16..20].try_into().unwrap()), -4.0);
        let rgb = u32::from_le_bytes(data[12..16].try_into().unwrap());
        assert_eq!(rgb, 0x00FF_8001);
    }
}
