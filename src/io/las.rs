//! Georeferenced point clouds as LAS 1.4 / LAZ with a CRS record.
//!
//! The cloud's points are ENU metres at a geodetic origin; they are carried
//! exactly into the CRS ([`crate::geo::enu_to_crs`]: a UTM zone, EPSG:326xx /
//! 327xx, height above the WGS84 ellipsoid; or ECEF, EPSG:4978) and written
//! with the `las` crate (LAZ through its `laz` feature, chosen by the `.laz`
//! extension): point format 6 (7 with colours, 8-bit colours scaled to 16 bits
//! ×257), the CRS as an OGC WKT VLR (`LASF_Projection` 2112, the global
//! encoding's WKT bit set, as LAS 1.4 asks for formats 6–10).
//!
//! Quantisation: scale 0.001 m on every axis and an offset at the whole metre
//! nearest the centre of the bounds, so a coordinate is stored within 0.5 mm
//! (a cloud up to 4 294 km across fits the 32-bit integers).
//!
//! The file is encoded in memory (the `las` writer would panic on a failed
//! header rewrite when dropped after an I/O error; a memory buffer cannot
//! fail), then written atomically (temp file, rename).

use std::io::Cursor;
use std::path::Path;

use rayon::prelude::*;

use crate::cloud::PointCloud;
use crate::error::{Error, Result};
use crate::geo::{enu_to_crs, EnuFrame, GeoCrs, Geodetic, UtmZone};
use crate::io::spill::CloudRef;

/// LAS coordinate step, metres.
pub const LAS_SCALE: f64 = 0.001;

/// What [`write_las`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct LasInfo {
    /// EPSG code of the CRS (326xx, 327xx or 4978).
    pub epsg: u16,
    /// The UTM zone for a UTM CRS.
    pub zone: Option<UtmZone>,
    /// LAS scale per axis, metres.
    pub scale: [f64; 3],
    /// LAS offset per axis, metres.
    pub offset: [f64; 3],
    /// True for LAZ.
    pub compressed: bool,
    /// Number of points.
    pub n_points: usize,
}

fn las_err(path: &Path, e: las::Error) -> Error {
    Error::io(path, std::io::Error::other(e.to_string()))
}

/// Writes `cloud` (ENU metres at `origin`) as LAS 1.4, or LAZ when `path`
/// ends in `.laz`, in `crs` (module doc). Atomic.
pub fn write_las(
    path: impl AsRef<Path>,
    cloud: &PointCloud,
    origin: &Geodetic,
    crs: GeoCrs,
) -> Result<LasInfo> {
    write_las_parts(
        path.as_ref(),
        &cloud.points,
        cloud.colors.as_deref(),
        origin,
        crs,
    )
}

/// [`write_las`] from the raw buffers: `points` `(N, 3)` f32 ENU metres,
/// `colors` `(N, 3)` bytes.
pub fn write_las_parts(
    path: &Path,
    points: &[f32],
    colors: Option<&[u8]>,
    origin: &Geodetic,
    crs: GeoCrs,
) -> Result<LasInfo> {
    let compressed = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("laz"));
    let (bytes, info) = las_bytes(path, points, colors, origin, crs, compressed)?;
    crate::io::atomic::write_bytes_atomic(path, &bytes)?;
    Ok(info)
}

/// The bytes of the LAS (or, `compressed`, LAZ) file [`write_las_parts`]
/// writes; `path` names the file in errors.
pub fn las_bytes(
    path: &Path,
    points: &[f32],
    colors: Option<&[u8]>,
    origin: &Geodetic,
    crs: GeoCrs,
    compressed: bool,
) -> Result<(Vec<u8>, LasInfo)> {
    let n = points.len() / 3;
    if let Some(c) = colors {
        if c.len() != 3 * n || points.len() % 3 != 0 {
            return Err(Error::ShapeMismatch {
                what: "colors".into(),
                expected: format!("({n}, 3)"),
                got: format!("{} values", c.len()),
            });
        }
    }
    let (w, info) = las_cloud_into(
        Cursor::new(Vec::new()),
        path,
        CloudRef::Memory(points, colors),
        origin,
        crs,
        compressed,
    )?;
    Ok((w.into_inner(), info))
}

/// [`las_bytes`] of a cloud in memory or on disk into `w`, a piece at a time
/// (two sweeps: the bounds that choose the offsets, then the points).
pub fn las_cloud_into<
    W: std::io::Write + std::io::Seek + std::fmt::Debug + Send + Sync + 'static,
>(
    w: W,
    path: &Path,
    cloud: CloudRef<'_>,
    origin: &Geodetic,
    crs: GeoCrs,
    compressed: bool,
) -> Result<(W, LasInfo)> {
    const BATCH: usize = 1 << 16;
    let n = cloud.len();
    let frame = EnuFrame::new(*origin)?;
    let meta = enu_to_crs(&[], &frame, crs)?;
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    cloud.for_each_piece(BATCH, |points, _| {
        let global = enu_to_crs(points, &frame, crs)?;
        for p in global.xyz.chunks_exact(3) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        Ok(())
    })?;

    // Offsets: the whole metre nearest the centre of the bounds.
    let mut offset = [0.0; 3];
    for (k, o) in offset.iter_mut().enumerate() {
        if n == 0 {
            continue;
        }
        *o = ((lo[k] + hi[k]) / 2.0).round();
        let half = (hi[k] - *o).max(*o - lo[k]);
        if half / LAS_SCALE > i32::MAX as f64 - 1.0 {
            return Err(Error::invalid(
                "cloud",
                format!(
                    "spans {:.0} m on axis {k}: more than LAS 32-bit coordinates hold at {LAS_SCALE} m",
                    hi[k] - lo[k]
                ),
            ));
        }
    }

    let with_colors = cloud.has_colors();
    let mut format =
        las::point::Format::new(if with_colors { 7 } else { 6 }).map_err(|e| las_err(path, e))?;
    format.is_compressed = compressed;
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = format;
    builder.generating_software = "slam2world".into();
    builder.system_identifier = "slam2world".into();
    let t = |k: usize| las::Transform {
        scale: LAS_SCALE,
        offset: offset[k],
    };
    builder.transforms = las::Vector {
        x: t(0),
        y: t(1),
        z: t(2),
    };
    let mut header = builder.into_header().map_err(|e| las_err(path, e))?;
    header
        .set_wkt_crs(meta.wkt.as_bytes().to_vec())
        .map_err(|e| las_err(path, e))?;

    let mut writer = las::Writer::new(w, header).map_err(|e| las_err(path, e))?;
    cloud.for_each_piece(BATCH, |points, colors| {
        crate::interrupt::check()?;
        let xyz = enu_to_crs(points, &frame, crs)?.xyz;
        let make = |i: usize| las::Point {
            x: xyz[3 * i],
            y: xyz[3 * i + 1],
            z: xyz[3 * i + 2],
            return_number: 1,
            number_of_returns: 1,
            gps_time: Some(0.0),
            color: colors.map(|c| las::Color {
                red: c[3 * i] as u16 * 257,
                green: c[3 * i + 1] as u16 * 257,
                blue: c[3 * i + 2] as u16 * 257,
            }),
            ..Default::default()
        };
        let batch: Vec<las::Point> = (0..points.len() / 3).into_par_iter().map(make).collect();
        for p in batch {
            writer.write_point(p).map_err(|e| las_err(path, e))?;
        }
        Ok(())
    })?;
    let w = writer.into_inner().map_err(|e| las_err(path, e))?;
    Ok((
        w,
        LasInfo {
            epsg: meta.epsg,
            zone: meta.zone,
            scale: [LAS_SCALE; 3],
            offset,
            compressed,
            n_points: n,
        },
    ))
}
